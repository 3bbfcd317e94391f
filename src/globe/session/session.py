"""One household's online loop, for everything that serves or scores it.

A :class:`HouseholdSession` owns what happens step by step in one home, and everything that
serves or replays a household drives one: the service (its HTTP routes, the MQTT publisher, the
dashboard), ``globe predict``, and the evaluation's replays of days (the fetch policy's scores, the
learning curve, the parity with the service). So what the robot is told at a step is what the
evaluation scored at that step.

- **The clock.** A day is cut into the household's own steps from its own day start
  (:mod:`globe.session.grid`). An observation at 18:00 is step 72 of a 10-minute day from 06:00,
  wherever the robot started; several observations inside one step update that step; steps
  nobody observed stay unknown (no label, objects not looked at).
- **The activity estimate.** The activity filter (:mod:`globe.inference.activity_filter`) is
  updated step by step with each step's label, when there is one, and the objects seen moving
  (an object is used at t when its place differs from the observed step t-1 and it was not put
  back from a use place, :mod:`globe.sequences.movements`); a step nobody
  observed is propagated by the activity model alone. With every label seen it is exactly the
  activity model's own prediction.
- **The decision**, once per state of the day (asking again before the next observation gives
  the same answer, and a fetch is decided once): the next activity, the object likely needed
  (through the chooser, the LLM gate when there is one), and the fetches of the fetch policy
  (:func:`~globe.inference.fetch_policy.follow_fetches`: at most ``max_fetches_per_step``, never an
  object waiting for the use it was fetched for, never one in use now or just put back, none at
  the day's last step), forecast from the filter's most probable histories, or, where the
  household deploys the clock-aware uses model (``Deployment.fetch_objects``), read from it with
  the activity under way, the clock, the day type and the time since each object's last use today
  (:meth:`~globe.inference.fetch_policy.FetchPolicy.candidates_at`).
- **Learning** (``learn=True``): when an observation belongs to a new day, the finished day is
  added to every model, so the result equals training on all days at once. Unknown steps of a
  learned day take the filter's most probable history; a day labelled on fewer than half of its
  steps (up to the last observed one) teaches nothing.
- **Sensors** (a household with ambient sensors, :mod:`globe.session.sensing`): every step up to
  the last observed one also takes in what the sensors showed there (the events observations
  carry), as the filter's likelihood, in the same filter. A step without a label then has its
  activity *recognised* (the filter's most probable activity there); with a budget of questions a
  day, the session asks "what are you doing?" where an answer is worth most
  (:class:`~globe.recognition.asking.QuestionPolicy`, decided as each observation is applied, so a
  replay asks the same questions); an answer is the step's label. The emission learns each
  finished day from its labelled and answered steps.

A household may start with no training day (cold start): until it has learned a first day its
decisions say ``status = "learning"`` and never fetch.
"""

from __future__ import annotations

import datetime as dt
import sys
import threading
from collections import Counter
from typing import Any, Sequence

import numpy as np

from globe.config import Deployment
from globe.data.csv_logs import activity_label
from globe.data.labels import known_activity
from globe.data.records import Day, Household
from globe.data.sensors import SensorDay
from globe.errors import DataError, UnknownLabelError
from globe.inference.activity_filter import ActivityFilter, Belief, HistoryMemo, as_dicts
from globe.inference.emission import MovementEmission
from globe.inference.fetch_policy import (
    FetchCandidate,
    FetchContext,
    FetchPolicy,
    FetchReport,
    follow_fetches,
    left_alone,
)
from globe.inference.forecast import Forecast, mixture
from globe.models.base import ActivityModelBase, stay_or_change
from globe.models.baselines import HourActivityBaseline, LastUses, mode
from globe.reasoning.choice import ObjectChooser, run_context
from globe.recognition.asking import DayAsker
from globe.sequences.movements import Alignment, used_between
from globe.sequences.runs import activity_runs, object_runs
from globe.session.grid import DayGrid
from globe.session.recognising import SensorSteps
from globe.session.records import Decision, NewActivities, Observation, Placement, Settled, instant
from globe.session.sensing import (
    Question,
    SessionSensors,
    seconds_after_midnight,
)


