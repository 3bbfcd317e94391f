"""The evaluation protocol: test days -> per-prediction records (metrics come later, from these).

Activity: at every step t = 1..T-1 of each test day, predict a_t from a_0..a_{t-1} as seen
(:attr:`~globe.data.records.Day.seen`: the annotation, or the activities recognised from sensors
where the day carries them), scored against the annotation.
Object: at every movement event, predict the object from the *predicted* activity of the
event's activity step and the objects already moved in the current (true) activity run; that
context is reset when the predicted activity differs from the true one. Candidates are O(â).
``oracle=True`` conditions on the true activity instead. A predictor or chooser that reads the
clock (the hour + activity baselines) is told the day as seen (``scan_day``); every chooser is
told the clock minute of the event's activity step (the step its activity is predicted for, as
the household session tells it at that step), which an object model that reads the clock uses.
"""

from __future__ import annotations

import copy
import time
from dataclasses import dataclass, replace
from typing import Callable, Mapping, Protocol, Sequence, runtime_checkable

from globe.data.records import Day, Household
from globe.models.base import stay_or_change
from globe.reasoning.backends.base import LLMBackend, QuestionRecorder
from globe.reasoning.choice import ContextFor, ObjectChoice, ObjectChooser, Ranking, run_context
from globe.sequences.movements import Alignment
from globe.sequences.runs import activity_runs

NO_PREDICTION = "<none>"


class ActivityPredictor(Protocol):
    def scan_proba(self, day: Sequence[str], weekday: int | None = None) -> list[dict[str, float]]: ...
    def ranked(self, distribution: dict[str, float]) -> list[str]: ...
    def top(self, distribution: dict[str, float]) -> str | None: ...  # ranked(...)[0], None if empty


@runtime_checkable
class DayPredictor(Protocol):
    """A predictor that reads the clock (hour + activity): asked with the whole :class:`Day`."""

    def scan_day(self, day: Day) -> list[dict[str, float]]: ...
    def ranked(self, distribution: dict[str, float]) -> list[str]: ...
    def top(self, distribution: dict[str, float]) -> str | None: ...


@dataclass(frozen=True, slots=True, kw_only=True)
class ActivityRecord:
    household: str
    day: str
    step: int
    previous: str
    true: str
    predicted: str
    confidence: float
    p_true: float  # the probability the model gave the true activity (for log loss)

    @property
    def is_change(self) -> bool:
        """The activity changes at this step: the moments a robot must anticipate."""
        return self.true != self.previous

    def as_row(self) -> dict[str, object]:
        return {"household": self.household, "day": self.day, "step": self.step, "previous": self.previous,
                "true": self.true, "predicted": self.predicted, "confidence": self.confidence, "p_true": self.p_true}


@dataclass(frozen=True, slots=True, kw_only=True)
class ObjectRecord:
    """One movement event: what was true, and the chooser's whole :class:`ObjectChoice`."""

    household: str
    day: str
    step: int
    true_activity: str
    predicted_activity: str
    context: tuple[str, ...]
    true: str
    choice: ObjectChoice
    injected: bool = False
    p_true: float | None = None  # the object model's probability of the true object (log loss), when it ranked

    @property
    def predicted(self) -> str:
        return self.choice.obj or NO_PREDICTION

    @property
    def confidence(self) -> float:
        return self.choice.confidence

    @property
    def asked(self) -> bool:
        return self.choice.asked

    @property
    def latency_s(self) -> float:
        return self.choice.latency_s

    def as_row(self) -> dict[str, object]:
        c = self.choice
        return {"household": self.household, "day": self.day, "step": self.step, "true_activity": self.true_activity,
                "predicted_activity": self.predicted_activity, "context": "|".join(self.context), "true": self.true,
                "predicted": self.predicted, "confidence": c.confidence, "ngram_choice": c.ngram_choice,
                "asked": c.asked, "candidates": "|".join(c.candidates), "answer": c.answer, "latency_s": c.latency_s,
                "fallback": c.fallback, "injected": self.injected}


@dataclass(slots=True)
class Evaluation:
    activity: list[ActivityRecord]
    objects: list[ObjectRecord]
    inference_s: float
    prefetch_s: float = 0.0  # the LLM's batched scoring of every question asked (then read from the cache)


class FixedScan:
    """An activity predictor answering with distributions computed beforehand, per day (by name):
    what a household's session served at each step, or a filter's, scored by the same protocol
    as a model's own (the ranking and the point prediction stay ``model``'s)."""

    def __init__(self, model: ActivityPredictor | DayPredictor, dists: Mapping[str, Sequence[dict[str, float]]]):
        self.model, self.dists = model, dists

    def scan_day(self, day: Day) -> list[dict[str, float]]:
        """``dists[t]``: P(the activity at step t | what was seen before it) on ``day``."""
        dists = self.dists.get(day.name)
        if dists is None:
            raise ValueError(f"no distributions computed for day {day.name}")
        if len(dists) != len(day):
            raise ValueError(f"{len(dists)} distributions for day {day.name} of {len(day)} steps")
        return list(dists)

    def ranked(self, distribution: dict[str, float]) -> list[str]:
        return self.model.ranked(distribution)

    def top(self, distribution: dict[str, float]) -> str | None:
        return self.model.top(distribution)


