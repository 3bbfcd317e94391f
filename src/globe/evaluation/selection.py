"""Cross-validation on training days, in one place: folds, the memo, and the rule that chooses.

Every search GLOBE runs (the activity and object models, the LLM gate, the lookahead's movement
settings and thresholds, the filter's movement evidence) holds out contiguous blocks of
*training* days (:func:`folds`), scores each candidate on them, and keeps the best with
:func:`best_of`: scores compared to :data:`SCORE_DECIMALS` decimals, ties to the first listed
candidate (the simpler one), so a changed last bit never flips a choice. Test days are never
looked at.

What a search computes is kept in a :class:`Memo` under a frozen, typed key that names every
input it depends on: the days (by a fingerprint of their content, :class:`DataKey`), the fold,
the model's settings and the alignment (:class:`FitKey`, :class:`SearchKey`). Equal keys mean
equal inputs, so a result is reused exactly where it applies and nowhere else.
"""

from __future__ import annotations

import hashlib
import itertools
import math
import statistics
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Hashable, Iterable, Mapping, Sequence, TypeVar

from globe.data.records import Day, Household

T = TypeVar("T")

SCORE_DECIMALS = 10
"""Scores are compared to this many decimals: candidates closer than that tie (the first listed wins)."""


def folds(n: int, k: int) -> list[tuple[list[int], list[int]]]:
    """Contiguous k-fold split of n items: (train indices, validation indices)."""
    k = max(2, min(k, n))
    bounds = [round(i * n / k) for i in range(k + 1)]
    return [([j for j in range(n) if not bounds[i] <= j < bounds[i + 1]], list(range(bounds[i], bounds[i + 1])))
            for i in range(k)]


def grid(space: Mapping[str, Sequence[Any]]) -> list[dict[str, Any]]:
    """Every combination of the values of ``space``, the first key varying slowest."""
    keys = list(space)
    return [dict(zip(keys, values)) for values in itertools.product(*(space[k] for k in keys))]


@dataclass(frozen=True, slots=True)
class Selection:
    """The chosen candidate, every candidate's score (higher is better: the criterion), what was
    measured beside it (``metrics``: per candidate, e.g. log loss and F1), and the time it took."""

    best: dict[str, Any]
    scores: list[tuple[dict[str, Any], float]] = field(default_factory=list)
    seconds: float = 0.0
    criterion: str = "f1"
    metrics: list[dict[str, float]] = field(default_factory=list)
    at_edge: tuple[str, ...] = ()  # settings whose chosen value is the last tried in its direction (see widening)


def best_of(scored: Sequence[tuple[T, float]]) -> T:
    """The candidate with the highest score (to :data:`SCORE_DECIMALS` decimals; ties: the first)."""
    if not scored:
        raise ValueError("no candidate to choose from")
    top = max(round(s, SCORE_DECIMALS) for _, s in scored)
    return next(c for c, s in scored if round(s, SCORE_DECIMALS) == top)


def select(candidates: Sequence[dict[str, Any]], score: Callable[[dict[str, Any]], float]) -> Selection:
    """Score every candidate and keep :func:`best_of` them, timing the search."""
    started = time.perf_counter()
    scored = [(dict(c), score(c)) for c in candidates]
    return Selection(dict(best_of(scored)) if scored else {}, scored, time.perf_counter() - started)


def select_by(candidates: Sequence[dict[str, Any]], measure: Callable[[dict[str, Any]], dict[str, float]],
              criterion: str) -> Selection:
    """:func:`select` where each candidate is measured several ways (``measure``: metric ->
    value) and ``criterion`` chooses: ``log_loss`` (lower is better, scored as its negative) or
    another metric (higher is better)."""
    started = time.perf_counter()
    measured = [(dict(c), measure(c)) for c in candidates]
    sign = -1.0 if criterion == "log_loss" else 1.0
    scored = [(c, sign * m[criterion]) for c, m in measured]
    return Selection(dict(best_of(scored)) if scored else {}, scored, time.perf_counter() - started, criterion,
                     [m for _, m in measured])


BEYOND_NOISE = 1.0
"""Standard errors by which a candidate must beat the first (the default) to replace it, in the
searches that choose a *decision* (:func:`best_beyond_noise`): the one-standard-error rule."""