class HouseholdSession(SensorSteps):
    """The online loop of one household (see module doc; thread-safe: one lock serialises it)."""

    def __init__(self, household: Household, *, activity: ActivityModelBase, chooser: ObjectChooser,
                 emission: MovementEmission, policy: FetchPolicy, grid: DayGrid, deployment: Deployment,
                 alignment: Alignment = "previous", max_hypotheses: int = 32, min_weight: float = 1e-4,
                 forecast_hypotheses: int = 4, learn: bool = True, new_activities: NewActivities = "refuse",
                 sensing: SessionSensors | None = None) -> None:
        self.activity_model = activity
        self.chooser = chooser
        self.emission = emission
        self.policy = policy
        self.grid = grid
        self.deployment = deployment
        self.alignment = alignment
        self.max_hypotheses = max_hypotheses
        self.min_weight = min_weight
        self.forecast_hypotheses = forecast_hypotheses
        self.learning = learn
        self.new_activities = new_activities
        self.sensing = sensing
        self.lock = threading.RLock()
        self._locations = {label: label for label in household.locations}  # interned labels
        self._object_index = {o: i for i, o in enumerate(household.objects)}
        self._use_places = household.use_places
        starts: dict[str, list[str]] = {}  # each object's movable nodes' start locations, in map order
        for n in household.nodes:
            if n.movable:
                starts.setdefault(n.cls, []).append(self._locations[n.start_location])
        self._start = tuple(loc for o in household.objects for loc in starts.get(o, ()))
        # the training days are counted, then dropped: the map is kept (memory per household stays small)
        self.household = Household(household.name, household.nodes, household.objects, (), (), household.source)
        self.days_learned = len(household.train)
        self.hour_activity = HourActivityBaseline(1).fit(household.train)  # the online scores' baseline
        self.learned_days = [d.name for d in household.train]  # their names, in the order learned
        self.observations = 0
        self.fallbacks: Counter[str] = Counter()
        self._last_instant: dt.datetime | None = None
        self._decided: tuple[tuple, Decision] | None = None
        self._filter: ActivityFilter | None = None  # today's, over the models as they are today
        self._beliefs: list[Belief] = []  # the filter's, before the day and after each observed step
        self._stale: int | None = None  # the first step the filter has not taken in since it changed
        self._belief_dist: tuple[tuple, dict[str, float]] | None = None
        self._sensor_day: SensorDay | None = None  # today's sensor activations, as read (None: to read again)
        self._asker: DayAsker | None = None  # today's questions (a household with sensors and a budget)
        self._question: Question | None = None  # the last question asked today
        self._recognition: tuple[tuple, list[tuple[str, float] | None]] | None = None  # recognised_today's, by state
        self._open(None)

    # -- validation ------------------------------------------------------------------------
    def validate(self, obs: Observation) -> None:
        """Raise :class:`DataError` (naming the field) for an observation that must not be stored."""
        self.validate_labels(obs)
        self.validate_time(obs)

    def validate_time(self, obs: Observation) -> None:
        """The check of :meth:`validate` that depends on the observations before: times increase."""
        when = instant(obs.time)
        if self._last_instant is not None and when <= self._last_instant:
            raise DataError(f"time {obs.time.isoformat()} is not after the last observation "
                            f"{self._last_instant.isoformat()}", field="time")

    def validate_labels(self, obs: Observation) -> None:
        """The checks of :meth:`validate` that do not depend on the observations before it."""
        if obs.activity is not None:
            self.activity_label(obs.activity)
        for obj, loc in obs.locations.items():
            if obj not in self._object_index:
                raise UnknownLabelError(f"unknown object {obj[:64]!r} (not a movable node of household "
                                        f"{self.household.name})", field=f"locations.{obj[:64]}")
            if loc not in self._locations:
                raise UnknownLabelError(f"unknown location {loc[:64]!r} for {obj!r}", field=f"locations.{obj}")
        if obs.sensors:
            self.validate_sensors(obs.sensors)

    def activity_label(self, raw: str) -> str:
        """The one label rule (:func:`globe.data.labels.known_activity`): an activity this household
        knows, or, when it learns new activities, any valid label."""
        return known_activity(raw, self.known_activities(), learn=self.new_activities == "learn")

    def known_activities(self) -> tuple[str, ...]:
        """The activities this household knows (learned, or seen today)."""
        known = dict.fromkeys(getattr(self.activity_model, "classes_", ()))
        known.update(dict.fromkeys(a for a in self._labels if a is not None))
        return tuple(known)

    @property
    def last_instant(self) -> dt.datetime | None:
        """The UTC instant of the last observation applied (None before any)."""
        return self._last_instant

    # -- the loop -------------------------------------------------------------------------------
    def placement(self, time: dt.datetime) -> Placement:
        """Where an observation at ``time`` would land (no state changes)."""
        day, step = self.grid.place(time)
        last = len(self._labels) - 1
        return Placement(day, step if day != self._day or step > last else last, day != self._day or step > last)

    def observe(self, obs: Observation) -> Placement:
        """Add one observation (validated by :meth:`validate` where it may be refused: a replayed
        day's labels are data); a new day first learns the finished one."""
        day, step = self.grid.place(obs.time)
        if day != self._day:
            if self._day is not None:
                self._close()
            self._open(day)
        activity = sys.intern(activity_label(obs.activity)) if obs.activity is not None else None
        last = len(self._labels) - 1
        if step <= last:  # inside the step under way (or a clock repeating an hour): update it
            step = last
        else:
            previous = self._states[-1] if self._states else self._start
            for _ in range(step - last):  # steps nobody observed: no label, objects where they were
                self._labels.append(None)
                self._states.append(previous)
                self._looked.append(False)
                self._uses.append(frozenset())
        if activity is not None:
            self._labels[step] = activity
        evidence = step  # the first step whose evidence this observation changes
        if obs.sensors and self.sensing is not None:
            index = self.sensing.index
            self._events += [(index[e.sensor], seconds_after_midnight(e.start, day), seconds_after_midnight(e.end, day))
                             for e in obs.sensors]
            self._sensor_day = None
            first_day, first = min(self.grid.place(e.start) for e in obs.sensors)
            if first_day <= day:  # activations reported late are the evidence of the steps they began in
                evidence = min(step, max(0, first) if first_day == day else 0)
        if obs.locations:
            state = list(self._states[step])
            for obj, loc in obs.locations.items():
                state[self._object_index[obj]] = self._locations[loc]
            self._states[step] = tuple(state)
        first = self._looked.index(True) if True in self._looked else step
        if first == step:  # nothing was seen before today's first observation: no object moved before it
            self._states[:step] = [self._states[step]] * step
        self._looked[step] = True
        if step and self._looked[step - 1]:
            self._uses[step] = self.moved(step)
        self._stale = evidence if self._stale is None else min(self._stale, evidence)
        self._last_instant = instant(obs.time)
        self.observations += 1
        self._consult(step)
        return Placement(day, step, True)

    def _filtered(self) -> Belief | None:
        """The activity filter's belief after the last observed step (None before a first day is
        learned), the steps it has not taken in yet updated now: it runs only once a step lacks its
        label (with every label seen the activity model answers itself), the same updates at once
        or one at a time."""
        if self._filter is None:
            return None
        if self._stale is not None:
            kept = self._beliefs  # in step order: those the stale steps changed are dropped from the end
            while kept and kept[-1].step >= self._stale:
                kept.pop()
            sensing = self.sensing
            first = max(self._stale - 1, 0)  # the step before: its evidence on the change into the first
            features = None if sensing is None else sensing.features(
                self._today_events(), [self.grid.minute(t) for t in range(first, len(self._labels))])
            labels: list[str] = []
            likes = edges = None
            for t in range(self._stale, len(self._labels)):
                if self._looked[t] or features is not None:  # the sensors watched every step
                    moved = self._uses[t] if t and self._looked[t] and self._looked[t - 1] else None
                    like = edge = None
                    if features is not None and sensing is not None:
                        if likes is None or len(labels) != len(self._filter.labels):  # (again when a label is new)
                            labels = list(self._filter.labels)
                            likes = sensing.likelihoods(features, labels)
                            edges = sensing.edge_tables(features, labels)
                        like = likes[t - first][None, :]
                        edge = edges[t - 1 - first][None] if edges is not None and t else None
                    kept.append(self._filter.update(kept[-1], t, [self._labels[t]], [moved], likelihood=like,
                                                    edges=edge))
            last = None if edges is None else edges[-1][None]  # the last step's, on the change after it
            self._beliefs, self._stale, self._edges_last = kept, None, last
        return self._beliefs[-1]

    def moved(self, step: int) -> frozenset[str]:
        """The objects used at ``step``: its place differs from the step before's, and it was not
        put back from a use place (:func:`~globe.sequences.movements.used_between`)."""
        if not step:
            return frozenset()
        return frozenset(used_between(self.household.objects, self._states[step - 1], self._states[step]))

    # -- what is known of today ---------------------------------------------------------------
    @property
    def day(self) -> str | None:
        """The day of the last observation (an ISO date; None before any)."""
        return self._day

    @property
    def weekday(self) -> int | None:
        """Today's day of the week (Monday 0; None before any observation)."""
        return None if self._day is None else dt.date.fromisoformat(self._day).weekday()

    @property
    def step(self) -> int | None:
        """The last observed step of today (None before any observation)."""
        return len(self._labels) - 1 if self._labels else None

    @property
    def status(self) -> str:
        return "ready" if self.days_learned > 0 else "learning"

    def observed_activity(self, step: int) -> str | None:
        """Today's activity at ``step`` as observed (None: unknown)."""
        return self._labels[step] if 0 <= step < len(self._labels) else None

    def observed(self, step: int) -> bool:
        """Whether ``step`` of today was observed."""
        return 0 <= step < len(self._looked) and self._looked[step]

    def today(self) -> list[tuple[int, str | None, bool]]:
        """(minute since midnight, observed activity or None, observed) of each step today."""
        return [(self.grid.minute(t), a, seen) for t, (a, seen) in enumerate(zip(self._labels, self._looked))]

    def activity_history(self) -> tuple[str, ...]:
        """Today's activities: the labels seen, unknown steps the filter's most probable history
        (before a first day is learned, the nearest label: there is no model to ask)."""
        if None not in self._labels:
            return tuple(self._labels)  # type: ignore[arg-type]
        belief = self._filtered()
        if self._filter is not None and belief is not None and belief.step >= 0:
            return self._filter.history(belief, int(np.argmax(belief.beam.weight)), memo=self._history_memo)
        return _nearest_labels(self._labels)

    def current_day(self) -> Day:
        """Today so far as a day (unknown activities as :meth:`activity_history` fills them)."""
        minutes = tuple(self.grid.minute(t) for t in range(len(self._labels)))
        return Day(f"live/{self._day}", minutes, self.activity_history(), tuple(self._states))

    def uses(self) -> list[frozenset[str]]:
        """Per step today, the objects used (moved) at it (none at steps after one nobody observed)."""
        return list(self._uses)

    def fetch_report(self, settled_only: bool = False) -> FetchReport:
        """Today's fetches so far, scored against today so far by the one rule of fetches
        (:func:`~globe.inference.fetch_policy.follow_fetches`). ``settled_only`` leaves out the
        fetches still waiting for their use inside their window (not yet right or wrong: a live
        precision counting them would read 0 % the minute after a first fetch)."""
        minutes = [self.grid.minute(t) for t in range(len(self._labels))]
        p = self.policy
        fetched = self.fetched_today
        report, waiting = follow_fetches(self.uses(), minutes, lambda t, _: fetched.get(t, ()), len(minutes),
                                         p.min_lead_steps, p.window_steps)
        if settled_only:
            report.fetches -= len(waiting)  # a waiting fetch was not used since: none of them counted useful
        return report

    # -- online scores ---------------------------------------------------------------------------
    def settle(self, place: Placement) -> Settled:
        """What an observation landing at ``place`` settles, read before it is applied (see
        :class:`Settled`): the one-step prediction of the step it closes is scored against that
        step's label (steps whose label stayed unknown, and the first step of a day or after one
        nobody observed, are not scored), a new day closes the finished day's fetches, and a step
        opened right after the last one gets its one-step prediction (what :meth:`decide` says of it)."""
        if not place.new_step or self._day is None:
            return Settled(self._day)
        scored = observed = fetches = opened = baselines = None
        if self._labels:
            last = len(self._labels) - 1
            predicted, label = self.step_predictions.get(last), self._labels[last]
            if predicted is not None and label is not None:
                scored, observed = (last, predicted[0] == label), (last, label)
                baselines = self._baselines_right(last, label)
            if place.day != self._day:
                fetches = self.fetch_report()
        if place.day == self._day and place.step == len(self._labels) and self._looked and self._looked[-1]:
            top = self.next_activity()
            if top is not None:
                opened = (place.step, *top)
        return Settled(self._day, scored, observed, fetches, opened, baselines)

    def _baselines_right(self, step: int, label: str) -> tuple[bool, bool]:
        """Whether persistence (the activity stays) and hour + activity (the most frequent next
        activity given it and the hour, counted on the days learnt) predicted ``label`` at ``step``
        from the step before (its label, else the last label before it)."""
        previous = next((a for a in reversed(self._labels[:step]) if a is not None), None)
        if previous is None:
            return False, False
        rule = mode(self.hour_activity.proba(previous, self.grid.minute(step - 1), 1))
        return previous == label, rule == label

    def remember(self, settled: Settled) -> None:
        """After the observation: keep the one-step prediction of the step it opened (scored when
        that step closes)."""
        if settled.opened is not None:
            step, activity, probability = settled.opened
            self.step_predictions[step] = (activity, probability)

    # -- the decision ---------------------------------------------------------------------------
    def _state(self) -> tuple:
        return self._day, len(self._labels), self.observations, self.days_learned

    @property
    def last_decision(self) -> Decision | None:
        """The decision already made for the current state of the day, if any."""
        return self._decided[1] if self._decided is not None and self._decided[0] == self._state() else None

    def belief(self) -> dict[str, float]:
        """P(the activity at the next step | everything observed today), {} while learning: with
        every step labelled the activity model's own ``predict_proba`` (what Table I scores, to the
        bit), else the filter's."""
        if self._filter is None:
            return {}
        state = self._state()
        if self._belief_dist is None or self._belief_dist[0] != state:
            belief = self._filtered() if None in self._labels else None
            if belief is not None:  # with what the last step showed of the change after it
                dist = as_dicts(self._filter.predictive(belief, self._edges_last), self._filter.labels)[0]
            else:
                dist = self.activity_model.predict_proba(tuple(self._labels), self.weekday)  # type: ignore[arg-type]
            self._belief_dist = (state, dist)
        return self._belief_dist[1]

    def next_activity(self) -> tuple[str, float] | None:
        """The next activity said and its probability (what :meth:`decide` says), or None: the
        likeliest, kept at the activity under way (its label, else the one recognised) by the
        deployment's stay margin (:func:`~globe.models.base.stay_or_change`, as the evaluation scores it)."""
        if self.days_learned == 0 or not self._labels:
            return None
        belief = self.belief()
        found = self.recognised()
        current = self._labels[-1] or (found[0] if found is not None else None)
        said = stay_or_change(self.activity_model.top(belief), belief, current, self.deployment.models.stay_margin)
        return (said, float(belief.get(said, 0.0))) if said is not None else None

    def decide(self) -> Decision:
        """Next activity, the object likely needed and what to fetch: decided once per state of
        the day, so every caller (the robot polling, Home Assistant's publisher) gets the same
        answer and a fetch is decided once, until the next observation."""
        decided = self.last_decision
        if decided is not None:
            return decided
        decision = self._decide()
        self._decided = (self._state(), decision)
        if decision.choice is not None and decision.choice.fallback:
            self.fallbacks[decision.choice.fallback] += 1
        if decision.fetches and self.step is not None:
            self.fetched_today.setdefault(self.step, []).extend(c.obj for c in decision.fetches)
        return decision

    def _decide(self) -> Decision:
        step = len(self._labels)
        labelled, recognised = self.step_counts()
        found, question = self.recognised(), self.question()
        nothing = Decision(self.status, self.days_learned, self._day or "", step, None, 0.0, None, (),
                           recognised=found, labelled_steps=labelled, recognised_steps=recognised, question=question)
        top = self.next_activity()
        if top is None:
            return nothing
        nxt, probability = top
        activity, objects = self._current_run()
        choice = self.chooser.choose_given(nxt, self.belief(), run_context(activity, objects),
                                           minute=self.grid.minute(step))
        fetches, candidates, alone = self._fetches()
        return Decision(self.status, self.days_learned, self._day or "", step, nxt, probability, choice, fetches,
                        candidates, alone, found, labelled, recognised, question)

    def object_ranking(self, activity: str, run: Sequence[str] | None = None) -> tuple[list[str], dict[str, float]]:
        """The objects likely needed during ``activity``, most likely first, and their
        probabilities, given the objects already moved in the run under way (``run``: as the
        objects of a run of ``activity``; default: today's)."""
        context = run_context(activity, tuple(run)) if run is not None else run_context(*self._current_run())
        return self.chooser.ngram_ranking(activity, self.belief(), context, self.grid.minute(len(self._labels)))

    def _current_run(self) -> tuple[str | None, tuple[str, ...]]:
        """The activity under way and the objects moved in its run so far (the runs of the day
        from two steps before it began: which activity a movement belongs to looks one step away)."""
        acts = self.activity_history()
        start = len(acts) - 1
        while start > 0 and acts[start - 1] == acts[-1]:
            start -= 1
        lo = max(0, start - 2)
        minutes = tuple(range(self.grid.minute(lo), self.grid.minute(len(acts)), self.grid.step_minutes))
        tail = Day(f"live/{self._day}", minutes, acts[lo:], tuple(self._states[lo:]))
        runs = activity_runs(tail, self.household.objects, self.alignment)
        return (runs[-1].activity, runs[-1].objects) if runs else (None, ())

    def waiting(self) -> dict[str, int]:
        """Objects fetched today that still wait for their use (object -> step fetched), after the
        last observed step's uses (fetches decided at that step already included)."""
        t, window = len(self._labels) - 1, self.policy.window_steps
        lo = max(0, t - window + 1)  # a fetch made before lo has had its window
        minutes = [self.grid.minute(s) for s in range(lo, t + 1)]
        fetched = {s - lo: objs for s, objs in self.fetched_today.items() if lo <= s <= t}
        found = follow_fetches(self._uses[lo:], minutes, lambda s, _: fetched.get(s, ()), t + 1 - lo,
                               self.policy.min_lead_steps, window)[1]
        return {obj: s + lo for obj, s in found.items()}

    def _fetches(self) -> tuple[tuple[FetchCandidate, ...], tuple[FetchCandidate, ...], frozenset[str]]:
        """(the fetches to start now, every candidate, the objects left alone)."""
        t = len(self._labels) - 1
        if t >= self.grid.last_step or self.days_learned == 0:
            return (), (), frozenset()
        candidates = tuple(self.policy.candidates_at(self._fetch_context(t)))
        before = self._states[t - 1] if t else self._states[t]
        alone = left_alone(self.household.objects, before, self._states[t], self._use_places)
        chosen = self.policy.choose(candidates, exclude=set(self.waiting()) | alone)
        return tuple(chosen), candidates, alone

    def _fetch_context(self, t: int) -> FetchContext:
        """What the fetch policy's candidates after step ``t`` are read from (the activity under way:
        the step's label, else the filter's most probable history's; each object's minutes since
        its last use today: the uses seen so far)."""
        since = np.empty(0)
        uses = self.policy.uses
        if uses is not None and uses.clock:  # read only by the clock-aware uses model
            since = self._last_uses.since(self._uses, t, self.grid.minute)
        activity = self._labels[t] or next(reversed(self.activity_history()), "")
        return FetchContext(activity, self.grid.minute(t), self.weekday, since, self.forecast)

    # -- forecasting ----------------------------------------------------------------------------
    def forecast(self, horizon: int) -> Forecast:
        """Where every object is expected to go in the next ``horizon + 1`` steps: from today's
        labels when every step has one, else mixed over the filter's most probable histories."""
        fc = self.policy.forecaster
        states = self._states
        belief = self._filtered() if None in self._labels else None
        if self._filter is None or belief is None:
            histories, weights = [self.activity_history()], np.ones(1)
        else:
            found = self._filter.top_histories(belief, self.forecast_hypotheses, memo=self._history_memo)
            histories, weights = [h.history for h in found], np.array([h.weight for h in found])
        many = fc.forecast_many([(h, states) for h in histories], horizon, weekdays=[self.weekday] * len(histories))
        return mixture(many, weights)

    def next_hour(self, steps: int) -> list[tuple[str, list[float], str | None]]:
        """Per object, P(first used at each of the next ``steps`` steps) and where it would most
        likely be taken; [] before a first learned day or today's first observation."""
        if self.days_learned == 0 or not self._labels:
            return []
        forecast = self.forecast(max(0, steps - 1))
        targets = forecast.likely_target(1, steps)
        return [(obj, [float(x) for x in forecast.departure[:steps, j]], targets[j])
                for j, obj in enumerate(forecast.objects)]

    # -- days -------------------------------------------------------------------------------------
    def _open(self, day: str | None) -> None:
        self._day = day
        self._labels: list[str | None] = []
        self._states: list[tuple[str, ...]] = []
        self._looked: list[bool] = []
        self._uses: list[frozenset[str]] = []  # per step, the objects seen moving there
        self.fetched_today: dict[int, list[str]] = {}  # step -> the objects decided after it
        self.step_predictions: dict[int, tuple[str, float]] = {}  # today's one-step predictions (by the service)
        self._belief_dist = None
        self._filter = None
        self._beliefs, self._stale, self._edges_last = [], None, None
        self._history_memo = HistoryMemo()  # the most probable history read last (its walk back stops there)
        self._last_uses = LastUses(self._object_index)
        self._events: list[tuple[int, float, float]] = []  # today's sensor activations (sensor, start, end)
        self._sensor_day = None
        self._asker = None
        self._question = None
        self._asked: list[int] = []  # today's steps asked about
        self._recognition = None
        self._worths: dict[int, float] = {}  # per unlabelled step, the worth of asking there
        if self.days_learned > 0:
            sensing = self.sensing
            floor = sensing.change_floor if sensing is not None else 0.0  # reading sensors: unseen changes possible
            self._filter = ActivityFilter(self.activity_model, self.emission, max_hypotheses=self.max_hypotheses,
                                          min_weight=self.min_weight, change_floor=floor)
            weekday = None if day is None else dt.date.fromisoformat(day).weekday()
            self._beliefs = [self._filter.start(1, weekdays=[weekday])]
            policy = sensing.policy() if sensing is not None else None
            if sensing is not None and policy is not None and day is not None:
                # the same worth the evaluation's asking curve scores: unsure, and about activities little labelled
                self._asker = DayAsker(policy, self.grid.steps,
                                       labelled=sensing.emission.labelled_steps(self._filter.labels))

    def _close(self) -> None:
        """The finished day is learned (see module doc)."""
        if self.learning:
            self._learn_sensors()
        labelled = sum(a is not None for a in self._labels)
        first = self.days_learned == 0 and self.sensing is not None and labelled > 0  # a cold start's answers
        if self.learning and len(self._labels) >= 2 and (2 * labelled >= len(self._labels) or first):
            self.learn([self.current_day()])

    def learn(self, days: Sequence[Day]) -> None:
        """Add whole days to every model (the same counts as training on them from the start)."""
        objects = self.household.objects
        self.activity_model.partial_fit([d.activities for d in days], [d.weekday for d in days])
        model = self.chooser.model
        model.partial_fit(object_runs(days, objects, self.alignment, model.reads_clock))  # type: ignore[attr-defined]
        self.emission.partial_fit(days, objects)
        self.policy.learn(days)
        self.hour_activity.partial_fit(days)
        self.days_learned += len(days)
        self.learned_days += [d.name for d in days]

    def stats(self) -> dict[str, Any]:
        return {"household": self.household.name, "status": self.status, "days_learned": self.days_learned,
                "observations": self.observations, "current_day": self._day, "steps_today": len(self._labels),
                "activities_known": len(getattr(self.activity_model, "classes_", ())),
                "training_days": len(getattr(self.activity_model, "training_data_", ())),
                "llm_fallbacks": dict(self.fallbacks)}


def _nearest_labels(labels: Sequence[str | None]) -> tuple[str, ...]:
    """Unknown steps take the last label before them (leading ones the first label): the stand-in
    of a household that has learned nothing yet, whose filter has no model to ask."""
    first = next((a for a in labels if a is not None), None)
    if first is None:
        return ()
    out, last = [], first
    for a in labels:
        last = a if a is not None else last
        out.append(last)
    return tuple(out)