def seen_day(day: Day) -> Day:
    """``day`` with its activities as seen (:attr:`~globe.data.records.Day.seen`): what a predictor
    that reads the whole day is shown (the day itself when nothing else was observed)."""
    return day if day.observed is None else replace(day, activities=day.observed, observed=None)


def _top(model: ActivityPredictor | DayPredictor, distribution: dict[str, float], current: str | None = None,
         stay_margin: float = 1.0) -> str:
    best = stay_or_change(model.top(distribution), distribution, current, stay_margin)
    return NO_PREDICTION if best is None else best


@dataclass(frozen=True, slots=True)
class _Query:
    """One movement event to predict: the true event, the predicted activity and its context."""

    day: str
    step: int
    true_activity: str
    true: str
    activity: str
    belief: dict[str, float]
    context_for: ContextFor
    injected: bool
    minute: int  # the clock minute of the event's activity step: what an object model that reads the clock is told


def evaluate_days(
    household: Household,
    days: Sequence[Day],
    activity_model: ActivityPredictor | DayPredictor,
    chooser: ObjectChooser,
    *,
    alignment: Alignment = "previous",
    oracle: bool = False,
    injected: Callable[[str, int, str], bool] | None = None,
    progress: Callable[[int], None] | None = None,
    rankings: dict | None = None,
    stay_margin: float = 1.0,
) -> Evaluation:
    """Run the protocol over ``days``; ``injected(day, step, obj)`` marks noise movements; the
    next activity said is the model's, kept at the current one by ``stay_margin``
    (:func:`~globe.models.base.stay_or_change`).

    The object questions do not depend on each other's answers, so when the chooser asks a
    cached LLM they are first collected and answered in the backend's preferred order
    (:meth:`~globe.reasoning.backends.base.LLMBackend.prefetch`), then read from the cache."""
    act_records: list[ActivityRecord] = []
    queries: list[_Query] = []
    started = time.perf_counter()
    for day in days:
        acts, seen = day.activities, day.seen
        dists = activity_model.scan_day(seen_day(day)) if isinstance(activity_model, DayPredictor) else \
            activity_model.scan_proba(seen, day.weekday)
        predicted = [_top(activity_model, d, seen[t - 1] if t else None, stay_margin) for t, d in enumerate(dists)]
        for t in range(1, len(acts)):
            act_records.append(ActivityRecord(household=household.name, day=day.name, step=t, previous=acts[t - 1],
                                              true=acts[t], predicted=predicted[t],
                                              confidence=dists[t].get(predicted[t], 0.0),
                                              p_true=dists[t].get(acts[t], 0.0)))
        for run in activity_runs(day, household.objects, alignment):
            for i, ev in enumerate(run.events):
                queries.append(_Query(
                    day.name, ev.step, run.activity, ev.obj,
                    run.activity if oracle else predicted[ev.activity_step],
                    {run.activity: 1.0} if oracle else dists[ev.activity_step],
                    run_context(run.activity, run.objects[:i]),
                    injected(day.name, ev.step, ev.obj) if injected else False, day.minutes[ev.activity_step]))
        if progress:
            progress(1)
    # The n-gram ranking of each event is computed once: the dry pass below and the real one
    # share it, and so do callers that pass ``rankings`` for several choosers over the same models.
    memo: dict = {} if rankings is None else rankings
    def ranking(q: _Query) -> Ranking | None:
        if not chooser.uses_ranking:
            return None
        key = (household.name, q.day, q.step, q.true, oracle)
        if key not in memo:
            memo[key] = chooser.ngram_ranking(q.activity, q.belief, q.context_for, q.minute)
        return memo[key]

    backend = getattr(chooser, "backend", None)
    prefetch_s = 0.0
    if isinstance(backend, LLMBackend) and backend.prefetches:
        recorder = QuestionRecorder(backend)
        dry = copy.copy(chooser)
        dry.backend = recorder  # type: ignore[attr-defined]
        for q in queries:
            dry.choose_given(q.activity, q.belief, q.context_for, ranking(q), q.minute)
        prefetch_started = time.perf_counter()
        backend.prefetch(recorder.questions)
        prefetch_s = time.perf_counter() - prefetch_started
    obj_records = []
    for q in queries:
        ranked = ranking(q)
        obj_records.append(ObjectRecord(household=household.name, day=q.day, step=q.step, true_activity=q.true_activity,
                                        predicted_activity=q.activity, context=q.context_for(q.activity), true=q.true,
                                        choice=chooser.choose_given(q.activity, q.belief, q.context_for, ranked,
                                                                    q.minute),
                                        injected=q.injected,
                                        p_true=None if ranked is None else ranked[1].get(q.true, 0.0)))
    return Evaluation(act_records, obj_records, time.perf_counter() - started, prefetch_s)
