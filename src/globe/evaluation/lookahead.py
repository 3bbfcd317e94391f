"""Lookahead scored as SLaTe-PRO scores itself: the relocation metric at 10-60 minutes.

At every reference step r of a test day, knowing a_0..a_{r-1} and every object's location up to
step r, each tracked object gets a prediction for each horizon s = 0..H-1: will it be somewhere
else than at step r at some step r+1..r+1+s, and if so where will it *first* be. A (reference
step x object) pair is *correct* when a change is predicted, a change happens and the predicted
first new location is the true one; precision = correct / predicted changes, recall = correct /
true changes (micro-averaged over pairs pooled over the test days), F1 from those. An object
that moves twice within the horizon counts by its first new place; one that moves away and back
still changed (its first new place is where it went).

A change is predicted when the forecaster's P(first new place = its best guess) reaches a
threshold (one per horizon); the thresholds and whether movement hazards know that an activity
ends are chosen by cross-validation on training days (the listed first values win ties).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from globe import assembly
from globe.config import GlobeConfig, ModelConfig
from globe.data.records import Day, Household
from globe.evaluation.tuning import Selection, folds
from globe.models.forecast import Forecaster


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
    (None: it stays put throughout)."""
    here = locations[r]
    out: list[str | None] = []
    for j, loc in enumerate(here):
        out.append(next((locations[u][j] for u in range(r + 1, min(r + 2 + s, len(locations)))
                         if locations[u][j] != loc), None))
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

    def f1s(self, threshold: float) -> list[float]:
        return [p.counts(threshold).f1 for p in self.pairs]

    def activity_accuracy(self) -> list[float]:
        return [c / t if t else 0.0 for c, t in zip(self.activity_correct, self.activity_total)]


def reference_steps(day: Day, horizons: int, first: int, last: int, stride: int = 1) -> range:
    """r = first..last (every ``stride``-th), cut so that r + horizons stays inside the day."""
    return range(max(first, 1), min(last, len(day) - 1 - horizons) + 1, stride)


def forecast_days(forecaster: Forecaster, days: Sequence[Day], horizons: int, first: int = 1, last: int = 102,
                  stride: int = 1) -> LookaheadRun:
    """Forecast every reference step of ``days`` and collect the pairs of each horizon."""
    mv = forecaster.movements
    run = LookaheadRun(horizons, [HorizonPairs() for _ in range(horizons)], np.zeros(horizons, int), np.zeros(horizons, int))
    for day in days:
        locs = np.array([[mv.location_index(x) for x in row] for row in day.locations], dtype=int).reshape(len(day), -1)
        for r in reference_steps(day, horizons, first, last, stride):
            fc = forecaster.forecast(day.activities[:r], day.locations[: r + 1], horizons - 1)
            window = np.array(day.locations[r + 1: r + 1 + horizons], dtype=object) != np.array(day.locations[r], dtype=object)
            moved_any = window.any(axis=0)
            first_step = window.argmax(axis=0)
            true_loc = locs[r + 1 + first_step, np.arange(locs.shape[1])]
            joint = np.cumsum(fc.destination, axis=0)
            best = joint.argmax(axis=2)
            prob = np.take_along_axis(joint, best[:, :, None], axis=2)[:, :, 0]
            for s in range(horizons):
                true = moved_any & (first_step <= s)
                pairs = run.pairs[s]
                pairs.probability.append(prob[s])
                pairs.hit.append(true & (best[s] == true_loc))
                pairs.true.append(true)
                ranked = forecaster.activity.ranked(fc.activity[s])
                run.activity_total[s] += 1
                run.activity_correct[s] += bool(ranked) and ranked[0] == day.activities[r + s]
    return run


