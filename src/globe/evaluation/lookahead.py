"""Lookahead scored as SLaTe-PRO scores itself: the relocation metric at 10-60 minutes.

At every reference step r of a test day, knowing a_0..a_{r-1} and every object's location up to
step r, each tracked object gets a prediction for each horizon s = 0..H-1: will it be somewhere
else than at step r at some step r+1..r+1+s, and if so where will it *first* be. A (reference
step x object) pair is *correct* when a change is predicted, a change happens and the predicted
first new location is the true one; precision = correct / predicted changes, recall = correct /
true changes (micro-averaged over pairs pooled over the test days), F1 from those. An object
that moves twice within the horizon counts by its first new place; one that moves away and back
still changed (its first new place is where it went). An object in use at r (at a place of class
``in_use``, :mod:`globe.sequences.movements`) is left out of that step's pairs: its next move is
being put back, which no one needs foreseen.

A change is predicted when the forecaster's P(first new place = its best guess) reaches a
threshold (one per horizon); the thresholds and whether movement hazards know that an activity
ends (and then what moved earlier in its run, and which activity starts) are chosen by
cross-validation on training days (the listed first values win ties).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np

from globe import assembly
from globe.config import GlobeConfig, LookaheadConfig, ModelConfig
from globe.data.records import Day, Household, is_use_place
from globe.evaluation.selection import DataKey, FitKey, Fold, Memo, SearchKey, Selection, best_of
from globe.evaluation.tuning import data_folds, fold_days
from globe.inference.forecast import Forecaster, Forecasts
from globe.inference.movements import MovementModel
from globe.models.base import ActivityModelBase
from globe.models.baselines import HOUR_ACTIVITY, HourActivityAhead, HourActivityBaseline, mode


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


def score_forecasts(run: LookaheadRun, forecasts: Forecasts, refs: Sequence[tuple[Day, int]], model: ActivityModelBase,
                    location_rows: dict) -> None:
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


def top_activities(dense: np.ndarray, names: Sequence[str], model: ActivityModelBase, horizons: int) -> np.ndarray:
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


def forecast_days(forecaster: Forecaster, days: Sequence[Day], horizons: int, first: int = 1, last: int | None = None,
                  stride: int = 1, chunk: int = 256) -> LookaheadRun:
    """Forecast every reference step of ``days`` and collect the pairs of each horizon."""
    run = LookaheadRun.empty(horizons)
    refs = reference_queries(days, horizons, first, last, stride)
    rows: dict = {}
    for lo in range(0, len(refs), chunk):
        part = refs[lo: lo + chunk]
        fcs = forecaster.forecast_many([(day.activities[:r], day.locations[: r + 1]) for day, r in part], horizons - 1,
                                       weekdays=[day.weekday for day, _ in part])
        score_forecasts(run, fcs, part, forecaster.activity, rows)
    return run


Setting = tuple[bool, bool, bool]  # the movement model's (run_end, run_memory, run_next)
SETTING_KEYS = ("run_end", "run_memory", "run_next")


def setting_of(best: Mapping[str, Any]) -> Setting:
    """The movement setting of a :func:`choose_settings` choice."""
    run_end, run_memory, run_next = (bool(best[k]) for k in SETTING_KEYS)
    return run_end, run_memory, run_next


def threshold_f1s(run: LookaheadRun, thresholds: Sequence[float]) -> list[list[float]]:
    """Per horizon, the F1 of ``run``'s pairs at each of ``thresholds``."""
    return [[p.counts(t).f1 for t in thresholds] for p in run.pairs]


def best_thresholds(f1s: Sequence[Sequence[float]], thresholds: Sequence[float]) -> tuple[float, ...]:
    """Each horizon's best threshold of :func:`threshold_f1s` (the first listed wins ties)."""
    return tuple(float(best_of(list(zip(thresholds, row)))) for row in f1s)


def _settings(config: GlobeConfig, run_ends: Sequence[bool] | None = None) -> list[Setting]:
    """Every movement setting tried (run memory and the next activity only with the run end)."""
    la = config.lookahead
    return [(e, mem, nxt) for e in (la.run_end if run_ends is None else run_ends) for mem in la.run_memory
            for nxt in la.run_next if e or not (mem or nxt)]


def movements_on(household: Household, la: LookaheadConfig, fold: Fold | None, setting: Setting,
                 memo: Memo, step_minutes: int) -> MovementModel:
    """The movement model of ``setting`` fitted on a fold's training part (or every training day),
    once: every activity model of a cross-validation shares the folds' movement models."""
    days = household.train if fold is None else fold_days(household, fold)[0]
    key = FitKey("MovementModel", DataKey.of(household), fold,
                 (la.hazard_shrinkage, la.duration_cap_minutes, la.destination_shrinkage, setting, step_minutes))
    return memo.get(key, lambda: assembly.movement_model(la, step_minutes, *setting).fit(days, household.objects))


