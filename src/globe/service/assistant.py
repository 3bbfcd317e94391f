"""The online assistant of one household: observe, predict, gate on confidence, learn.

No web imports here: the service, the simulated robot and tests drive it directly.

Observations arrive one at a time (a time, the current activity, and the locations of the
objects the robot sees; unseen objects keep their last known place). Each observation is one
step of the day. A day begins at ``day_start_minute``; when an observation belongs to a new day
the finished day is added to both models (``partial_fit``), so the result equals training on
all days at once. A gap longer than one step is filled by repeating the last observed step
(the person is assumed to have gone on doing the same thing), up to ``max_gap_steps``; a longer
gap ends the day early (what was seen is learned) and starts its history afresh.
"""

from __future__ import annotations

import datetime as dt
import threading
from collections import Counter, defaultdict
from dataclasses import dataclass
from typing import Mapping, Sequence

from globe.data.records import Day, Household
from globe.errors import DataError, UnknownLabelError
from globe.reasoning.choice import ObjectChooser, run_context
from globe.sequences.runs import activity_runs


@dataclass(frozen=True, slots=True)
class Observation:
    time: dt.datetime
    activity: str
    locations: Mapping[str, str]  # object -> location (may be partial)


@dataclass(frozen=True, slots=True)
class Prediction:
    day: str
    step: int
    activity: str | None
    activity_probability: float
    obj: str | None
    object_probability: float
    llm_consulted: bool
    llm_fallback: str | None
    act: bool
    fetch_to: str | None  # where the person is likely to need it (the object's usual target)


