"""Activity anticipation for any home, with or without objects: the activity 1..k steps ahead
(weighted F1, accuracy, log loss) and the next *different* activity (accuracy at each change
event, the event-based measure smart-home papers report), for an activity model beside two
baselines that need no model: persistence ("nothing changes") and the time-of-day mode (what
training days did most often at that step).

The model sees the true activities up to the reference step r and nothing after; every r with
r + k inside the day is scored. Far ahead, what the person did at that hour on training days can
say more than where the model's paths lead, so the model is also scored mixed with the time of
day, ``(1 - w) P_model + w P_time``, with ``w`` chosen per horizon by log loss on held-out
training days (:func:`blend_weights`; ``w = 0`` wins ties). A change event is a step r whose
activity differs from the one before; its truth is the first later activity that differs from
a_r (events with none left in the day are not scored).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from globe import assembly
from globe.config import GlobeConfig, ModelConfig
from globe.data.records import Day, Household
from globe.evaluation import report
from globe.evaluation.metrics import LOG_LOSS_FLOOR, f1, log_loss
from globe.evaluation.parallel import precompute_selections, run_forked, worker_count
from globe.evaluation.selection import Fold, Memo, best_of
from globe.evaluation.tuning import data_folds, fold_days, tuned_models
from globe.inference.horizon import activity_marginals, next_different
from globe.models.base import ActivityModelBase
from globe.models.state_space import StateSpace, state_space

ANTICIPATION_COLUMNS = ("household", "method", "horizon_min", "references", "weighted_f1", "accuracy", "log_loss")
NEXT_COLUMNS = ("household", "method", "events", "accuracy")


@dataclass(frozen=True, slots=True)
class HorizonScores:
    """Scores of one method at one horizon (``steps`` ahead of the reference)."""

    method: str
    steps: int
    references: int
    weighted_f1: float
    accuracy: float
    log_loss: float


@dataclass(frozen=True, slots=True)
class AnticipationScores:
    household: str
    step_minutes: int
    horizons: tuple[HorizonScores, ...]
    next_activity: dict[str, tuple[int, float]]  # method -> (events, accuracy)

    def rows(self) -> list[dict]:
        """``activity_anticipation.csv`` rows (one per method and horizon)."""
        return [{"household": self.household, "method": s.method, "horizon_min": s.steps * self.step_minutes,
                 "references": s.references, "weighted_f1": round(s.weighted_f1, 4), "accuracy": round(s.accuracy, 4),
                 "log_loss": round(s.log_loss, 4)} for s in self.horizons]

    def next_rows(self) -> list[dict]:
        """``next_activity.csv`` rows (one per method)."""
        return [{"household": self.household, "method": m, "events": n, "accuracy": round(a, 4)}
                for m, (n, a) in self.next_activity.items()]


def time_of_day(train: Sequence[Day]) -> list[dict[str, float]]:
    """The share of training days on which each activity was seen, at each step."""
    counts: list[Counter[str]] = []
    for day in train:
        for t, a in enumerate(day.activities):
            if t == len(counts):
                counts.append(Counter())
            counts[t][a] += 1
    return [{a: c / sum(seen.values()) for a, c in seen.items()} for seen in counts]


def at_step(by_step: list[dict[str, float]], step: int) -> dict[str, float]:
    """The time-of-day distribution at ``step`` (empty past the training days' last step)."""
    return by_step[step] if step < len(by_step) else {}


def _top(dist: dict[str, float]) -> str:
    """The most probable label (ties: the first name), or '<none>' for an empty distribution."""
    best = max(dist.values(), default=0.0)
    return min((a for a, p in dist.items() if p == best), default="<none>") if best > 0 else "<none>"


def score_anticipation(household: str, model: ActivityModelBase, train: Sequence[Day], test: Sequence[Day],
                       steps: int, step_minutes: int, method: str = "model",
                       blend: Sequence[float] | None = None) -> AnticipationScores:
    """Score ``model`` (fitted on ``train``), persistence and the time-of-day mode on ``test``
    at 1..``steps`` steps ahead and at the next different activity; with ``blend`` (a weight of
    the time of day per horizon), also the model mixed with it."""
    space = state_space(model)
    refs = [(day, r) for day in test for r in range(len(day) - steps)]
    roots = np.array([space.state(day.activities[: r + 1], day.weekday) for day, r in refs], dtype=np.int64)
    labels = space.labels
    marginals = activity_marginals(space, roots, steps)
    by_step = time_of_day(train)
    methods: tuple[str, ...] = (method, "persistence", "time_of_day")
    if blend is not None:
        methods += (f"{method} + time of day",)
    horizons = []
    for j in range(1, steps + 1):
        true, pred = [], {m: [] for m in methods}  # type: ignore[var-annotated]
        p_true: dict[str, list[float]] = {m: [] for m in methods}
        for q, (day, r) in enumerate(refs):
            truth = day.activities[r + j]
            true.append(truth)
            row = marginals[q, j - 1]
            total = row.sum()
            mine = {labels[i]: float(p / total) for i, p in enumerate(row.tolist()) if p > 0} if total > 0 else {}
            tod = at_step(by_step, r + j)
            dists = [mine, {day.activities[r]: 1.0}, tod]
            if blend is not None:
                w = blend[j - 1]
                dists.append({a: (1 - w) * mine.get(a, 0.0) + w * tod.get(a, 0.0) for a in {*mine, *tod}})
            for m, dist in zip(methods, dists):
                pred[m].append(_top(dist))
                p_true[m].append(dist.get(truth, 0.0))
        for m in methods:
            horizons.append(HorizonScores(m, j, len(refs), f1(true, pred[m]) or 0.0,
                                          sum(a == b for a, b in zip(true, pred[m])) / max(len(true), 1),
                                          log_loss(p_true[m]) or 0.0))
    return AnticipationScores(household, step_minutes, tuple(horizons),
                              _next_activity(space, test, by_step, method))


def _next_activity(space: StateSpace, test: Sequence[Day], by_step: list[dict[str, float]],
                   method: str) -> dict[str, tuple[int, float]]:
    """Accuracy of the next different activity at every change event of ``test``."""
    events = []
    for day in test:
        acts = day.activities
        for r in range(1, len(acts)):
            if acts[r] != acts[r - 1]:
                later = next((a for a in acts[r + 1:] if a != acts[r]), None)
                if later is not None:
                    events.append((day, r, later))
    if not events:
        return {m: (0, 0.0) for m in (method, "persistence", "time_of_day")}
    roots = np.array([space.state(day.activities[: r + 1], day.weekday) for day, r, _ in events], dtype=np.int64)
    current = np.array([space.code(day.activities[r]) for day, r, _ in events], dtype=np.int64)
    limits = np.array([len(day) - 1 - r for day, r, _ in events], dtype=np.int64)
    probs = next_different(space, roots, current, limits)
    labels = space.labels
    hits = {method: 0, "persistence": 0, "time_of_day": 0}
    for q, (day, r, truth) in enumerate(events):
        row = probs[q]
        mine = {labels[i]: float(p) for i, p in enumerate(row.tolist()) if p > 0}
        hits[method] += _top(mine) == truth
        here = day.activities[r]
        modes = (_top(by_step[t]) for t in range(r + 1, min(len(day), len(by_step))))
        hits["time_of_day"] += next((a for a in modes if a != here), None) == truth
        # persistence never expects a change: it has no next different activity (a miss)
    return {m: (len(events), h / len(events)) for m, h in hits.items()}


BLEND_WEIGHTS = (0.0, 0.1, 0.25, 0.5, 0.75, 0.9)
"""Weights of the time of day tried per horizon (the first wins ties: the model alone)."""


def fold_losses(household: Household, models: ModelConfig, step_minutes: int, steps: int, fold: Fold,
                stride: int = 1) -> np.ndarray:
    """(horizons x :data:`BLEND_WEIGHTS`): the log loss on one fold's held-out training days of
    each mix of the model with the time of day (every ``stride``-th reference step)."""
    losses = np.zeros((steps, len(BLEND_WEIGHTS)))
    weights = np.array(BLEND_WEIGHTS)
    train, held_out = fold_days(household, fold)
    refs = [(day, r) for day in held_out for r in range(0, len(day) - steps, stride)]
    if not refs:
        return losses
    space = state_space(assembly.fitted_activity_model(models, step_minutes, train))
    roots = np.array([space.state(day.activities[: r + 1], day.weekday) for day, r in refs], dtype=np.int64)
    marginals = activity_marginals(space, roots, steps)
    totals = marginals.sum(axis=2)
    index = {a: i for i, a in enumerate(space.labels)}
    by_step = time_of_day(train)
    for j in range(1, steps + 1):
        p_model, p_time = np.zeros(len(refs)), np.zeros(len(refs))
        for q, (day, r) in enumerate(refs):
            truth, total = day.activities[r + j], totals[q, j - 1]
            if truth in index and total > 0:
                p_model[q] = marginals[q, j - 1, index[truth]] / total
            p_time[q] = at_step(by_step, r + j).get(truth, 0.0)
        mixed = np.outer(p_model, 1 - weights) + np.outer(p_time, weights)
        losses[j - 1] -= np.log(np.maximum(mixed, LOG_LOSS_FLOOR)).sum(axis=0)
    return losses


def blend_weights(losses: Sequence[np.ndarray]) -> tuple[float, ...]:
    """Per horizon, the weight of the time of day (:data:`BLEND_WEIGHTS`) whose mix with the model
    has the lowest log loss summed over the folds (:func:`fold_losses`)."""
    total = np.sum(losses, axis=0)
    return tuple(float(best_of([(w, -total[j, i]) for i, w in enumerate(BLEND_WEIGHTS)])) for j in range(len(total)))


def run_activity_anticipation(config: GlobeConfig, households: Sequence[Household],
                              memo: Memo) -> list[AnticipationScores]:
    """Every household's test days, with the routine family's model chosen by cross-validation
    on its training days (``memo``: the main job's searches). The folds of the time-of-day
    weights, then the households, run on several processes."""
    tested = [h for h in households if h.test]
    workers = worker_count(config.evaluation.workers)
    precompute_selections(config, tested, ["routine"], memo)  # the searches not run yet, in parallel
    chosen = []
    for h in tested:
        models, _ = tuned_models(h, config, "routine", memo)
        chosen.append((h, models, assembly.step_minutes(h, config), assembly.lookahead_steps(config, h)))
    folds = [(i, fold) for i, (h, *_) in enumerate(chosen) for fold in data_folds(h, config.selection.folds)]
    losses = run_forked(lambda t: fold_losses(*chosen[folds[t][0]], folds[t][1], config.lookahead.cv_stride),
                        len(folds), workers)

    def score(i: int) -> AnticipationScores:
        h, models, step, steps = chosen[i]
        model = assembly.fitted_activity_model(models, step, h.train)
        blend = blend_weights([loss for (owner, _), loss in zip(folds, losses) if owner == i])
        return score_anticipation(h.name, model, h.train, h.test, steps, step, f"chosen ({models.activity_estimator})",
                                  blend)

    return run_forked(score, len(chosen), workers, [len(h.test) for h, *_ in chosen])


def write_activity_anticipation(out_dir: Path, scores: Sequence[AnticipationScores], title: str) -> list[Path]:
    """``activity_anticipation.csv`` and ``.png``, ``next_activity.csv``; returns the paths."""
    from globe.evaluation.plots_anticipation import activity_horizon_figure, save_figure

    out_dir.mkdir(parents=True, exist_ok=True)
    rows = [r for s in scores for r in s.rows()]
    paths = [out_dir / name for name in ("activity_anticipation.csv", "next_activity.csv", "activity_anticipation.png")]
    report.write_csv(paths[0], rows, list(ANTICIPATION_COLUMNS))
    report.write_csv(paths[1], [r for s in scores for r in s.next_rows()], list(NEXT_COLUMNS))
    save_figure(activity_horizon_figure(rows, title), paths[2])
    return paths
