"""The online assistant of one household: observe, predict, gate on confidence, learn.

No web imports here: the service, the simulated robot and tests drive it directly.

Observations arrive one at a time: an aware time in the household's zone, the current activity
(or None when the robot could not tell), and the locations of the objects the robot sees (unseen
objects keep their last known place). The day is cut into steps of ``step_minutes`` from
``day_start_minute`` (wall-clock time): several observations inside one step update that step;
a gap of a few steps is filled by repeating the last step (the person is assumed to have gone
on doing the same thing), up to ``max_gap_steps``; a longer gap ends the day early (what was
seen is learned) and starts its history afresh. When an observation belongs to a new day the
finished day is added to both models (``partial_fit``), so the result equals training on all
days at once.

A household may start with no training day at all (cold start): until it has learned a first
day its predictions say ``status = "learning"`` and never ask the robot to act.
"""

from __future__ import annotations

import datetime as dt
import sys
import threading
from collections import Counter, defaultdict
from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

from globe import assembly
from globe.config import GlobeConfig
from globe.data.records import Day, Household
from globe.errors import DataError, UnknownLabelError
from globe.inference.activity_filter import ActivityFilter, as_dicts
from globe.inference.emission import MovementEmission
from globe.inference.fetch_policy import FetchPolicy
from globe.reasoning.backends.base import LLMBackend
from globe.reasoning.choice import ObjectChoice, ObjectChooser, run_context
from globe.sequences.runs import ActivityRun, activity_runs
from globe.service.schemas import Prediction

UTC = dt.timezone.utc


@dataclass(frozen=True, slots=True)
class Observation:
    time: dt.datetime  # aware, in the household's zone (naive = wall time, for library use)
    activity: str | None  # None: unknown at this step
    locations: Mapping[str, str]  # object -> location (may be partial)


@dataclass(frozen=True, slots=True)
class Placement:
    """Where an observation lands: its day, its step, and whether it opens a new step."""

    day: str
    step: int
    new_step: bool


def fill_unknown(labels: Sequence[str | None]) -> list[str] | None:
    """Carry the last known activity forward over unknown steps (leading unknowns take the first
    known label); None if no step is known. A stand-in for a proper filter over missing labels."""
    first = next((a for a in labels if a is not None), None)
    if first is None:
        return None
    out: list[str] = []
    last = first
    for a in labels:
        last = a if a is not None else last
        out.append(last)
    return out