def _cv_run(household: Household, config: GlobeConfig, models: ModelConfig, run_end: bool,
            run_memory: bool = False) -> LookaheadRun:
    """Pairs of every held-out *training* day (contiguous folds, every ``cv_stride``-th reference)."""
    la = config.lookahead
    runs = []
    for train_idx, val_idx in folds(len(household.train), config.selection.folds):
        fitted = assembly.forecaster(household, config, days=[household.train[i] for i in train_idx], models=models,
                                     run_end=run_end, run_memory=run_memory)
        runs.append(forecast_days(fitted.forecaster, [household.train[i] for i in val_idx], la.horizons,
                                  la.first_reference, la.last_reference, la.cv_stride))
    return _pool(runs, la.horizons)


def choose_settings(household: Household, config: GlobeConfig, models: ModelConfig,
                    run_ends: Sequence[bool] | None = None) -> Selection:
    """The movement model's settings (run end of ``run_ends``, default ``lookahead.run_end``;
    run memory of ``lookahead.run_memory``, only with the run end) and a change threshold per
    horizon, by F1 on held-out *training* days. The setting with the best mean over horizons of
    each horizon's best F1 wins, then each horizon takes its best threshold; ties go to the first
    listed values (the simpler model, the higher threshold).
    ``best``: ``{"run_end": bool, "run_memory": bool, "thresholds": (one per horizon)}``."""
    la = config.lookahead
    settings = [(e, mem) for e in (la.run_end if run_ends is None else run_ends) for mem in la.run_memory if e or not mem]
    scores: list[tuple[dict, float]] = []
    best: dict | None = None
    best_score = -1.0
    for run_end, run_memory in settings:
        pooled = _cv_run(household, config, models, run_end, run_memory)
        per = [[p.counts(t).f1 for t in la.thresholds] for p in pooled.pairs]
        scores.extend(({"run_end": run_end, "run_memory": run_memory, "horizon": s, "threshold": t}, f)
                      for s, row in enumerate(per) for t, f in zip(la.thresholds, row))
        score = float(np.mean([max(row) for row in per]))
        if score > best_score:
            best_score = score
            best = {"run_end": run_end, "run_memory": run_memory,
                    "thresholds": tuple(la.thresholds[row.index(max(row))] for row in per)}
    return Selection(best or {"run_end": True, "run_memory": False, "thresholds": (0.5,) * la.horizons}, scores)


def choose_threshold(household: Household, config: GlobeConfig, models: ModelConfig, run_end: bool = True) -> Selection:
    """One change threshold for every horizon (best mean F1 over horizons on held-out training
    days, ties to the first listed), for a forecaster built with ``run_end`` (the default of
    :func:`globe.assembly.forecaster`). ``best``: ``{"threshold": t}``."""
    pooled = _cv_run(household, config, models, run_end)
    scores = [({"threshold": t}, float(np.mean(pooled.f1s(t)))) for t in config.lookahead.thresholds]
    return Selection(dict(max(scores, key=lambda ps: ps[1])[0]), scores)


def _pool(runs: Sequence[LookaheadRun], horizons: int) -> LookaheadRun:
    pooled = LookaheadRun(horizons, [HorizonPairs() for _ in range(horizons)], np.zeros(horizons, int), np.zeros(horizons, int))
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


def evaluate_lookahead(household: Household, config: GlobeConfig, models: ModelConfig, method: str) -> LookaheadResult:
    """Choose the settings on training days, fit on all of them, score the test days."""
    la = config.lookahead
    chosen = choose_settings(household, config, models)
    run_end, run_memory = bool(chosen.best["run_end"]), bool(chosen.best["run_memory"])
    fitted = assembly.forecaster(household, config, models=models, run_end=run_end, run_memory=run_memory)
    run = forecast_days(fitted.forecaster, household.test, la.horizons, la.first_reference, la.last_reference)
    ts = tuple(float(t) for t in chosen.best["thresholds"])
    return LookaheadResult(method, household.name, ts, tuple(p.counts(t) for p, t in zip(run.pairs, ts)),
                           tuple(run.activity_accuracy()), fitted.train_s, chosen, run_end, run_memory)


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