def best_beyond_noise(per_fold: Sequence[tuple[T, Sequence[float]]], k: float = BEYOND_NOISE) -> T:
    """The first candidate (the default: the plain argmax, never asking the LLM) unless others beat
    it fold by fold: of those whose mean paired gain over it exceeds ``k`` standard errors of that
    gain, the one with the highest mean (ties: the first). A decision rule picked by a gain of a
    few thousandths, smaller than the folds disagree by, is noise that test days do not repeat."""
    if not per_fold:
        raise ValueError("no candidate to choose from")
    first, base = per_fold[0]
    best, best_gain = first, 0.0
    for candidate, scores in per_fold[1:]:
        gains = [a - b for a, b in zip(scores, base)]
        if len(gains) < 2:
            continue
        mean = statistics.fmean(gains)
        se = statistics.stdev(gains) / math.sqrt(len(gains))
        if mean > k * se and round(mean, SCORE_DECIMALS) > round(best_gain, SCORE_DECIMALS):
            best, best_gain = candidate, mean
    return best


def select_beyond_noise(candidates: Sequence[dict[str, Any]],
                        measure: Callable[[dict[str, Any]], Sequence[dict[str, float]]], criterion: str) -> Selection:
    """:func:`select_by` where ``measure`` gives one metric dict per fold and the first candidate
    keeps its place unless another beats it beyond noise (:func:`best_beyond_noise`; ``criterion``
    higher is better). The scores kept are the means over the folds."""
    started = time.perf_counter()
    measured = [(dict(c), list(measure(c))) for c in candidates]
    per_fold = [(c, [m[criterion] for m in folds]) for c, folds in measured]
    means = [{name: statistics.fmean(m[name] for m in folds) for name in folds[0]} if folds else {}
             for _, folds in measured]
    best = best_beyond_noise(per_fold) if per_fold else {}
    return Selection(dict(best), [(c, m.get(criterion, 0.0)) for (c, _), m in zip(measured, means)],
                     time.perf_counter() - started, criterion, means)


Beyond = Callable[[Any, bool], Any]
"""``beyond(edge, upward)``: the next value past ``edge`` of a setting's grid (None: none)."""


def _edges(candidates: Sequence[dict[str, Any]], best: dict[str, Any], key: str) -> tuple[Any, Any] | None:
    """The lowest and highest ``key`` tried among candidates equal to ``best`` but for it."""
    tried = [c[key] for c in candidates if key in c and all(c.get(k) == v for k, v in best.items() if k != key)]
    return (min(tried), max(tried)) if tried else None


def select_widening(candidates: Sequence[dict[str, Any]], measure: Callable[[dict[str, Any]], dict[str, float]],
                    criterion: str, beyond: Mapping[str, Beyond], rounds: int = 3) -> Selection:
    """:func:`select_by`, then, while the best sits at an edge of a setting of ``beyond`` (its
    highest or lowest value tried), the value past that edge is tried too (up to ``rounds``
    times): a grid that stops before the optimum says so by choosing its edge. What still sits at
    an edge afterwards is named in :attr:`Selection.at_edge`. Each candidate is measured once."""
    measured: dict[tuple, dict[str, float]] = {}

    def once(c: dict[str, Any]) -> dict[str, float]:
        key = tuple(sorted(c.items()))
        if key not in measured:
            measured[key] = measure(c)
        return measured[key]

    started, tried = time.perf_counter(), [dict(c) for c in candidates]
    chosen = select_by(tried, once, criterion)
    for _ in range(rounds):
        more: list[dict[str, Any]] = []
        for key, step in beyond.items():
            edges = _edges(tried, chosen.best, key) if key in chosen.best else None
            if edges is None:
                continue
            for edge, upward in ((edges[1], True), (edges[0], False)):
                value = step(edge, upward) if chosen.best[key] == edge else None
                if value is not None and chosen.best | {key: value} not in tried + more:
                    more.append(chosen.best | {key: value})
        if not more:
            break
        tried += more
        chosen = select_by(tried, once, criterion)
    at_edge = []
    for key in beyond:
        edges = _edges(tried, chosen.best, key) if key in chosen.best else None
        if edges is not None and edges[0] != edges[1] and chosen.best[key] in edges:
            at_edge.append(key)
    return Selection(chosen.best, chosen.scores, time.perf_counter() - started, criterion, chosen.metrics,
                     tuple(at_edge))