class OnlineAssistant:
    """State and models of one household (thread-safe: one lock serialises its requests)."""

    def __init__(self, household: Household, activity_model, chooser: ObjectChooser, *, alignment: str = "previous",
                 action_threshold: float = 0.5, day_start_minute: int = 360, step_minutes: int = 10,
                 max_gap_steps: int = 36, fetch_policy: FetchPolicy | None = None,
                 activity_filter: Callable[[], ActivityFilter] | None = None,
                 emission: MovementEmission | None = None) -> None:
        self.activity_model = activity_model
        self.chooser = chooser
        self.fetch_policy = fetch_policy  # None: fetch when the object probability reaches action_threshold
        self._new_filter = activity_filter  # builds a filter over the current models (None: carry labels forward)
        self.emission = emission  # the filter's movement evidence, learned with the models
        self.alignment = alignment
        self.action_threshold = action_threshold
        self.day_start_minute = day_start_minute
        self.step_minutes = step_minutes
        self.max_gap_steps = max_gap_steps
        self.lock = threading.RLock()
        self._locations = {label: label for label in household.locations}  # interned labels
        self._object_index = {o: i for i, o in enumerate(household.objects)}
        starts: dict[str, list[str]] = {}  # each object's movable nodes' start locations, in map order
        for n in household.nodes:
            if n.movable:
                starts.setdefault(n.cls, []).append(self._locations[n.start_location])
        self._start = tuple(loc for o in household.objects for loc in starts.get(o, ()))
        self.observations = 0
        self._prediction: tuple[tuple, Prediction] | None = None  # the decision of the current state
        self.feedback = {"accepted": 0, "refused": 0}
        self.fallbacks: Counter[str] = Counter()
        self.quarantined = 0
        self.pending = 0  # observations stored but held until the clock reaches them (set by the registry)
        self.training_days_set_aside = 0  # stored training days that could not be read back (set by the registry)
        self._target_counts: dict[tuple[str, str], Counter[str]] = defaultdict(Counter)
        # the training days are counted, then dropped: keep the map only (memory per household stays small)
        self.household = Household(household.name, household.nodes, household.objects, (), (), household.source)
        if fetch_policy is None:  # only the threshold rule reads where objects are taken (the policy forecasts it)
            self._count_targets(self._runs(household.train))
        self.days_learned = len(household.train)
        self._last_instant: dt.datetime | None = None
        self._belief: tuple[tuple, dict[str, float]] | None = None  # (state key, belief): predict and observe share it
        self._reset_day(None)

    # -- validation ------------------------------------------------------------------------
    def validate(self, obs: Observation) -> None:
        """Raise :class:`DataError` (naming the field) for an observation that must not be stored."""
        self.validate_labels(obs)
        self.validate_time(obs)

    def validate_time(self, obs: Observation) -> None:
        """The check of :meth:`validate` that depends on the observations before: times increase."""
        instant = _instant(obs.time)
        if self._last_instant is not None and instant <= self._last_instant:
            raise DataError(f"time {obs.time.isoformat()} is not after the last observation "
                            f"{self._last_instant.isoformat()}", field="time")

    def validate_labels(self, obs: Observation) -> None:
        """The checks of :meth:`validate` that do not depend on the observations before it."""
        if obs.activity is not None and not obs.activity.strip():
            raise DataError("empty activity (send null when it is unknown)", field="activity")
        for obj, loc in obs.locations.items():
            if obj not in self._object_index:
                raise UnknownLabelError(f"unknown object {obj[:64]!r} (not a movable node of household "
                                        f"{self.household.name})", field=f"locations.{obj[:64]}")
            if loc not in self._locations:
                raise UnknownLabelError(f"unknown location {loc[:64]!r} for {obj!r}", field=f"locations.{obj}")

    @property
    def last_instant(self) -> dt.datetime | None:
        """The UTC instant of the last observation applied (None before any)."""
        return self._last_instant

    # -- the loop ---------------------------------------------------------------------------
    def _wall(self, time: dt.datetime) -> tuple[str, int]:
        """Day key and minute since that date's midnight (00:00 of the next date is 1440)."""
        wall = time.replace(tzinfo=None)
        key = (wall - dt.timedelta(minutes=self.day_start_minute)).date()
        minute = int((wall - dt.datetime.combine(key, dt.time())).total_seconds() // 60)
        return key.isoformat(), minute

    def day_key(self, time: dt.datetime) -> str:
        return self._wall(time)[0]

    def _slot(self, minute: int) -> int:
        return (minute - self.day_start_minute) // self.step_minutes

    def placement(self, time: dt.datetime) -> Placement:
        """Where an observation at ``time`` would land (no state changes)."""
        key, minute = self._wall(time)
        slot = self._slot(minute)
        if key == self._day_key and self._slots:
            if slot <= self._slots[-1]:
                return Placement(key, len(self._slots) - 1, False)
            missing = slot - self._slots[-1] - 1
            if missing <= self.max_gap_steps:
                return Placement(key, len(self._slots) + missing, True)
        return Placement(key, 0, True)

    def observe(self, obs: Observation) -> Placement:
        """Add one (already validated) observation; learns from the previous day on rollover."""
        key, minute = self._wall(obs.time)
        slot = self._slot(minute)
        if self._day_key is not None and key != self._day_key:
            self._learn_current_day()
            self._reset_day(key)
        elif self._day_key is None:
            self._reset_day(key)
        activity = sys.intern(obs.activity.strip()) if obs.activity is not None else None
        if self._slots and slot <= self._slots[-1]:  # inside the current step (or a DST repeat): update it
            state = list(self._states[-1])
            self._set(state, obs.locations)
            self._states[-1] = tuple(state)
            if activity is not None:
                self._activities[-1] = activity
        else:
            if self._slots:
                missing = slot - self._slots[-1] - 1
                if missing > self.max_gap_steps:  # learn what was seen, then start afresh
                    self._learn_current_day()
                    self._reset_day(key)
                else:
                    for _ in range(missing):
                        self._append(self._slots[-1] + 1, self._activities[-1], self._states[-1])
            state = list(self._states[-1]) if self._states else list(self._start)
            self._set(state, obs.locations)
            self._append(slot, activity, tuple(state))
        self._last_instant = _instant(obs.time)
        self.observations += 1
        return Placement(key, len(self._slots) - 1, True)

    def _set(self, state: list[str], locations: Mapping[str, str]) -> None:
        for obj, loc in locations.items():
            state[self._object_index[obj]] = self._locations[loc]

    # -- the two decisions: what comes next when labels are missing, and what to fetch ----
    def activity_history(self) -> list[str]:
        """The day's activities with unknown steps carrying the last known label forward (see
        :func:`fill_unknown`): what is learned at the end of the day, and the run context."""
        return fill_unknown(self._activities) or []

    def activity_belief(self) -> dict[str, float]:
        """The next-activity distribution given the day so far. With every label known, the
        activity model's own; otherwise a forward filter over the activities the unknown steps
        may have had, given the time and the objects seen moving (never a guess taken as truth)."""
        key = self._state()
        if self._belief is not None and self._belief[0] == key:
            return self._belief[1]
        belief = self._compute_belief()
        self._belief = (key, belief)
        return belief

    def _compute_belief(self) -> dict[str, float]:
        if self._new_filter is None or all(a is not None for a in self._activities):
            return self.activity_model.predict_proba(tuple(self.activity_history()), self.weekday)
        flt = self._new_filter()
        belief = flt.start(weekdays=[self.weekday])
        previous: tuple[str, ...] | None = None
        objects = self.household.objects
        for step, (label, state) in enumerate(zip(self._activities, self._states)):
            moved = None if previous is None else frozenset(o for o, x, y in zip(objects, previous, state) if x != y)
            belief = flt.update(belief, step, [label], [moved])
            previous = state
        return as_dicts(flt.predictive(belief), flt.labels)[0]

    def fetch_decision(self, choice: ObjectChoice, activity: str) -> tuple[str | None, str | None, float | None]:
        """What to fetch now: (object, where to, P(used within the lead window)), or Nones.

        With a fetch policy: the object whose expected value of fetching is highest and positive
        (costs of a useless fetch and of a missed need, minimum lead time). Without one: the
        chosen object when its probability reaches the action threshold."""
        if self.fetch_policy is None:
            if choice.obj is not None and choice.confidence >= self.action_threshold:
                return choice.obj, self.fetch_target(activity, choice.obj), None
            return None, None, None
        history = self.activity_history()
        if not self._states or len(history) != len(self._states):  # nothing seen today, or no label yet: no basis
            return None, None, None
        now = len(self._slots) - 1
        recent = {o for o, at in self._fetched.items() if now - at < self.fetch_policy.window_steps}
        fetches = self.fetch_policy.decide(history, self._states, exclude=recent, weekday=self.weekday)
        if not fetches:
            return None, None, None
        best = fetches[0]
        self._fetched[best.obj] = now
        return best.obj, best.to_location, best.probability

    # -- what the dashboard and the online scores read ---------------------------------------
    @property
    def day(self) -> str | None:
        """The day the last observation belongs to (None before any)."""
        return self._day_key

    @property
    def weekday(self) -> int | None:
        """Today's day of the week (Monday 0; None before any observation): the models that know
        it predict from it."""
        return None if self._day_key is None else dt.date.fromisoformat(self._day_key).weekday()

    @property
    def steps_today(self) -> int:
        return len(self._slots)

    def next_activity(self) -> tuple[str, float] | None:
        """The top next activity and its probability (what :meth:`predict` says), or None while
        learning; computed once per state (:meth:`predict` reuses it)."""
        if self.days_learned == 0:
            return None
        belief = self.activity_belief()
        ranked = self.activity_model.ranked(belief)
        return (ranked[0], float(belief[ranked[0]])) if ranked else None

    def observed_activity(self, step: int) -> str | None:
        """Today's activity at ``step`` as observed (None: unknown)."""
        return self._activities[step] if 0 <= step < len(self._activities) else None

    def step_minute(self, step: int) -> int:
        """Minute since the day's midnight of today's ``step``."""
        return self.day_start_minute + self._slots[step] * self.step_minutes

    def today(self) -> list[tuple[int, str | None]]:
        """(minute since midnight, observed activity or None) of each step today."""
        return [(self.day_start_minute + slot * self.step_minutes, a) for slot, a in zip(self._slots, self._activities)]

    def lead_window(self, policy_minutes: tuple[int, int]) -> tuple[int, int]:
        """(min lead, window) in steps: the fetch policy's, else ``policy_minutes`` converted as it would be."""
        if self.fetch_policy is not None:
            return self.fetch_policy.min_lead_steps, self.fetch_policy.window_steps
        lead, window = policy_minutes
        return max(1, -(-lead // self.step_minutes)), max(1, window // self.step_minutes)

    def next_hour(self, steps: int) -> list[tuple[str, list[float], str | None]]:
        """Per object, P(first used at each of the next ``steps`` steps) and where it would most
        likely be taken, from the fetch policy's forecaster; [] without a policy or a basis."""
        history = self.activity_history()
        if self.fetch_policy is None or not self._states or len(history) != len(self._states) or self.days_learned == 0:
            return []
        forecast = self.fetch_policy.forecaster.forecast(history, self._states, max(0, steps - 1), self.weekday)
        targets = forecast.likely_target(1, steps)
        return [(obj, [float(x) for x in forecast.departure[:steps, j]], targets[j])
                for j, obj in enumerate(forecast.objects)]

    # -- prediction ------------------------------------------------------------------------
    @property
    def status(self) -> str:
        return "ready" if self.days_learned > 0 else "learning"

    def _state(self) -> tuple:
        """What the predictions depend on: the day, its steps, the observations and the days learned."""
        return (self._day_key, len(self._slots), self.observations, self.days_learned)

    @property
    def last_prediction(self) -> Prediction | None:
        """The prediction already decided for the current state of the day, if any."""
        return self._prediction[1] if self._prediction is not None and self._prediction[0] == self._state() else None

    def predict(self) -> Prediction:
        """Next activity, the object likely needed, and whether the robot should act: decided once
        per state of the day, so every caller (the robot polling, Home Assistant's publisher) gets
        the same answer and a fetch is decided once, until the next observation."""
        decided = self.last_prediction
        if decided is not None:
            return decided
        prediction = self._decide()
        self._prediction = (self._state(), prediction)
        return prediction

    def _decide(self) -> Prediction:
        step = len(self._slots)
        day = self._day_key or ""
        nothing = Prediction(status=self.status, days_learned=self.days_learned, day=day, step=step, activity=None,
                             activity_probability=0.0, object=None, object_probability=0.0, llm_consulted=False,
                             llm_fallback=None, act=False)
        if self.days_learned == 0:
            return nothing
        top = self.next_activity()
        if top is None:
            return nothing
        nxt = top[0]
        belief = self.activity_belief()
        choice = self.chooser.choose_given(nxt, belief, run_context(*self._current_run()))
        if choice.fallback:
            self.fallbacks[choice.fallback] += 1
        fetch, to, p_useful = self.fetch_decision(choice, nxt)
        return nothing.model_copy(update={
            "activity": nxt, "activity_probability": belief[nxt], "object": choice.obj,
            "object_probability": choice.confidence, "llm_consulted": choice.asked, "llm_fallback": choice.fallback,
            "act": fetch is not None, "fetch_object": fetch, "fetch_to": to, "fetch_probability": p_useful})

    def record_feedback(self, accepted: bool) -> None:
        self.feedback["accepted" if accepted else "refused"] += 1

    # -- internals ---------------------------------------------------------------------------
    def _reset_day(self, key: str | None) -> None:
        self._day_key = key
        self.step_predictions: dict[int, tuple[str, float]] = {}  # today's one-step predictions (by the registry)
        self.fetches_today: dict[int, list[str]] = {}  # step -> objects GLOBE decided to fetch after it
        self._fetched: dict[str, int] = {}  # object -> step it was last fetched (not again within the window)
        self._slots: list[int] = []
        self._activities: list[str | None] = []
        self._states: list[tuple[str, ...]] = []

    def _append(self, slot: int, activity: str | None, state: tuple[str, ...]) -> None:
        self._slots.append(slot)
        self._activities.append(activity)
        self._states.append(state)

    def current_day(self) -> Day:
        """The day so far (unknown activities filled as :meth:`activity_history` does)."""
        minutes = tuple(self.day_start_minute + s * self.step_minutes for s in self._slots)
        return Day(f"live/{self._day_key}", minutes, tuple(self.activity_history()), tuple(self._states))

    def _current_run(self) -> tuple[str | None, tuple[str, ...]]:
        if all(a is None for a in self._activities):  # nothing observed today, or no label yet: no run
            return None, ()
        runs = activity_runs(self.current_day(), self.household.objects, self.alignment)  # type: ignore[arg-type]
        last = runs[-1]
        return last.activity, last.objects

    def _learn_current_day(self) -> None:
        if len(self._activities) < 2 or fill_unknown(self._activities) is None:
            return
        self.learn([self.current_day()])

    def learn(self, days: Sequence[Day]) -> None:
        """Add whole days to both models (the same counts as training on them from the start)."""
        self.activity_model.partial_fit([d.activities for d in days], [d.weekday for d in days])
        runs = self._runs(days)
        self.chooser.model.partial_fit([(r.activity, r.objects) for r in runs])  # type: ignore[attr-defined]
        if self.emission is not None:
            self.emission.partial_fit(days, self.household.objects)
        if self.fetch_policy is not None:
            self.fetch_policy.learn(days)
        if self.fetch_policy is None:
            self._count_targets(runs)
        self.days_learned += len(days)

    def _runs(self, days: Sequence[Day]) -> list[ActivityRun]:
        return [r for d in days for r in activity_runs(d, self.household.objects, self.alignment)]  # type: ignore[arg-type]

    def _count_targets(self, runs: Sequence[ActivityRun]) -> None:
        for r in runs:
            for e in r.events:
                self._target_counts[(r.activity, e.obj)][e.target] += 1

    def fetch_target(self, activity: str, obj: str | None) -> str | None:
        """Where ``obj`` is usually taken during ``activity``: where the robot should bring it."""
        counts = self._target_counts.get((activity, obj)) if obj else None
        return max(sorted(counts), key=counts.__getitem__) if counts else None

    def stats(self) -> dict:
        return {"household": self.household.name, "status": self.status, "days_learned": self.days_learned,
                "observations": self.observations, "current_day": self._day_key, "steps_today": len(self._slots),
                "feedback": dict(self.feedback), "activities_known": len(getattr(self.activity_model, "classes_", ())),
                "training_days": len(self.activity_model.training_data_), "quarantined": self.quarantined,
                "training_days_set_aside": self.training_days_set_aside, "pending": self.pending,
                "llm_fallbacks": dict(self.fallbacks)}


def _instant(time: dt.datetime) -> dt.datetime:
    """The UTC instant of ``time`` (naive = UTC, for library callers without a zone)."""
    return time.astimezone(UTC) if time.tzinfo else time.replace(tzinfo=UTC)


def build_assistant(household: Household, config: GlobeConfig, backend: LLMBackend | None) -> OnlineAssistant:
    """The online assistant of one household: its models, gate, filter and fetch policy, each
    built by :mod:`globe.assembly` from ``config``, and the service's settings."""
    fitted = assembly.fit_household(household, config)
    activity = fitted.activity  # the filter's closure keeps this, not the counted sequences
    chooser = assembly.object_chooser(fitted.objects, config.gate, backend, marginal=config.models.object_marginal)
    s, fc = config.service, config.filter
    # The filter's movement evidence is learned with the models; the filter itself is rebuilt per
    # prediction over the current models (cheap), so it never reads stale counts.
    emission = assembly.household_emission(fc).fit(household.train, household.objects, fitted.sequences.moves)
    policy = None
    if s.fetch_decision == "policy":
        movements = assembly.movement_model(config.lookahead, assembly.step_minutes(household, config),
                                            run_end=True).fit(fitted.sequences.packed, household.objects)
        policy = assembly.fetch_policy(assembly.forecaster_over(activity, movements, config.lookahead), config.policy,
                                       s.step_minutes)
    return OnlineAssistant(household, activity, chooser, alignment=config.sequences.alignment,
                           action_threshold=s.action_threshold, day_start_minute=s.day_start_minute,
                           step_minutes=s.step_minutes, max_gap_steps=s.max_gap_steps, fetch_policy=policy,
                           activity_filter=lambda: assembly.activity_filter(activity, emission, fc), emission=emission)
