"""Activity anticipation for any home, with or without objects: the activity 1..k steps ahead
(weighted F1, accuracy, log loss) and the next *different* activity (accuracy at each change
event, the event-based measure smart-home papers report), for an activity model beside three
baselines that need no model: persistence ("nothing changes"), the time-of-day mode (what
training days did most often at that step) and "hour + activity" (the most frequent activity h
ahead given the current activity and the clock hour, counted per horizon:
:class:`~globe.models.baselines.HourActivityBaseline`).

The model sees the activities up to the reference step r as GLOBE saw them
(:attr:`~globe.data.records.Day.seen`: the annotation, or the activities recognised from sensors)
and nothing after; the truth is always the annotation. Every r with r + k inside the day is
scored. Far ahead, what the person did at that hour on training days can say more than where
the model's paths lead, so the model is also scored mixed with the time of day,
``(1 - w) P_model + w P_time``, with ``w`` chosen per horizon by log loss on held-out
training days (:func:`blend_weights`; ``w = 0`` wins ties). A change event is a step r whose
activity differs from the one before; its truth is the first later activity that differs from
a_r (events with none left in the day are not scored).

A probability and a decision are chosen apart, per horizon, on held-out training days
(:func:`choose_per_horizon`): the distribution by log loss (the model mixed with the time of day,
or the direct hour + activity estimate), the point prediction by weighted F1 (the model's mode, or
one of the three baselines). That row, ``CV per horizon``, is what a home gets: never a model a
two-line rule beats on its own training days.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np

from globe import assembly
from globe.config import GlobeConfig, ModelConfig
from globe.data.records import Day, Household
from globe.evaluation import report
from globe.evaluation.metrics import LOG_LOSS_FLOOR, f1, log_loss
from globe.evaluation.parallel import precompute_selections, run_forked, worker_count
from globe.evaluation.selection import Fold, Memo, best_beyond_noise, best_of
from globe.evaluation.tuning import data_folds, fold_days, tuned_models
from globe.inference.horizon import activity_marginals, next_different
from globe.models.base import ActivityModelBase
from globe.models.baselines import HourActivityBaseline, TimeOfDayBaseline, mode
from globe.models.state_space import StateSpace, state_space

ANTICIPATION_COLUMNS = ("household", "method", "horizon_min", "references", "weighted_f1", "accuracy", "log_loss")
NEXT_COLUMNS = ("household", "method", "events", "accuracy")
PERSISTENCE, TIME_OF_DAY, HOUR_ACTIVITY, PER_HORIZON = "persistence", "time_of_day", "hour + activity", "CV per horizon"


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
    """The share of training days on which each activity was seen, at each step
    (:class:`~globe.models.baselines.TimeOfDayBaseline`, also a row of Table I)."""
    return TimeOfDayBaseline().fit(train).by_step_


def at_step(by_step: list[dict[str, float]], step: int) -> dict[str, float]:
    """The time-of-day distribution at ``step`` (empty past the training days' last step)."""
    return by_step[step] if step < len(by_step) else {}


def _top(dist: dict[str, float]) -> str:
    """The most probable label (ties: the first name), or '<none>' for an empty distribution."""
    return mode(dist) or "<none>"


@dataclass(frozen=True, slots=True)
class HorizonChoice:
    """What cross-validation chose at one horizon: the distribution (the model mixed with the time
    of day at ``weight``, or ``HOUR_ACTIVITY``) and the decision (``"model"``, the mode of that
    mix, or a baseline's)."""

    weight: float
    distribution: str = "model"
    decision: str = "model"


def score_anticipation(household: str, model: ActivityModelBase, train: Sequence[Day], test: Sequence[Day],
                       steps: int, step_minutes: int, method: str = "model",
                       blend: Sequence[float] | None = None,
                       choices: Sequence[HorizonChoice] | None = None,
                       next_choice: str | None = None) -> AnticipationScores:
    """Score ``model`` (fitted on ``train``) and the three baselines on ``test`` at 1..``steps``
    steps ahead and at the next different activity; with ``blend`` (a weight of the time of day
    per horizon), also the model mixed with it; with ``choices`` (:func:`choose_per_horizon`) and
    ``next_choice`` (:func:`choose_next`), the row of what cross-validation chose."""
    space = state_space(model)
    refs = [(day, r) for day in test for r in range(len(day) - steps)]
    roots = np.array([space.state(day.seen[: r + 1], day.weekday) for day, r in refs], dtype=np.int64)
    labels = space.labels
    marginals = activity_marginals(space, roots, steps)
    by_step = time_of_day(train)
    direct = HourActivityBaseline(steps).fit(train)
    methods: tuple[str, ...] = (method, PERSISTENCE, TIME_OF_DAY, HOUR_ACTIVITY)
    if blend is not None:
        methods += (f"{method} + time of day",)
    if choices is not None:
        methods += (PER_HORIZON,)
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
            dists = {method: mine, PERSISTENCE: {day.seen[r]: 1.0}, TIME_OF_DAY: tod,
                     HOUR_ACTIVITY: direct.proba(day.seen[r], day.minutes[r], j)}
            if blend is not None or choices is not None:
                w = blend[j - 1] if blend is not None else choices[j - 1].weight  # type: ignore[index]
                dists[f"{method} + time of day"] = mixed = _mix(mine, tod, w)
            if choices is not None:
                c = choices[j - 1]
                dists[PER_HORIZON] = dists[HOUR_ACTIVITY] if c.distribution == HOUR_ACTIVITY else mixed
                said = _top(mixed if c.decision == "model" else dists[c.decision])
            for m in methods:
                dist = dists[m]
                p_true[m].append(dist.get(truth, 0.0))
                pred[m].append(said if m == PER_HORIZON else _top(dist))
        for m in methods:
            horizons.append(HorizonScores(m, j, len(refs), f1(true, pred[m]) or 0.0,
                                          sum(a == b for a, b in zip(true, pred[m])) / max(len(true), 1),
                                          log_loss(p_true[m]) or 0.0))
    return AnticipationScores(household, step_minutes, tuple(horizons),
                              _next_activity(space, test, by_step, direct, method, next_choice))


def _mix(model: dict[str, float], tod: dict[str, float], w: float) -> dict[str, float]:
    """``(1 - w) P_model + w P_time``."""
    return {a: (1 - w) * model.get(a, 0.0) + w * tod.get(a, 0.0) for a in {*model, *tod}}


NEXT_CANDIDATES = ("model", TIME_OF_DAY, HOUR_ACTIVITY, PERSISTENCE)
"""The next-different-activity rules, in the order they win ties."""


def next_activity_hits(space: StateSpace, days: Sequence[Day], by_step: list[dict[str, float]],
                       direct: HourActivityBaseline) -> tuple[int, dict[str, int]]:
    """The change events of ``days`` and how many each rule of :data:`NEXT_CANDIDATES` got right:
    the model's next different activity, the first time-of-day mode after the event that differs,
    hour + activity's; persistence never expects a change (no hit). The events and their truth are
    the annotation's; each rule is told the activities as seen (:attr:`~globe.data.records.Day.seen`)."""
    events = []
    for day in days:
        acts = day.activities
        for r in range(1, len(acts)):
            if acts[r] != acts[r - 1]:
                later = next((a for a in acts[r + 1:] if a != acts[r]), None)
                if later is not None:
                    events.append((day, r, later))
    hits = dict.fromkeys(NEXT_CANDIDATES, 0)
    if not events:
        return 0, hits
    roots = np.array([space.state(day.seen[: r + 1], day.weekday) for day, r, _ in events], dtype=np.int64)
    current = np.array([space.code(day.seen[r]) for day, r, _ in events], dtype=np.int64)
    limits = np.array([len(day) - 1 - r for day, r, _ in events], dtype=np.int64)
    probs = next_different(space, roots, current, limits)
    labels = space.labels
    for q, (day, r, truth) in enumerate(events):
        row = probs[q]
        hits["model"] += _top({labels[i]: float(p) for i, p in enumerate(row.tolist()) if p > 0}) == truth
        here = day.seen[r]
        modes = (_top(by_step[t]) for t in range(r + 1, min(len(day), len(by_step))))
        hits[TIME_OF_DAY] += next((a for a in modes if a != here), None) == truth
        hits[HOUR_ACTIVITY] += _top(direct.next_proba(here, day.minutes[r])) == truth
    return len(events), hits


def _next_activity(space: StateSpace, test: Sequence[Day], by_step: list[dict[str, float]],
                   direct: HourActivityBaseline, method: str, choice: str | None) -> dict[str, tuple[int, float]]:
    """Accuracy of the next different activity at every change event of ``test``, per rule (and of
    the rule chosen on training days, ``choice``)."""
    events, hits = next_activity_hits(space, test, by_step, direct)
    out = {method if m == "model" else m: (events, h / events if events else 0.0) for m, h in hits.items()}
    out = {m: out[m] for m in (method, PERSISTENCE, TIME_OF_DAY, HOUR_ACTIVITY)}
    if choice is not None:
        out[PER_HORIZON] = out[method if choice == "model" else choice]
    return out


def choose_next(folds: Sequence["FoldScores"]) -> str:
    """The next-different-activity rule by accuracy per fold: the model's unless another beats it
    beyond noise (:func:`~globe.evaluation.selection.best_beyond_noise`)."""
    scored = [f for f in folds if f.next_events]
    return best_beyond_noise([(m, [f.next_hits[m] / f.next_events for f in scored]) for m in NEXT_CANDIDATES])


BLEND_WEIGHTS = (0.0, 0.1, 0.25, 0.5, 0.75, 0.9)
"""Weights of the time of day tried per horizon (the first wins ties: the model alone)."""


@dataclass(slots=True)
class FoldScores:
    """One fold's held-out training days, per horizon: the log loss (summed) of each mix of the
    model with the time of day (``losses``: horizons x :data:`BLEND_WEIGHTS`) and of the direct
    hour + activity estimate (``direct_loss``); the truth and each candidate decision's point
    predictions (``predicted``: ``"model"`` at each blend weight, keyed by its index, and the
    three baselines), for weighted F1."""

    losses: np.ndarray
    direct_loss: np.ndarray
    truth: list[list[str]] = field(default_factory=list)
    predicted: dict[str, list[list[str]]] = field(default_factory=dict)
    next_hits: dict[str, int] = field(default_factory=dict)  # per rule of NEXT_CANDIDATES
    next_events: int = 0


def fold_scores(household: Household, models: ModelConfig, step_minutes: int, steps: int, fold: Fold,
                stride: int = 1) -> FoldScores:
    """:class:`FoldScores` of one fold (every ``stride``-th reference step of its held-out days)."""
    out = FoldScores(np.zeros((steps, len(BLEND_WEIGHTS))), np.zeros(steps))
    weights = np.array(BLEND_WEIGHTS)
    train, held_out = fold_days(household, fold)
    refs = [(day, r) for day in held_out for r in range(0, len(day) - steps, stride)]
    if not refs:
        return out
    space = state_space(assembly.fitted_activity_model(models, step_minutes, train))
    roots = np.array([space.state(day.activities[: r + 1], day.weekday) for day, r in refs], dtype=np.int64)
    marginals = activity_marginals(space, roots, steps)
    totals = marginals.sum(axis=2, keepdims=True)
    marginals = np.divide(marginals, totals, out=np.zeros_like(marginals), where=totals > 0)
    names = sorted({*space.labels, *(a for d in train for a in d.activities)})  # argmax ties: the first name
    column = {a: i for i, a in enumerate(names)}
    order = [column[a] for a in space.labels]
    by_step = time_of_day(train)
    tod = np.zeros((max(len(d) for d, _ in refs) + 1, len(names)))  # per step (none past training's last)
    for t, dist in enumerate(by_step[: len(tod)]):
        tod[t, [column[a] for a in dist]] = list(dist.values())
    tod_top = [_top(dist) for dist in by_step]
    direct = HourActivityBaseline(steps).fit(train)
    decisions = {**{str(i): [] for i in range(len(BLEND_WEIGHTS))}, PERSISTENCE: [], TIME_OF_DAY: [],
                 HOUR_ACTIVITY: []}  # type: dict[str, list[list[str]]]
    at = np.array([r for _, r in refs])
    for j in range(1, steps + 1):
        p_model = np.zeros((len(refs), len(names)))
        p_model[:, order] = marginals[:, j - 1]
        p_time = tod[at + j]
        truth, hour_activity, p_direct = [], [], np.zeros(len(refs))
        for q, (day, r) in enumerate(refs):
            truth.append(day.activities[r + j])
            dist = direct.proba(day.activities[r], day.minutes[r], j)
            hour_activity.append(_top(dist))
            p_direct[q] = dist.get(truth[-1], 0.0)
        rows = np.arange(len(refs))
        true_col = np.array([column.get(a, -1) for a in truth])
        seen = true_col >= 0
        for i, w in enumerate(weights):
            mixed = (1 - w) * p_model + w * p_time
            p_true = np.where(seen, mixed[rows, np.maximum(true_col, 0)], 0.0)
            out.losses[j - 1, i] -= np.log(np.maximum(p_true, LOG_LOSS_FLOOR)).sum()
            best = mixed.argmax(axis=1)
            decisions[str(i)].append([names[b] if mixed[q, b] > 0 else "<none>" for q, b in enumerate(best)])
        out.direct_loss[j - 1] -= np.log(np.maximum(p_direct, LOG_LOSS_FLOOR)).sum()
        out.truth.append(truth)
        decisions[PERSISTENCE].append([day.activities[r] for day, r in refs])
        decisions[TIME_OF_DAY].append([tod_top[r + j] if r + j < len(tod_top) else "<none>" for _, r in refs])
        decisions[HOUR_ACTIVITY].append(hour_activity)
    out.predicted = decisions
    out.next_events, out.next_hits = next_activity_hits(space, held_out, by_step, direct)
    return out


def blend_weights(losses: Sequence[np.ndarray]) -> tuple[float, ...]:
    """Per horizon, the weight of the time of day (:data:`BLEND_WEIGHTS`) whose mix with the model
    has the lowest log loss summed over the folds (:attr:`FoldScores.losses`)."""
    total = np.sum(losses, axis=0)
    return tuple(float(best_of([(w, -total[j, i]) for i, w in enumerate(BLEND_WEIGHTS)])) for j in range(len(total)))


def choose_per_horizon(folds: Sequence[FoldScores]) -> list[HorizonChoice]:
    """Per horizon, over the folds pooled: the time-of-day weight of :func:`blend_weights`; the
    distribution with the lower log loss (that mix, or the direct hour + activity estimate; the
    model wins ties); the decision by weighted F1 per fold: the mix's mode unless a baseline
    (persistence, the time-of-day mode, hour + activity) beats it beyond noise
    (:func:`~globe.evaluation.selection.best_beyond_noise`)."""
    weights = blend_weights([f.losses for f in folds])
    losses, direct = np.sum([f.losses for f in folds], axis=0), np.sum([f.direct_loss for f in folds], axis=0)
    out = []
    for j, w in enumerate(weights):
        i = BLEND_WEIGHTS.index(w)
        distribution = best_of([("model", -losses[j, i]), (HOUR_ACTIVITY, -direct[j])])
        candidates = (("model", str(i)), (PERSISTENCE, PERSISTENCE), (TIME_OF_DAY, TIME_OF_DAY),
                      (HOUR_ACTIVITY, HOUR_ACTIVITY))
        scored = [f for f in folds if f.truth]
        decision = best_beyond_noise([(name, [f1(f.truth[j], f.predicted[key][j]) or 0.0 for f in scored])
                                      for name, key in candidates])
        out.append(HorizonChoice(w, distribution, decision))
    return out


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
    scored = run_forked(lambda t: fold_scores(*chosen[folds[t][0]], folds[t][1], config.lookahead.cv_stride),
                        len(folds), workers)

    def score(i: int) -> AnticipationScores:
        h, models, step, steps = chosen[i]
        model = assembly.fitted_activity_model(models, step, h.train)
        mine = [f for (owner, _), f in zip(folds, scored) if owner == i]
        choices = choose_per_horizon(mine)
        return score_anticipation(h.name, model, h.train, h.test, steps, step, f"chosen ({models.activity_estimator})",
                                  [c.weight for c in choices], choices, choose_next(mine))

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
