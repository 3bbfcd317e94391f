"""The relocation metric (SLaTe-PRO's) and the scoring of lookahead forecasts against test days.

What :mod:`globe.evaluation.lookahead` counts: per reference step, horizon and tracked object,
whether a change was predicted, whether one happened and whether the predicted first new place
was the true one (objects in use at the reference step left out: their next move is being put
back). Kept apart from the search over settings so each reads on its own.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from globe.data.records import Day, is_use_place
from globe.inference.forecast import Forecasts
from globe.models.base import ActivityModelBase


@dataclass(frozen=True, slots=True)
class RelocationCounts:
    """Pooled counts of the relocation metric; precision, recall and F1 from them."""

    correct: int = 0
    predicted: int = 0
    true: int = 0

    def __add__(self, other: "RelocationCounts") -> "RelocationCounts":
        return RelocationCounts(self.correct + other.correct, self.predicted + other.predicted, self.true + other.true)

    @property
    def precision(self) -> float:
        return self.correct / self.predicted if self.predicted else 0.0

    @property
    def recall(self) -> float:
        return self.correct / self.true if self.true else 0.0

    @property
    def f1(self) -> float:
        p, r = self.precision, self.recall
        return 2 * p * r / (p + r) if p + r > 0 else 0.0


def true_first_locations(locations: Sequence[Sequence[str]], r: int, s: int) -> list[str | None]:
    """Per object, its first location other than the one at step r within steps r+1..r+1+s
    (None: it stays put throughout, or it is in use at r and can only be put back first)."""
    here = locations[r]
    out: list[str | None] = []
    for j, loc in enumerate(here):
        out.append(None if is_use_place(loc) else next(
            (locations[u][j] for u in range(r + 1, min(r + 2 + s, len(locations))) if locations[u][j] != loc), None))
    return out


def relocation_counts(true: Sequence[str | None], predicted: Sequence[str | None]) -> RelocationCounts:
    """Count one set of pairs: ``true``/``predicted`` first new location per pair (None = no change)."""
    if len(true) != len(predicted):
        raise ValueError(f"{len(true)} true and {len(predicted)} predicted pairs")
    correct = sum(1 for t, p in zip(true, predicted) if t is not None and p is not None and t == p)
    return RelocationCounts(correct, sum(p is not None for p in predicted), sum(t is not None for t in true))


@dataclass(slots=True)
class HorizonPairs:
    """Every (reference step x object) pair of one horizon: the probability of the predicted
    first new place, whether that place is the true one, and whether a change happened. A
    threshold turns them into :class:`RelocationCounts` without forecasting again."""

    probability: list[np.ndarray] = field(default_factory=list)
    hit: list[np.ndarray] = field(default_factory=list)
    true: list[np.ndarray] = field(default_factory=list)

    def counts(self, threshold: float) -> RelocationCounts:
        if not self.probability:
            return RelocationCounts()
        p, hit, true = np.concatenate(self.probability), np.concatenate(self.hit), np.concatenate(self.true)
        predicted = (p >= threshold) & (p > 0)
        return RelocationCounts(int((predicted & hit).sum()), int(predicted.sum()), int(true.sum()))


@dataclass(slots=True)
class LookaheadRun:
    """The pairs of every horizon and the activity accuracy at r+s, over some days."""

    horizons: int
    pairs: list[HorizonPairs]
    activity_correct: np.ndarray
    activity_total: np.ndarray

    @classmethod
    def empty(cls, horizons: int) -> "LookaheadRun":
        return cls(horizons, [HorizonPairs() for _ in range(horizons)], np.zeros(horizons, int),
                   np.zeros(horizons, int))

    def f1s(self, threshold: float) -> list[float]:
        return [p.counts(threshold).f1 for p in self.pairs]

    def activity_accuracy(self) -> list[float]:
        return [c / t if t else 0.0 for c, t in zip(self.activity_correct, self.activity_total)]


def reference_steps(day: Day, horizons: int, first: int, last: int | None, stride: int = 1) -> range:
    """r = first..last (every ``stride``-th), cut so that r + horizons stays inside the day."""
    end = len(day) - 1 - horizons
    return range(max(first, 1), (end if last is None else min(last, end)) + 1, stride)


def reference_queries(days: Sequence[Day], horizons: int, first: int = 1, last: int | None = None,
                      stride: int = 1) -> list[tuple[Day, int]]:
    """Every (day, reference step r) scored, in order."""
    return [(day, r) for day in days for r in reference_steps(day, horizons, first, last, stride)]


def score_forecasts(run: LookaheadRun, forecasts: Forecasts, refs: Sequence[tuple[Day, int]],
                    model: ActivityModelBase | None, location_rows: dict) -> None:
    """Add the pairs of ``forecasts`` (one per reference of ``refs``) to ``run``. ``location_rows``
    caches each day's location indices (of the forecaster's movement model)."""
    best, prob = forecasts.first_locations(run.horizons)
    top = top_activities(forecasts.trees.activity_matrix(), forecasts.trees.names, model, run.horizons)
    score_arrays(run, refs, best, prob, top, forecasts.trees.names, forecasts.locations, location_rows)


def score_arrays(run: LookaheadRun, refs: Sequence[tuple[Day, int]], best: np.ndarray, prob: np.ndarray,
                 top: np.ndarray, names: Sequence[str], locations: tuple[str, ...], location_rows: dict) -> None:
    """Add pairs to ``run``: per reference, horizon and object the predicted first new place
    (``best``, location indices of ``locations``) and its probability, and the top activity
    per horizon (``top``: ids of ``names``, -1 for none)."""
    horizons = run.horizons
    if not refs:
        return
    coded = [_locations_of(location_rows, locations, day) for day, _ in refs]
    future = np.stack([ids[r + 1: r + 1 + horizons] for (_, r), (ids, _) in zip(refs, coded)])
    here = np.stack([ids[r] for (_, r), (ids, _) in zip(refs, coded)])
    window = future != here[:, None, :]  # (refs, horizons, objects): somewhere else than at r
    # an object in use at r can only be put back first: no use to foresee (sequences.movements)
    in_use = {id(day): _in_use(day) for day in {id(day): day for day, _ in refs}.values()}
    free = ~np.stack([in_use[id(day)][r] for day, r in refs])
    moved_any = window.any(axis=1) & free
    first_step = window.argmax(axis=1)
    later = np.stack([index[r + 1: r + 1 + horizons] for (_, r), (_, index) in zip(refs, coded)])
    true_loc = np.take_along_axis(later, first_step[:, None, :], axis=1)[:, 0, :]
    for s in range(horizons):
        true = moved_any & (first_step <= s)
        pairs = run.pairs[s]
        pairs.probability.append(np.where(free, prob[:, s], 0.0).ravel())
        pairs.hit.append((true & (best[:, s] == true_loc)).ravel())
        pairs.true.append(true.ravel())
        run.activity_total[s] += len(refs)
        run.activity_correct[s] += sum(1 for (day, r), a in zip(refs, top[:, s].tolist())
                                       if a >= 0 and names[a] == day.activities[r + s])


_CODED: dict[int, tuple[Day, np.ndarray, list[str]]] = {}


def _coded(day: Day) -> tuple[np.ndarray, list[str]]:
    """(steps x objects) ids of ``day``'s places (one per distinct name) and the names (memoised)."""
    hit = _CODED.get(id(day))
    if hit is not None and hit[0] is day:
        return hit[1], hit[2]
    if len(_CODED) > 4096:
        _CODED.clear()
    names: dict[str, int] = {}
    rows: dict[tuple[str, ...], list[int]] = {}
    ids = np.array([rows.get(row) or rows.setdefault(row, [names.setdefault(x, len(names)) for x in row])
                    for row in day.locations], dtype=int).reshape(len(day), -1)
    _CODED[id(day)] = (day, ids, list(names))
    return ids, list(names)