class OnlineAssistant:
    """State and models of one household (thread-safe: one lock serialises its requests)."""

    def __init__(self, household: Household, activity_model, chooser: ObjectChooser, *, alignment: str = "previous",
                 action_threshold: float = 0.5, day_start_minute: int = 360, step_minutes: int = 10,
                 max_gap_steps: int = 36) -> None:
        self.household = household
        self.activity_model = activity_model
        self.chooser = chooser
        self.alignment = alignment
        self.action_threshold = action_threshold
        self.day_start_minute = day_start_minute
        self.step_minutes = step_minutes
        self.max_gap_steps = max_gap_steps
        self.lock = threading.RLock()
        self._start_state = {n.cls: n.start_location for n in household.nodes if n.movable}
        self.days_learned = 0
        self.observations = 0
        self.feedback = {"accepted": 0, "refused": 0}
        self._target_counts: dict[tuple[str, str], Counter[str]] = defaultdict(Counter)
        self._count_targets(household.train)
        self._reset_day(None)

    # -- validation ------------------------------------------------------------------------
    def validate(self, obs: Observation) -> None:
        """Raise :class:`DataError` (naming the field) for an observation that must not be stored."""
        if not obs.activity or not obs.activity.strip():
            raise DataError("empty activity", field="activity")
        known = self.household.locations
        for obj, loc in obs.locations.items():
            if obj not in self._start_state:
                raise UnknownLabelError(f"unknown object {obj!r} (not a movable node of household {self.household.name})",
                                        field=f"locations.{obj}")
            if loc not in known:
                raise UnknownLabelError(f"unknown location {loc!r} for {obj!r}", field=f"locations.{obj}")
        if self._last_time is not None and obs.time <= self._last_time:
            raise DataError(f"time {obs.time.isoformat()} is not after the last observation {self._last_time.isoformat()}",
                            field="time")

    # -- the loop ---------------------------------------------------------------------------
    def day_key(self, time: dt.datetime) -> str:
        return (time - dt.timedelta(minutes=self.day_start_minute)).date().isoformat()

    def observe(self, obs: Observation) -> None:
        """Add one (already validated) observation; learns from the previous day on rollover."""
        key = self.day_key(obs.time)
        if self._day_key is not None and key != self._day_key:
            self._learn_current_day()
            self._reset_day(key)
        elif self._day_key is None:
            self._reset_day(key)
        midnight = dt.datetime.combine(dt.date.fromisoformat(key), dt.time(), tzinfo=obs.time.tzinfo)
        minute = int((obs.time - midnight).total_seconds() // 60)  # 00:00 of the next date is 1440
        if self._minutes:
            missing = round((minute - self._minutes[-1]) / self.step_minutes) - 1
            if missing > self.max_gap_steps:  # learn what was seen, then start afresh
                self._learn_current_day()
                self._reset_day(key)
            else:
                for _ in range(max(0, missing)):
                    self._append(self._minutes[-1] + self.step_minutes, self._activities[-1], self._states[-1])
        state = dict(self._states[-1]) if self._states else dict(self._start_state)
        state.update(obs.locations)
        self._append(minute, obs.activity, state)
        self._last_time = obs.time
        self.observations += 1

    def predict(self) -> Prediction:
        """Next activity, the object likely needed, and whether the robot should act."""
        history = tuple(self._activities)
        belief = self.activity_model.predict_proba(history)
        ranked = self.activity_model.ranked(belief)
        if not ranked:
            return Prediction(self._day_key or "", len(history), None, 0.0, None, 0.0, False, None, False, None)
        nxt = ranked[0]
        choice = self.chooser.choose_given(nxt, belief, run_context(*self._current_run()))
        act = choice.obj is not None and choice.confidence >= self.action_threshold
        return Prediction(self._day_key or "", len(history), nxt, belief[nxt], choice.obj, choice.confidence,
                          choice.asked, choice.fallback, act, self.fetch_target(nxt, choice.obj))

    def record_feedback(self, accepted: bool) -> None:
        self.feedback["accepted" if accepted else "refused"] += 1

    # -- internals ---------------------------------------------------------------------------
    def _reset_day(self, key: str | None) -> None:
        self._day_key = key
        self._minutes: list[int] = []
        self._activities: list[str] = []
        self._states: list[dict[str, str]] = []
        if key is None:
            self._last_time: dt.datetime | None = None

    def _append(self, minute: int, activity: str, state: Mapping[str, str]) -> None:
        self._minutes.append(minute)
        self._activities.append(activity)
        self._states.append(dict(state))

    def current_day(self) -> Day:
        objects = self.household.objects
        return Day(f"live/{self._day_key}", tuple(self._minutes), tuple(self._activities),
                   tuple(tuple(s[o] for o in objects) for s in self._states))

    def _current_run(self) -> tuple[str | None, tuple[str, ...]]:
        if not self._activities:
            return None, ()
        runs = activity_runs(self.current_day(), self.household.objects, self.alignment)  # type: ignore[arg-type]
        last = runs[-1]
        return last.activity, last.objects

    def _learn_current_day(self) -> None:
        if len(self._activities) < 2:
            return
        self.learn([self.current_day()])

    def learn(self, days: Sequence[Day]) -> None:
        """Add whole days to both models (the same counts as training on them from the start)."""
        self.activity_model.partial_fit([d.activities for d in days])
        runs = [(r.activity, r.objects) for d in days for r in activity_runs(d, self.household.objects, self.alignment)]  # type: ignore[arg-type]
        self.chooser.model.partial_fit(runs)
        self._count_targets(days)
        self.days_learned += len(days)

    def _count_targets(self, days: Sequence[Day]) -> None:
        for d in days:
            for r in activity_runs(d, self.household.objects, self.alignment):  # type: ignore[arg-type]
                for e in r.events:
                    self._target_counts[(r.activity, e.obj)][e.target] += 1

    def fetch_target(self, activity: str, obj: str | None) -> str | None:
        """Where ``obj`` is usually taken during ``activity``: where the robot should bring it."""
        counts = self._target_counts.get((activity, obj)) if obj else None
        return max(sorted(counts), key=counts.__getitem__) if counts else None

    def stats(self) -> dict:
        return {"household": self.household.name, "days_learned": self.days_learned, "observations": self.observations,
                "current_day": self._day_key, "steps_today": len(self._activities), "feedback": dict(self.feedback),
                "activities_known": len(getattr(self.activity_model, "classes_", ())),
                "training_days": len(self.activity_model.training_data_)}