def cv_key(household: Household, config: GlobeConfig, models: ModelConfig, setting: Setting) -> SearchKey:
    """What the held-out pairs of one movement setting depend on."""
    return SearchKey("lookahead-cv", DataKey.of(household), (config.lookahead, setting), models, config.selection.folds,
                     None)


def cv_runs(household: Household, config: GlobeConfig, models: ModelConfig, settings: Sequence[Setting],
            memo: Memo) -> dict[Setting, LookaheadRun]:
    """Pairs of every held-out *training* day (contiguous folds, every ``cv_stride``-th reference)
    for each movement setting (run end, run memory, next activity): each fold's activity model is
    fitted once and its activity paths are shared by every setting. Kept in ``memo``."""
    la, horizons = config.lookahead, assembly.lookahead_steps(config, household)
    todo = [s for s in dict.fromkeys(settings) if cv_key(household, config, models, s) not in memo]
    runs: dict[Setting, list[LookaheadRun]] = {setting: [] for setting in todo}
    for fold in data_folds(household, config.selection.folds) if todo else ():
        train, held_out = fold_days(household, fold)
        step = assembly.step_minutes(household, config)
        activity = assembly.fitted_activity_model(models, step, train)
        refs = reference_queries(held_out, horizons, la.first_reference, la.last_reference, la.cv_stride)
        queries = [(day.activities[:r], day.locations[: r + 1]) for day, r in refs]
        weekdays = [day.weekday for day, _ in refs]
        trees = None
        for setting in todo:
            fc = assembly.forecaster_over(activity, movements_on(household, la, fold, setting, memo, step), la)
            if trees is None:
                trees = fc.trees(fc.roots([a for a, _ in queries], [r for _, r in refs], weekdays), horizons - 1)
            run = LookaheadRun.empty(horizons)
            forecasts = fc.forecast_many(queries, horizons - 1, trees=trees, weekdays=weekdays)
            score_forecasts(run, forecasts, refs, activity, {})
            runs[setting].append(run)
    for setting in todo:
        memo.put(cv_key(household, config, models, setting), pool(runs[setting], horizons))
    return {s: memo.get(cv_key(household, config, models, s), lambda: None) for s in settings}  # type: ignore[misc]


def choose_settings(household: Household, config: GlobeConfig, models: ModelConfig, memo: Memo,
                    run_ends: Sequence[bool] | None = None) -> Selection:
    """The movement model's settings (run end of ``run_ends``, default ``lookahead.run_end``;
    run memory of ``lookahead.run_memory`` and the next activity of ``lookahead.run_next``, both
    only with the run end) and a change threshold per horizon, by F1 on held-out *training* days.
    The setting with the best mean over horizons of each horizon's best F1 wins, then each
    horizon takes its best threshold; ties go to the first listed values (the simpler model, the
    higher threshold).
    ``best``: ``{"run_end": bool, "run_memory": bool, "run_next": bool, "thresholds": (one per horizon)}``."""
    la = config.lookahead
    settings = _settings(config, run_ends)
    key = SearchKey("lookahead", DataKey.of(household), (la, tuple(settings)), models, config.selection.folds, None)
    return memo.get(key, _choose, household, config, models, settings, memo)


def _choose(household: Household, config: GlobeConfig, models: ModelConfig, settings: Sequence[Setting],
            memo: Memo) -> Selection:
    la = config.lookahead
    started = time.perf_counter()
    pooled_runs = cv_runs(household, config, models, settings, memo)
    scores: list[tuple[dict, float]] = []
    per_setting: list[tuple[dict, float]] = []
    for setting in settings:
        named = dict(zip(SETTING_KEYS, setting))
        per = threshold_f1s(pooled_runs[setting], la.thresholds)
        scores.extend(({**named, "horizon": s, "threshold": t}, f)
                      for s, row in enumerate(per) for t, f in zip(la.thresholds, row))
        best = float(np.mean([max(row) for row in per]))
        per_setting.append(({**named, "thresholds": best_thresholds(per, la.thresholds)}, best))
    return Selection(best_of(per_setting), scores, time.perf_counter() - started)


def pool(runs: Sequence[LookaheadRun], horizons: int) -> LookaheadRun:
    """The pairs and activity counts of several runs together."""
    pooled = LookaheadRun.empty(horizons)
    for run in runs:
        for s in range(horizons):
            for name in ("probability", "hit", "true"):
                getattr(pooled.pairs[s], name).extend(getattr(run.pairs[s], name))
        pooled.activity_correct += run.activity_correct
        pooled.activity_total += run.activity_total
    return pooled