# -- what results depend on ------------------------------------------------------------------

_FINGERPRINTS: dict[int, tuple[tuple[Day, ...], str]] = {}


def fingerprint(days: Sequence[Day]) -> str:
    """A digest of the content of ``days`` (names, minutes, activities, places): equal for equal
    days, whatever object holds them (memoised for the tuples a household holds)."""
    days = tuple(days)
    hit = _FINGERPRINTS.get(id(days))
    if hit is not None and hit[0] is days:
        return hit[1]
    digest = hashlib.sha256()
    rows: dict[int, bytes] = {}
    for day in days:
        digest.update(f"{day.name}\x00{','.join(map(str, day.minutes))}\x00{chr(31).join(day.activities)}\x00".encode())
        for row in day.locations:
            code = rows.get(id(row))
            if code is None:
                code = rows[id(row)] = hashlib.sha256(chr(31).join(row).encode()).digest()[:8]
            digest.update(code)
    out = digest.hexdigest()[:32]
    if len(_FINGERPRINTS) > 256:
        _FINGERPRINTS.clear()
    _FINGERPRINTS[id(days)] = (days, out)
    return out


@dataclass(frozen=True, slots=True)
class DataKey:
    """The days a result was computed from: the household and a fingerprint of the days' content
    (a noisy variant of a household shares its name, never its fingerprint)."""

    household: str
    days: str
    objects: tuple[str, ...]

    @classmethod
    def of(cls, household: Household, days: Sequence[Day] | None = None) -> "DataKey":
        return cls(household.name, fingerprint(household.train if days is None else days), household.objects)


@dataclass(frozen=True, slots=True)
class Fold:
    """Fold ``index`` of a ``k``-fold split of the training days of ``data``: its days are
    :func:`folds`' (train, validation) indices of that fold."""

    data: DataKey
    k: int
    index: int


@dataclass(frozen=True, slots=True)
class FitKey:
    """A model fitted on a fold's training part (``fold``) or on every training day (``fold``
    None): which model (``model``), its fit parameters and the movement alignment it counted with."""

    model: str
    data: DataKey
    fold: Fold | None
    params: Hashable
    alignment: str | None = None


@dataclass(frozen=True, slots=True)
class SearchKey:
    """A cross-validated choice: which search, on which days, over which space (the settings
    searched), from which fixed settings (``given``), with ``k`` folds and the alignment."""

    search: str
    data: DataKey
    space: Hashable
    given: Hashable
    k: int
    alignment: str | None


def frozen_params(params: Mapping[str, Any]) -> tuple[tuple[str, Any], ...]:
    """A parameter mapping as a key part (sorted (name, value) pairs)."""
    return tuple(sorted(params.items()))


class Memo:
    """Results by frozen keys (:class:`FitKey`, :class:`SearchKey`, or another frozen dataclass
    naming every input): what one stage computes, a later one reuses."""

    def __init__(self) -> None:
        self._items: dict[Hashable, Any] = {}

    def get(self, key: Hashable, make: Callable[..., T], *args: Any) -> T:
        """The result under ``key``, ``make(*args)`` (kept) on first use."""
        try:
            return self._items[key]
        except KeyError:
            value = self._items[key] = make(*args)
            return value

    def __contains__(self, key: Hashable) -> bool:
        return key in self._items

    def __len__(self) -> int:
        return len(self._items)

    def put(self, key: Hashable, value: Any) -> None:
        self._items[key] = value

    def keys(self) -> frozenset[Hashable]:
        return frozenset(self._items)

    def entries(self, where: Callable[[Hashable], bool]) -> dict[Hashable, Any]:
        """The results whose keys pass ``where`` (what a worker process hands back)."""
        return {k: v for k, v in self._items.items() if where(k)}

    def update(self, entries: Iterable[tuple[Hashable, Any]] | Mapping[Hashable, Any]) -> None:
        self._items.update(entries)
