"""Lookahead scored as SLaTe-PRO scores itself: the relocation metric at 10-60 minutes.

At every reference step r of a test day, knowing a_0..a_{r-1} as seen (the annotation, or the
activities recognised from sensors: :attr:`~globe.data.records.Day.seen`) and every object's
location up to step r, each tracked object gets a prediction for each horizon s = 0..H-1: will it
be somewhere else than at step r at some step r+1..r+1+s, and if so where will it *first* be. A (reference
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
cross-validation on training days (the listed first values win ties). For GLOBE's routine model
the same cross-validation also offers the clock-aware object model
(:class:`~globe.models.baselines.HourActivityAhead` with ``clock=True``: P(an object's first move
within each horizon | the activity, the hour, the day type, the time since its last use)) in place
of the movement model's forecast; ``lookahead_selection.csv`` says which won (``objects``).

Beside the models, two rows that are no model: the object baseline (:data:`BASELINE`, the hour
and the activity alone) and the *oracle* (:data:`ORACLE`), the movement model told the true
activity of every step up to the horizon, so only where objects go is predicted: not deployable,
it shows what perfect activity knowledge would give and so how much of a gap is the activity's.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np

from globe import assembly
from globe.config import GlobeConfig, LookaheadConfig, ModelConfig
from globe.data.records import Day, Household
from globe.evaluation.relocation import (
    LookaheadRun,
    RelocationCounts,
    _coded,
    _in_use,
    reference_queries,
    reference_steps,
    score_arrays,
    score_forecasts,
)
from globe.evaluation.selection import DataKey, FitKey, Fold, Memo, SearchKey, Selection, best_of
from globe.evaluation.tuning import data_folds, fold_days
from globe.inference.forecast import Forecaster, Forecasts, forecast_known
from globe.inference.movements import MovementModel
from globe.models.baselines import (
    HOUR_ACTIVITY,
    ORACLE,
    HourActivityAhead,
    HourActivityBaseline,
    minutes_since_use,
    mode,
    used_matrix,
)


def forecast_days(forecaster: Forecaster | MovementModel, days: Sequence[Day], horizons: int, first: int = 1,
                  last: int | None = None, stride: int = 1, chunk: int = 256) -> LookaheadRun:
    """Forecast every reference step of ``days`` and collect the pairs of each horizon. A movement
    model alone forecasts as the oracle does (:func:`oracle_forecasts`)."""
    run = LookaheadRun.empty(horizons)
    refs = reference_queries(days, horizons, first, last, stride)
    rows: dict = {}
    for lo in range(0, len(refs), chunk):
        part = refs[lo: lo + chunk]
        if isinstance(forecaster, MovementModel):
            score_forecasts(run, oracle_forecasts(forecaster, part, horizons), part, None, rows)
            continue
        fcs = forecaster.forecast_many([(day.seen[:r], day.locations[: r + 1]) for day, r in part], horizons - 1,
                                       weekdays=[day.weekday for day, _ in part])
        score_forecasts(run, fcs, part, forecaster.activity, rows)
    return run


def oracle_forecasts(movements: MovementModel, refs: Sequence[tuple[Day, int]], horizons: int) -> Forecasts:
    """The oracle's forecasts at ``refs``: ``movements`` told the true activities a_r..a_{r+horizons}
    (:func:`~globe.inference.forecast.forecast_known`)."""
    return forecast_known(movements, [(day.activities[:r], day.locations[: r + 1]) for day, r in refs],
                          [day.activities[r: r + horizons + 1] for day, r in refs], horizons - 1)


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


def cv_key(household: Household, config: GlobeConfig, models: ModelConfig, setting: Setting,
           oracle: bool = False) -> SearchKey:
    """What the held-out pairs of one movement setting depend on (the oracle's: not the activity model)."""
    if oracle:
        return SearchKey("lookahead-oracle-cv", DataKey.of(household), (config.lookahead, setting), None,
                         config.selection.folds, None)
    return SearchKey("lookahead-cv", DataKey.of(household), (config.lookahead, setting), models, config.selection.folds,
                     None)


def cv_runs(household: Household, config: GlobeConfig, models: ModelConfig, settings: Sequence[Setting],
            memo: Memo, oracle: bool = False) -> dict[Setting, LookaheadRun]:
    """Pairs of every held-out *training* day (contiguous folds, every ``cv_stride``-th reference)
    for each movement setting (run end, run memory, next activity): each fold's activity model is
    fitted once and its activity paths are shared by every setting (the ``oracle`` follows the
    true activities instead: :func:`oracle_forecasts`). Kept in ``memo``."""
    la, horizons = config.lookahead, assembly.lookahead_steps(config, household)
    todo = [s for s in dict.fromkeys(settings) if cv_key(household, config, models, s, oracle) not in memo]
    runs: dict[Setting, list[LookaheadRun]] = {setting: [] for setting in todo}
    for fold in data_folds(household, config.selection.folds) if todo else ():
        train, held_out = fold_days(household, fold)
        step = assembly.step_minutes(household, config)
        refs = reference_queries(held_out, horizons, la.first_reference, la.last_reference, la.cv_stride)
        if oracle:
            for setting in todo:
                run = LookaheadRun.empty(horizons)
                mv = movements_on(household, la, fold, setting, memo, step)
                score_forecasts(run, oracle_forecasts(mv, refs, horizons), refs, None, {})
                runs[setting].append(run)
            continue
        activity = assembly.fitted_activity_model(models, step, train)
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
        memo.put(cv_key(household, config, models, setting, oracle), pool(runs[setting], horizons))
    return {s: memo.get(cv_key(household, config, models, s, oracle), lambda: None)  # type: ignore[misc]
            for s in settings}


MOVEMENTS, CLOCK = "movements", "clock"
"""Where a lookahead row's objects come from: the movement model's forecast, or the clock-aware
object model (:class:`~globe.models.baselines.HourActivityAhead`, ``clock=True``)."""


def choose_settings(household: Household, config: GlobeConfig, models: ModelConfig, memo: Memo,
                    run_ends: Sequence[bool] | None = None, oracle: bool = False,
                    objects: Sequence[str] = (MOVEMENTS,)) -> Selection:
    """The movement model's settings (run end of ``run_ends``, default ``lookahead.run_end``;
    run memory of ``lookahead.run_memory`` and the next activity of ``lookahead.run_next``, both
    only with the run end) and a change threshold per horizon, by F1 on held-out *training* days
    (of the ``oracle``'s forecasts, told the true activity, when asked). With :data:`CLOCK` in
    ``objects`` the clock-aware object model is a candidate too, after every setting.
    The candidate with the best mean over horizons of each horizon's best F1 wins, then each
    horizon takes its best threshold; ties go to the first listed values (the simpler model, the
    higher threshold).
    ``best``: ``{"run_end": bool, "run_memory": bool, "run_next": bool, "thresholds": (one per horizon)}``
    and, where the clock-aware model was offered, ``"objects"`` (:data:`MOVEMENTS` or :data:`CLOCK`)."""
    la = config.lookahead
    settings = _settings(config, run_ends)
    offered = tuple(objects) if objects != (MOVEMENTS,) else ()
    key = SearchKey("lookahead-oracle" if oracle else "lookahead", DataKey.of(household),
                    (la, tuple(settings), *((offered,) if offered else ())), None if oracle else models,
                    config.selection.folds, None)
    return memo.get(key, _choose, household, config, models, settings, memo, oracle, offered)


def _choose(household: Household, config: GlobeConfig, models: ModelConfig, settings: Sequence[Setting],
            memo: Memo, oracle: bool = False, offered: Sequence[str] = ()) -> Selection:
    la = config.lookahead
    started = time.perf_counter()
    pooled_runs = cv_runs(household, config, models, settings, memo, oracle)
    scores: list[tuple[dict, float]] = []
    per_setting: list[tuple[dict, float]] = []

    def offer(named: dict, run: LookaheadRun | None) -> None:
        assert run is not None
        per = threshold_f1s(run, la.thresholds)
        scores.extend(({**named, "horizon": s, "threshold": t}, f)
                      for s, row in enumerate(per) for t, f in zip(la.thresholds, row))
        best = float(np.mean([max(row) for row in per]))
        per_setting.append(({**named, "thresholds": best_thresholds(per, la.thresholds)}, best))

    objects = {"objects": MOVEMENTS} if offered else {}
    for setting in settings:
        offer({**dict(zip(SETTING_KEYS, setting)), **objects}, pooled_runs[setting])
    if CLOCK in offered:  # with the movement setting that won: the forecaster's activity and fetch session keep it
        movement = {k: v for k, v in best_of(per_setting).items() if k in SETTING_KEYS}
        offer({**movement, "objects": CLOCK}, moves_baseline_cv(household, config, clock=True))
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
    objects: str = "movements"  # whose objects were scored: the movement model's forecast, the clock-aware
    # model (CLOCK) or, for the baseline row, the baseline's


# The training time reported is the best of this many fits (as timeit): what it costs, not the machine's noise.
TIMING_FITS = 3


CLOCK_OFFERED_TO = ("routine",)
"""The lookahead methods whose cross-validation is offered the clock-aware object model: GLOBE's
own (persistence and the n-gram stay the paper's comparisons)."""


def evaluate_lookahead(household: Household, config: GlobeConfig, models: ModelConfig, method: str,
                       memo: Memo) -> LookaheadResult:
    """Choose the settings on training days, fit on all of them, score the test days (the
    objects of the clock-aware model where cross-validation chose it, the activity ahead still
    the forecaster's)."""
    la = config.lookahead
    if method == ORACLE:
        return evaluate_oracle(household, config, memo)
    offered = (MOVEMENTS, CLOCK) if method in CLOCK_OFFERED_TO else (MOVEMENTS,)
    chosen = choose_settings(household, config, models, memo, objects=offered)
    run_end, run_memory, run_next = setting_of(chosen.best)
    fits = [assembly.forecaster(household, config, models=models, run_end=run_end, run_memory=run_memory,
                                run_next=run_next) for _ in range(TIMING_FITS)]
    fitted = fits[0]
    horizons = assembly.lookahead_steps(config, household)
    run = forecast_days(fitted.forecaster, household.test, horizons, la.first_reference, la.last_reference)
    train_s = min(f.train_s for f in fits)
    if chosen.best.get("objects") == CLOCK:
        started = time.perf_counter()
        clock = fit_moves_baseline(household.train, household.objects, horizons, la, clock=True)
        train_s += time.perf_counter() - started
        run.pairs = baseline_days(clock, household.test, horizons, la.first_reference, la.last_reference).pairs
    ts = tuple(float(t) for t in chosen.best["thresholds"])
    return LookaheadResult(method, household.name, ts, tuple(p.counts(t) for p, t in zip(run.pairs, ts)),
                           tuple(run.activity_accuracy()), train_s, chosen, run_end, run_memory,
                           run_next, fitted.forecaster, str(chosen.best.get("objects", MOVEMENTS)))


def evaluate_oracle(household: Household, config: GlobeConfig, memo: Memo) -> LookaheadResult:
    """The oracle row: its movement setting and thresholds chosen by F1 on held-out training days
    (its own forecasts there, told the true activities), the movement model fitted on every
    training day, the test days scored (its activity accuracy is 1 by construction)."""
    la = config.lookahead
    chosen = choose_settings(household, config, config.models, memo, oracle=True)
    setting = setting_of(chosen.best)
    step = assembly.step_minutes(household, config)
    started = time.perf_counter()
    movements = assembly.movement_model(la, step, *setting).fit(household.train, household.objects)
    train_s = time.perf_counter() - started
    run = forecast_days(movements, household.test, assembly.lookahead_steps(config, household), la.first_reference,
                        la.last_reference)
    ts = tuple(float(t) for t in chosen.best["thresholds"])
    return LookaheadResult(ORACLE, household.name, ts, tuple(p.counts(t) for p, t in zip(run.pairs, ts)),
                           tuple(run.activity_accuracy()), train_s, chosen, *setting)


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


def since_use(day: Day, objects: Sequence[str]) -> np.ndarray:
    """(steps x objects): minutes since each object's last use that day, at each step
    (:func:`~globe.models.baselines.minutes_since_use` of :func:`~globe.models.baselines.used_matrix`)."""
    return minutes_since_use(used_matrix(day, objects), day.minutes)


def fit_moves_baseline(days: Sequence[Day], objects: Sequence[str], horizons: int, la: LookaheadConfig,
                       clock: bool = False) -> MovesBaseline:
    """:class:`MovesBaseline` on ``days`` (every reference step the lookahead would score); with
    ``clock``, its first moves by the clock-aware object model (day type, time since last use)."""
    from collections import Counter

    moves = HourActivityAhead(objects, horizons, clock=clock)
    goes: dict[tuple[int, str], Counter[str]] = {}
    seen: set[str] = set()
    for day in days:
        rs = list(reference_steps(day, horizons, la.first_reference, la.last_reference))
        moves.add([day.activities[r - 1] for r in rs], [day.minutes[r - 1] for r in rs], first_moves(day, rs, horizons),
                  ~_in_use(day)[rs], day.weekday, since_use(day, objects)[rs] if clock else None)
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
    since = {id(day): since_use(day, baseline.moves.objects) for day in days} if baseline.moves.clock else {}
    for q, (day, r) in enumerate(refs):
        current, minute = day.seen[r - 1], day.minutes[r - 1]
        here = day.locations[r]
        for j in range(n_obj):
            place, share = baseline.places.get((j, here[j])) or baseline.anywhere.get(j, (UNKNOWN_PLACE, 0.0))
            best[q, :, j] = index[place]
            prob[q, :, j] = share
        prob[q] *= baseline.moves.proba(current, minute, day.weekday, since[id(day)][r] if since else None)
        for s in range(horizons):
            said = mode(baseline.activity.proba(current, minute, s + 1))
            top[q, s] = codes.get(said, -1) if said is not None else -1
    score_arrays(run, refs, best, prob, top, labels, baseline.locations, {})
    return run


def moves_baseline_cv(household: Household, config: GlobeConfig, clock: bool = False) -> LookaheadRun:
    """The pairs of the object baseline (or, with ``clock``, the clock-aware object model) on
    held-out training days: contiguous folds, every ``cv_stride``-th reference, as the models'."""
    la, horizons = config.lookahead, assembly.lookahead_steps(config, household)
    runs = []
    for fold in data_folds(household, config.selection.folds):
        train, held_out = fold_days(household, fold)
        fitted = fit_moves_baseline(train, household.objects, horizons, la, clock)
        runs.append(baseline_days(fitted, held_out, horizons, la.first_reference, la.last_reference, la.cv_stride))
    return pool(runs, horizons)


def evaluate_moves_baseline(household: Household, config: GlobeConfig) -> LookaheadResult:
    """The baseline row: its change threshold per horizon chosen by F1 on held-out training days
    (:func:`moves_baseline_cv`), then counted on every training day and scored on the test days."""
    la, horizons = config.lookahead, assembly.lookahead_steps(config, household)
    started = time.perf_counter()
    per = threshold_f1s(moves_baseline_cv(household, config), la.thresholds)
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
                           train_s, selection, False, False, False, objects=BASELINE)