_IN_USE: dict[int, tuple[Day, np.ndarray]] = {}


def _in_use(day: Day) -> np.ndarray:
    """(steps x objects): whether each object is at a use place (:func:`is_use_place`; memoised
    as :func:`_coded` is: every threshold and fold of a search scores the same days)."""
    hit = _IN_USE.get(id(day))
    if hit is not None and hit[0] is day:
        return hit[1]
    if len(_IN_USE) > 4096:
        _IN_USE.clear()
    ids, names = _coded(day)
    mask = np.array([is_use_place(x) for x in names], dtype=bool)[ids]
    _IN_USE[id(day)] = (day, mask)
    return mask


def _locations_of(cache: dict, locations: tuple[str, ...], day: Day) -> tuple[np.ndarray, np.ndarray]:
    """(steps x objects) of ``day``: an id per distinct place name, and the movement model's
    location index (places it never saw share one)."""
    out = cache.get(day.name)
    if out is None:
        ids, names = _coded(day)
        index = {x: i for i, x in enumerate(locations)}
        unknown = len(locations) - 1
        inv = np.array([index.get(x, unknown) for x in names], dtype=int)
        out = cache[day.name] = (ids, inv[ids])
    return out


def top_activities(dense: np.ndarray, names: Sequence[str], model: ActivityModelBase | None,
                   horizons: int) -> np.ndarray:
    """(queries x horizons): the id of ``model.ranked(...)[0]`` of each activity distribution
    of ``dense`` (queries x steps x names; most probable, ties: training frequency, then name),
    -1 when empty."""
    dense = dense[:, :horizons]
    frequency = getattr(model, "frequency_", {})
    tiebreak = np.empty(len(names), dtype=int)
    order = sorted(range(len(names)), key=lambda i: (-frequency.get(names[i], 0), str(names[i])))
    tiebreak[order] = np.arange(len(names))
    top = dense.max(axis=2, initial=0.0)
    candidate = (dense == top[..., None]) & (dense > 0)
    score = np.where(candidate, tiebreak[None, None, :], len(names))
    out = score.argmin(axis=2) if len(names) else np.zeros(dense.shape[:2], dtype=int)
    return np.where(candidate.any(axis=2), out, -1)