@dataclass(frozen=True, slots=True)
class LookaheadResult:
    """One method on one household: the chosen thresholds and the test-day counts per horizon."""

    method: str
    household: str
    thresholds: tuple[float, ...]  # one per horizon
    counts: tuple[RelocationCounts, ...]
    activity_accuracy: tuple[float, ...]
    train_s: float
    selection: Selection
    run_end: bool = True
    run_memory: bool = False
    run_next: bool = False
    forecaster: Forecaster | None = field(default=None, compare=False, repr=False)  # fitted on every training day


# The training time reported is the best of this many fits (as timeit): what it costs, not the machine's noise.
TIMING_FITS = 3


def evaluate_lookahead(household: Household, config: GlobeConfig, models: ModelConfig, method: str,
                       memo: Memo) -> LookaheadResult:
    """Choose the settings on training days, fit on all of them, score the test days."""
    la = config.lookahead
    chosen = choose_settings(household, config, models, memo)
    run_end, run_memory, run_next = setting_of(chosen.best)
    fits = [assembly.forecaster(household, config, models=models, run_end=run_end, run_memory=run_memory,
                                run_next=run_next) for _ in range(TIMING_FITS)]
    fitted = fits[0]
    run = forecast_days(fitted.forecaster, household.test, assembly.lookahead_steps(config, household),
                        la.first_reference, la.last_reference)
    ts = tuple(float(t) for t in chosen.best["thresholds"])
    return LookaheadResult(method, household.name, ts, tuple(p.counts(t) for p, t in zip(run.pairs, ts)),
                           tuple(run.activity_accuracy()), min(f.train_s for f in fits), chosen, run_end, run_memory,
                           run_next, fitted.forecaster)


LOOKAHEAD_COLUMNS = ("method", "household", "horizon_min", "precision", "recall", "f1", "activity_accuracy")


def lookahead_rows(results: Sequence[LookaheadResult], step_minutes: int = 10) -> list[dict]:
    """``lookahead.csv`` rows: each method x household x horizon, and the mean over households."""
    rows: list[dict] = []
    for method in dict.fromkeys(r.method for r in results):
        mine = [r for r in results if r.method == method]
        for res in mine:
            for s, (c, acc) in enumerate(zip(res.counts, res.activity_accuracy)):
                rows.append({"method": method, "household": res.household, "horizon_min": step_minutes * (s + 1),
                             "precision": round(c.precision, 4), "recall": round(c.recall, 4), "f1": round(c.f1, 4),
                             "activity_accuracy": round(float(acc), 4)})
        for s in range(min(len(r.counts) for r in mine)):
            rows.append({"method": method, "household": "mean", "horizon_min": step_minutes * (s + 1),
                         **{k: round(float(np.mean([getattr(r.counts[s], k) for r in mine])), 4)
                            for k in ("precision", "recall", "f1")},
                         "activity_accuracy": round(float(np.mean([r.activity_accuracy[s] for r in mine])), 4)})
    return rows


# ---- the object baseline's row ---------------------------------------------------------------

BASELINE = HOUR_ACTIVITY
"""The lookahead's baseline row: where objects go by the clock and the activity alone."""

UNKNOWN_PLACE = "<unknown>"


@dataclass(slots=True)
class MovesBaseline:
    """The lookahead's object baseline, counted on training days: P(an object's first move within
    each horizon | the activity under way, the clock slot) straight from the reference steps
    (:class:`~globe.models.baselines.HourActivityAhead`), its most frequent first new place from
    where it is (else overall), and the activity ahead by hour + activity
    (:class:`~globe.models.baselines.HourActivityBaseline`)."""

    moves: HourActivityAhead
    places: dict[tuple[int, str], tuple[str, float]]  # (object column, from) -> (its likeliest next place, share)
    anywhere: dict[int, tuple[str, float]]  # object column -> the same, from anywhere
    activity: HourActivityBaseline
    locations: tuple[str, ...]  # every place seen, then UNKNOWN_PLACE (as the movement model's)


def first_moves(day: Day, rs: Sequence[int], horizons: int) -> np.ndarray:
    """(references x horizons x objects): whether each object's first move after reference step r
    (to a place other than its place at r) comes within steps r+1..r+1+s, as the lookahead scores
    it (an object in use at r never: :func:`score_arrays`)."""
    ids, _ = _coded(day)
    at = np.asarray(rs, dtype=int)
    if not len(at):
        return np.zeros((0, horizons, ids.shape[1]), dtype=bool)
    future = ids[at[:, None] + 1 + np.arange(horizons)[None, :]]  # (refs, horizons, objects)
    window = future != ids[at][:, None, :]
    moved = window.any(axis=1) & ~_in_use(day)[at]
    first = window.argmax(axis=1)
    return moved[:, None, :] & (first[:, None, :] <= np.arange(horizons)[None, :, None])


def fit_moves_baseline(days: Sequence[Day], objects: Sequence[str], horizons: int, la: LookaheadConfig
                       ) -> MovesBaseline:
    """:class:`MovesBaseline` on ``days`` (every reference step the lookahead would score)."""
    from collections import Counter

    moves = HourActivityAhead(objects, horizons)
    goes: dict[tuple[int, str], Counter[str]] = {}
    seen: set[str] = set()
    for day in days:
        rs = list(reference_steps(day, horizons, la.first_reference, la.last_reference))
        moves.add([day.activities[r - 1] for r in rs], [day.minutes[r - 1] for r in rs], first_moves(day, rs, horizons),
                  ~_in_use(day)[rs])
        ids, names = _coded(day)
        seen.update(names)
        for t, j in zip(*np.nonzero(ids[1:] != ids[:-1])):
            goes.setdefault((int(j), names[ids[t, j]]), Counter())[names[ids[t + 1, j]]] += 1
    anywhere: dict[int, Counter[str]] = {}
    for (j, _), to in goes.items():
        anywhere.setdefault(j, Counter()).update(to)

    def likeliest(to: Counter[str]) -> tuple[str, float]:
        place = min(to, key=lambda x: (-to[x], x))
        return place, to[place] / sum(to.values())

    return MovesBaseline(moves, {k: likeliest(v) for k, v in goes.items()},
                         {j: likeliest(v) for j, v in anywhere.items()},
                         HourActivityBaseline(horizons).fit(days), (*sorted(seen), UNKNOWN_PLACE))


def baseline_days(baseline: MovesBaseline, days: Sequence[Day], horizons: int, first: int = 1,
                  last: int | None = None, stride: int = 1) -> LookaheadRun:
    """The pairs of ``baseline``'s predictions at every reference step of ``days``, scored as a
    forecaster's (:func:`score_arrays`): the predicted first new place with P(a first move within
    the horizon) x its share among the object's next places."""
    run = LookaheadRun.empty(horizons)
    refs = reference_queries(days, horizons, first, last, stride)
    if not refs:
        return run
    index = {x: i for i, x in enumerate(baseline.locations)}
    labels = list(baseline.activity.classes_)
    codes = {a: i for i, a in enumerate(labels)}
    n_obj = len(baseline.moves.objects)
    best = np.zeros((len(refs), horizons, n_obj), dtype=int)
    prob = np.zeros((len(refs), horizons, n_obj))
    top = np.full((len(refs), horizons), -1, dtype=int)
    for q, (day, r) in enumerate(refs):
        current, minute = day.activities[r - 1], day.minutes[r - 1]
        here = day.locations[r]
        for j in range(n_obj):
            place, share = baseline.places.get((j, here[j])) or baseline.anywhere.get(j, (UNKNOWN_PLACE, 0.0))
            best[q, :, j] = index[place]
            prob[q, :, j] = share
        prob[q] *= baseline.moves.proba(current, minute)
        for s in range(horizons):
            said = mode(baseline.activity.proba(current, minute, s + 1))
            top[q, s] = codes.get(said, -1) if said is not None else -1
    score_arrays(run, refs, best, prob, top, labels, baseline.locations, {})
    return run


def evaluate_moves_baseline(household: Household, config: GlobeConfig) -> LookaheadResult:
    """The baseline row: its change threshold per horizon chosen by F1 on held-out training days
    (contiguous folds, every ``cv_stride``-th reference, as the models'), then counted on every
    training day and scored on the test days."""
    la, horizons = config.lookahead, assembly.lookahead_steps(config, household)
    started = time.perf_counter()
    runs = []
    for fold in data_folds(household, config.selection.folds):
        train, held_out = fold_days(household, fold)
        fitted = fit_moves_baseline(train, household.objects, horizons, la)
        runs.append(baseline_days(fitted, held_out, horizons, la.first_reference, la.last_reference, la.cv_stride))
    per = threshold_f1s(pool(runs, horizons), la.thresholds)
    thresholds = best_thresholds(per, la.thresholds)
    plain = dict.fromkeys(SETTING_KEYS, False)
    selection = Selection({**plain, "thresholds": thresholds},
                          [({**plain, "horizon": s, "threshold": t}, f)
                           for s, row in enumerate(per) for t, f in zip(la.thresholds, row)],
                          time.perf_counter() - started)
    fit_started = time.perf_counter()
    fitted = fit_moves_baseline(household.train, household.objects, horizons, la)
    train_s = time.perf_counter() - fit_started
    run = baseline_days(fitted, household.test, horizons, la.first_reference, la.last_reference)
    return LookaheadResult(BASELINE, household.name, thresholds,
                           tuple(p.counts(t) for p, t in zip(run.pairs, thresholds)), tuple(run.activity_accuracy()),
                           train_s, selection, False, False, False)
