"""Baselines: the rules every model must clear, for the activity (persistence, the time-of-day
mode, hour + current activity) and for objects (the most frequent use given the hour and the
activity, and its horizon version for the lookahead and the fetch policy)."""

from __future__ import annotations

from collections import Counter
from itertools import repeat
from typing import Any, Callable, Collection, Iterable, Mapping, Sequence

import numpy as np

from globe.data.records import Day
from globe.models.base import ActivityModelBase, CountingModel, Weekdays, rank
from globe.models.state_space import StateSpace
from globe.sequences.movements import moved_objects

HOUR_ACTIVITY = "hour_activity"
"""The name of the hour + activity rows in every results table (Table I, the lookahead, the fetch
policy): the activity and object baselines of this module."""

ORACLE = "oracle"
"""The name of the oracle rows of the lookahead and the fetch policy: the movement model told the
true activity of every step ahead (:func:`globe.inference.forecast.forecast_known`). No rule a
robot can follow: the ceiling perfect activity knowledge gives, shown beside the baselines."""

ORACLE_LABEL = "oracle: true activity (not deployable)"
"""How tables and plots name the oracle rows."""


class PersistenceModel(ActivityModelBase):
    """"The activity stays the same": the floor every activity model must clear.

    With no history it predicts the most frequent first activity of the training days.
    """

    kind = "persistence"

    def partial_fit(self, days: Sequence[Sequence[str]], weekdays: Weekdays = None) -> "PersistenceModel":
        if not hasattr(self, "training_data_"):
            self.training_data_: list[tuple[str, ...]] = []
            self.first_: Counter[str] = Counter()
            self.frequency_: Counter[str] = Counter()
        for day in days:
            self.training_data_.append(tuple(day))
            if day:
                self.first_[day[0]] += 1
            self.frequency_.update(day)
        self.classes_ = tuple(sorted(self.frequency_))
        self._learnt()
        return self

    def _build_states(self) -> "PersistenceStates":
        return PersistenceStates(self)


class PersistenceStates(StateSpace):
    """The state is the last activity's code plus one (0: nothing yet, predicting the first)."""

    def __init__(self, model: PersistenceModel) -> None:
        super().__init__(model, model.classes_)
        total = sum(model.first_.values())
        self._first = np.zeros(len(self.labels))
        if total:
            self._first[[self.labels.index(a) for a in model.first_]] = [c / total for c in model.first_.values()]
        self.root = 0

    def _grow_labels(self) -> None:
        self._first = np.concatenate([self._first, np.zeros(len(self.labels) - len(self._first))])

    def last(self, states: np.ndarray) -> np.ndarray:
        return np.asarray(states, dtype=np.int64) - 1

    def children(self, states: np.ndarray, codes: np.ndarray) -> np.ndarray:
        return np.asarray(codes, dtype=np.int64) + 1

    def path(self, day: Sequence[str], weekday: int | None = None) -> np.ndarray:
        """:meth:`StateSpace.path` at once: the state after a step is its activity's code + 1."""
        codes = np.array([self.code(a) for a in day[:-1]], dtype=np.int64)
        return np.concatenate(([self.root], codes + 1)).astype(np.int64) if day else np.empty(0, dtype=np.int64)

    def rows(self, states: np.ndarray) -> np.ndarray:
        states = np.asarray(states, dtype=np.int64)
        out = np.zeros((len(states), len(self.labels)))
        out[states == 0] = self._first
        held = np.flatnonzero(states > 0)
        out[held, states[held] - 1] = 1.0
        return out


def mode(distribution: Mapping[str, float]) -> str | None:
    """The most probable label (ties: the first name), None for an empty or all-zero distribution:
    the point prediction of every baseline, so ties never depend on dict order."""
    best = max(distribution.values(), default=0.0)
    return min((a for a, p in distribution.items() if p == best), default=None) if best > 0 else None


class _TableRow:
    """What the Table I protocol asks of an activity predictor beyond its distributions."""

    kind = "baseline"

    def ranked(self, distribution: Mapping[str, float]) -> list[str]:
        return sorted(distribution, key=lambda a: (-distribution[a], a))

    def top(self, distribution: Mapping[str, float]) -> str | None:
        return mode(distribution)

    def get_params(self) -> dict[str, Any]:
        return {}


class HourActivityBaseline(_TableRow):
    """"Hour + current activity": the activity h steps ahead given the current activity and the
    clock hour, counted per horizon straight from the training days (a *direct* h-ahead estimate,
    where a model's forecast iterates one-step transitions). Its point prediction is the most
    frequent such activity, backing off to the hour's, then to "it stays the same"; as a
    distribution the same levels are shrunk into each other,

        P(b | a, hour) = (n(a, hour -> b) + k P(b | hour, a)) / (n(a, hour) + k)
        P(b | hour, a) = (n(hour -> b) + k P_stay(b | a)) / (n(hour) + k)
        P_stay(b | a)  = 1 - eps if b == a else eps / (A - 1)

    with ``k`` small, so the mode of a seen (activity, hour) wins, and no activity of training
    ever gets 0. The next *different* activity is counted the same way (:meth:`next_proba`).
    """

    kind = "hour_activity"

    def __init__(self, horizons: int, *, slot_minutes: int = 60, shrinkage: float = 0.5, eps: float = 0.01) -> None:
        self.horizons = horizons
        self.slot_minutes = slot_minutes
        self.shrinkage = shrinkage
        self.eps = eps

    def fit(self, days: Sequence) -> "HourActivityBaseline":
        """Count ``days`` (:class:`~globe.data.records.Day`: activities and clock minutes)."""
        self._seen: Counter[tuple[int, int, str, str]] = Counter()  # (horizon, hour, a_r, a_{r+j}); 0: next different
        self._labels: set[str] = set()
        self._first: Counter[str] = Counter()
        return self.partial_fit(days)

    def partial_fit(self, days: Sequence) -> "HourActivityBaseline":
        """Add ``days`` to the counts (a household's session learning day by day: the same counts as
        fitting on every day at once)."""
        if not hasattr(self, "_seen"):
            return self.fit(days)
        h, width = self.horizons, self.slot_minutes
        seen, labels, first = self._seen, self._labels, self._first
        for day in days:
            acts, n = day.activities, len(day.activities)
            first.update(acts[:1])
            slots = [m // width for m in day.minutes]
            labels.update(acts)
            for j in range(1, min(h, n - 1) + 1):
                seen.update(zip(repeat(j, n - j), slots[: n - j], acts[: n - j], acts[j:]))
            after: list[str | None] = [None] * n  # the next activity other than a_r, from the end back
            for r in range(n - 2, -1, -1):
                after[r] = acts[r + 1] if acts[r + 1] != acts[r] else after[r + 1]
            seen.update((0, slots[r], acts[r], b) for r, b in enumerate(after) if b is not None)
        self.pair_: list[dict[tuple[int, str], Counter[str]]] = [{} for _ in range(h + 1)]
        self.slot_: list[dict[int, Counter[str]]] = [{} for _ in range(h + 1)]
        for (j, slot, a, b), c in seen.items():
            self.pair_[j].setdefault((slot, a), Counter())[b] += c
            self.slot_[j].setdefault(slot, Counter())[b] += c
        self.classes_ = tuple(sorted(labels))
        self.first_ = {a: c / sum(first.values()) for a, c in sorted(first.items())} if first else {}
        self._answers: dict[tuple[int, str, int, bool], dict[str, float]] = {}
        return self

    def get_params(self) -> dict[str, Any]:
        return {"horizons": self.horizons, "slot_minutes": self.slot_minutes, "shrinkage": self.shrinkage,
                "eps": self.eps}

    def scan_day(self, day: Any) -> list[dict[str, float]]:
        """One step ahead at every step of ``day`` (a :class:`~globe.data.records.Day`: the Table I
        protocol's question, with the clock it needs): step t from a_{t-1} at its minute, the first
        step from the training days' first activities."""
        acts, minutes = day.activities, day.minutes
        return [dict(self.first_)] + [self.proba(acts[t - 1], minutes[t - 1], 1) for t in range(1, len(acts))]

    def _proba(self, j: int, current: str, minute: int, stay: bool) -> dict[str, float]:
        """The shrunk distribution (class doc), kept per (horizon, activity, hour): few of them
        answer every step of a day. Callers must not change it."""
        key = (j, current, minute // self.slot_minutes, stay)
        hit = self._answers.get(key)
        if hit is None:
            hit = self._answers[key] = self._shrunk(j, current, minute, stay)
        return hit

    def _shrunk(self, j: int, current: str, minute: int, stay: bool) -> dict[str, float]:
        labels, k = self.classes_, self.shrinkage
        n_other = max(len(labels) - 1, 1)
        base = {b: (1 - self.eps if b == current else self.eps / n_other) if stay else
                (0.0 if b == current else 1 / n_other) for b in labels}
        slot = minute // self.slot_minutes
        for counts in (self.slot_[j].get(slot), self.pair_[j].get((slot, current))):
            if counts:
                n = sum(counts.values())
                base = {b: (counts.get(b, 0) + k * base[b]) / (n + k) for b in labels}
        total = sum(base.values())  # below 1 only for an activity training never saw
        return {b: p / total for b, p in base.items()} if total > 0 else base

    def proba(self, current: str, minute: int, steps: int) -> dict[str, float]:
        """P(the activity ``steps`` ahead) for the activity ``current`` at clock ``minute``."""
        return self._proba(steps, current, minute, stay=True)

    def next_proba(self, current: str, minute: int) -> dict[str, float]:
        """P(the next activity other than ``current``), ``current`` under way at ``minute``."""
        return self._proba(0, current, minute, stay=False)


class TimeOfDayBaseline(_TableRow):
    """"The time-of-day mode": at step t, the share of training days on which each activity was
    seen at their step t, whatever happened before. A rule that knows the clock and nothing of the
    day so far; a model that cannot beat it at some horizon has learnt nothing about the hours."""

    kind = "time_of_day"

    def fit(self, days: Sequence[Any]) -> "TimeOfDayBaseline":
        """Count ``days`` (:class:`~globe.data.records.Day`, or plain activity sequences)."""
        counts: list[Counter[str]] = []
        for day in days:
            for t, a in enumerate(getattr(day, "activities", day)):
                if t == len(counts):
                    counts.append(Counter())
                counts[t][a] += 1
        self.by_step_ = [{a: c / sum(seen.values()) for a, c in seen.items()} for seen in counts]
        return self

    def at(self, step: int) -> dict[str, float]:
        """The distribution at ``step`` (empty past the training days' last step)."""
        return self.by_step_[step] if step < len(self.by_step_) else {}

    def scan_proba(self, day: Sequence[str], weekday: int | None = None) -> list[dict[str, float]]:
        """The distribution at every step of a day (the Table I protocol's question)."""
        return [self.at(t) for t in range(len(day))]


class HourActivityObjects(CountingModel):
    """"The most frequent departure given the hour and the activity": the object baseline, with the
    per-activity object n-gram's interface (:class:`~globe.models.objects.ObjectModel`) plus the
    clock, so cross-validation offers it as the household's object model beside the n-gram
    (``models.object_model``). Counted from the runs of training days, each use (a move that
    counts as one: a departure for an imported home, every relocation for HOMER+) credited to its
    run's activity and to the clock slot of the step whose activity it is credited to (the step a
    prediction of the next activity is for), the levels shrunk into each other as
    :class:`HourActivityBaseline`'s,

        P(o | a, slot) = (n(a, slot, o) + k P(o | a)) / (n(a, slot) + k)
        P(o | a)       = (n(a, o) + k P(o)) / (n(a) + k)
        P(o)           = n(o) / n

    so the mode of a seen (activity, slot) wins and the coarser levels break its ties. It ignores
    what moved earlier in the run: what a robot would know from the clock and the activity alone."""

    _parameter_constraints = {"slot_minutes": int, "shrinkage": float}
    kind = "hour_activity_objects"
    reads_clock = True  # trained on timed runs (:func:`~globe.sequences.runs.timed_run_objects`)

    def __init__(self, *, slot_minutes: int = 60, shrinkage: float = 0.5) -> None:
        self.slot_minutes = slot_minutes
        self.shrinkage = shrinkage

    def fit(self, runs: Iterable[tuple[str, Sequence[str], Sequence[int]]]) -> "HourActivityObjects":
        """Count ``runs`` from scratch: (activity, objects used in the run, the clock minute each
        is credited to)."""
        self._reset()
        return self.partial_fit(runs)

    def partial_fit(self, runs: Iterable[tuple[str, Sequence[str], Sequence[int]]]) -> "HourActivityObjects":
        if not hasattr(self, "training_data_"):
            self._validate_params()
            self.training_data_: list[tuple[str, tuple[str, ...], tuple[int, ...]]] = []
            self.pair_: dict[tuple[str, int], Counter[str]] = {}
            self.frequency_: dict[str, Counter[str]] = {}
            self.overall_: Counter[str] = Counter()
        for activity, objects, minutes in runs:
            objects, minutes = tuple(objects), tuple(minutes)
            if len(objects) != len(minutes):
                raise ValueError(f"a run of {activity!r} with {len(objects)} objects and {len(minutes)} minutes")
            self.training_data_.append((activity, objects, minutes))
            for obj, minute in zip(objects, minutes):
                self.pair_.setdefault((activity, minute // self.slot_minutes), Counter())[obj] += 1
                self.frequency_.setdefault(activity, Counter())[obj] += 1
                self.overall_[obj] += 1
        self._answers: dict[tuple[str, int | None], dict[str, float]] = {}
        return self

    def candidates(self, activity: str) -> tuple[str, ...]:
        """O(a): every object used during ``activity`` in training, sorted."""
        self._check_fitted()
        return tuple(sorted(self.frequency_.get(activity, ())))

    def recent_runs(self, activity: str, k: int) -> tuple[tuple[str, ...], ...]:
        """None: a baseline shows the LLM nothing (part of the object models' interface)."""
        return ()

    def predict_proba(self, activity: str, history: Sequence[str] = (), minute: int | None = None
                      ) -> dict[str, float]:
        """P(the object used | ``activity`` at clock ``minute``); without a minute, the activity's
        level. ``history`` is ignored. Memoised: the dict returned is shared, to be read only."""
        self._check_fitted()
        slot = None if minute is None else minute // self.slot_minutes
        found = self._answers.get((activity, slot))
        if found is None:
            found = self._answers[(activity, slot)] = self._shrunk(activity, slot)
        return found

    def _shrunk(self, activity: str, slot: int | None) -> dict[str, float]:
        total, k = sum(self.overall_.values()), self.shrinkage
        if not total:
            return {}
        dist = {o: c / total for o, c in self.overall_.items()}
        levels = [self.frequency_.get(activity)] + ([] if slot is None else [self.pair_.get((activity, slot))])
        for counts in levels:
            if counts:
                n = sum(counts.values())
                dist = {o: (counts.get(o, 0) + k * p) / (n + k) for o, p in dist.items()}
        return dist

    def ranked(self, activity: str, distribution: dict[str, float]) -> list[str]:
        """Most probable first; ties by the activity's counts, then by name."""
        return rank(distribution, self.frequency_.get(activity, {}))

    def predict(self, activity: str, history: Sequence[str] = (), minute: int | None = None) -> str | None:
        ranked = self.ranked(activity, self.predict_proba(activity, history, minute))
        return ranked[0] if ranked else None


SINCE_MINUTES = (30, 120)
"""The clock-aware object model's bands of time since an object's last use that day: not yet
used today, under 30 minutes, under two hours, longer."""


def minutes_since_use(used: np.ndarray, minutes: Sequence[int]) -> np.ndarray:
    """(steps x objects): minutes from each object's last use at or before each step of a day
    (``used``: steps x objects, bool) to that step's clock minute; -1 before its first use."""
    steps = np.arange(len(used))[:, None]
    last = np.maximum.accumulate(np.where(used, steps, -1), axis=0) if len(used) else np.zeros_like(used, dtype=int)
    clock = np.asarray(minutes, dtype=float)
    return np.where(last >= 0, clock[:, None] - clock[np.maximum(last, 0)], -1.0)


class LastUses:
    """The last row of :func:`minutes_since_use` for a day that grows step by step, each step's
    uses final once a later step exists (a household session's day): the steps before ``t`` are
    folded in once, so reading it at every step costs the new steps, not the whole day."""

    def __init__(self, index: Mapping[str, int]) -> None:
        self.index = index  # object -> column
        self.uses: Sequence[Collection[str]] | None = None  # the day folded (its list of per-step uses)
        self.folded = 0  # steps 0..folded-1 are in ``last``
        self.last = np.full(len(index), -1, dtype=np.int64)  # each object's last use step among them

    def since(self, uses: Sequence[Collection[str]], t: int, minute: Callable[[int], int]) -> np.ndarray:
        """Minutes from each object's last use at or before step ``t`` to step ``t``'s clock
        ``minute(t)``; -1 before its first use (``uses[s]``: the objects used at step s)."""
        if uses is not self.uses or self.folded > t:
            self.uses, self.folded, self.last = uses, 0, np.full(len(self.index), -1, dtype=np.int64)
        for s in range(self.folded, t):
            for obj in uses[s]:
                self.last[self.index[obj]] = s
        self.folded = t
        last = self.last.copy()
        for obj in uses[t]:
            last[self.index[obj]] = t
        clock = float(minute(t))
        return np.array([clock - minute(s) if s >= 0 else -1.0 for s in last.tolist()])


def since_band(since: np.ndarray) -> np.ndarray:
    """The band of :data:`SINCE_MINUTES` of each minutes-since-use (0: not used yet that day)."""
    return np.where(since < 0, 0, 1 + np.searchsorted(np.asarray(SINCE_MINUTES), since, side="right"))


class HourActivityAhead:
    """P(an object's event within each of ``horizons`` windows | the current activity, the clock
    slot), counted directly from reference steps of training days: the lookahead's and the fetch
    policy's object baseline (what the event is, a first move or a use within a lead window, is
    the caller's: :meth:`add` takes the outcomes). The same shrinkage as
    :class:`HourActivityObjects`: (activity, slot) -> activity -> every reference, each level a
    share of the references it counted for that object (one in use is not asked whether it will
    be taken).

    With ``clock=True`` it is the *clock-aware* object model, two levels deeper: the day type
    (weekday or weekend, when days are dated), then the time since each object's last use that
    day (:data:`SINCE_MINUTES`), each shrunk towards the level above with the same small ``k``,

        P(o | a, slot, type, band_o) = (n(a, slot, type, band_o; o) + k P(o | a, slot, type))
                                       / (refs(a, slot, type, band_o; o) + k)

    so a cell seen a few times moves the estimate a little and an unseen one leaves it as is: a
    home whose uses follow the hour, the day of the week or a pause after each use is told apart
    from one whose uses follow the activity alone only when the training days show it."""

    def __init__(self, objects: Sequence[str], horizons: int, *, slot_minutes: int = 60,
                 shrinkage: float = 0.5, clock: bool = False) -> None:
        self.objects = tuple(objects)
        self.horizons = horizons
        self.slot_minutes = slot_minutes
        self.shrinkage = shrinkage
        self.clock = clock
        self._shape = (horizons, len(self.objects))
        self._events: dict[object, np.ndarray] = {None: np.zeros(self._shape)}
        self._refs: dict[object, np.ndarray] = {None: np.zeros(len(self.objects))}  # per object
        self._answers: dict[tuple, np.ndarray] = {}

    def _keys(self, activity: str, minute: int, weekday: int | None) -> list[object]:
        """The levels a reference counts in, coarsest first (the day type only for a dated day)."""
        slot = minute // self.slot_minutes
        keys: list[object] = [None, activity, (activity, slot)]
        if self.clock and weekday is not None:
            keys.append((activity, slot, weekday >= 5))
        return keys

    def add(self, activities: Sequence[str], minutes: Sequence[int], events: np.ndarray,
            counted: np.ndarray | None = None, weekday: int | None = None,
            since: np.ndarray | None = None) -> "HourActivityAhead":
        """Count references: the activity and clock minute of each, ``events`` (references x
        horizons x objects, bool: the object's event happened within that window) and ``counted``
        (references x objects: which objects each reference asks about; default all); for the
        clock-aware model, the day's ``weekday`` (None: undated) and ``since`` (references x
        objects: :func:`minutes_since_use`)."""
        events = np.asarray(events, dtype=float)
        asked = np.ones((len(events), len(self.objects))) if counted is None else np.asarray(counted, dtype=float)
        bands = since_band(np.asarray(since)) if self.clock and since is not None else None
        for i, (a, m, ev, c) in enumerate(zip(activities, minutes, events, asked)):
            keys = self._keys(a, m, weekday)
            for key in keys:
                self._count(key, ev, c)
            if bands is not None:
                for b in np.unique(bands[i]).tolist():
                    mine = bands[i] == b
                    self._count((keys[-1], b), ev * mine, c * mine)
        self._answers.clear()
        return self

    def _count(self, key: object, events: np.ndarray, refs: np.ndarray) -> None:
        got = self._events.get(key)
        if got is None:
            self._events[key], self._refs[key] = events.copy(), refs.copy()
        else:
            got += events
            self._refs[key] += refs

    def proba(self, activity: str, minute: int, weekday: int | None = None,
              since: np.ndarray | None = None) -> np.ndarray:
        """(horizons x objects): P(the event within each window) for ``activity`` under way at
        clock ``minute`` (the clock-aware model also reads the day's ``weekday`` and each
        object's minutes ``since`` its last use). Shared: read only."""
        keys = self._keys(activity, minute, weekday)
        found = self._answers.get(tuple(keys))
        if found is None:
            k = self.shrinkage
            n = self._refs[None]
            p = np.divide(self._events[None], n, out=np.zeros(self._shape), where=n > 0)
            for key in keys[1:]:
                if key in self._refs:
                    p = (self._events[key] + k * p) / (self._refs[key] + k)
            found = self._answers[tuple(keys)] = p
        if not self.clock or since is None:
            return found
        bands = since_band(np.asarray(since))
        out = found.copy()
        deepest = next((k for k in reversed(keys) if k in self._refs), None)  # a dated question of undated days
        for b in np.unique(bands).tolist():
            key = (deepest, b)
            if key in self._refs:
                cols = bands == b
                out[:, cols] = (self._events[key][:, cols] + self.shrinkage * out[:, cols]) / (self._refs[key][cols]
                                                                                              + self.shrinkage)
        return out


def used_matrix(day: Day, objects: Sequence[str]) -> np.ndarray:
    """(steps x objects, bool): the objects used (moved, :func:`moved_objects`) at each step of ``day``."""
    used = np.array([[o in moved for o in objects] for moved in moved_objects(day, objects)], dtype=bool)
    return used.reshape(len(day), len(objects))


def fit_uses_ahead(days: Sequence[Day], objects: Sequence[str], min_lead: int, window: int,
                   clock: bool = False, ahead: HourActivityAhead | None = None) -> HourActivityAhead:
    """P(o is used at a step u with ``min_lead`` <= u - t <= ``window`` | the activity at t, the
    clock slot of t), counted at every step t of ``days`` (added to ``ahead`` when given, so a
    session learning day by day counts what fitting on every day at once would): the fetch
    policy's candidates from uses; with ``clock``, the clock-aware model (also the day type and the
    time since o's last use)."""
    ahead = HourActivityAhead(objects, 1, clock=clock) if ahead is None else ahead
    lo = max(1, min_lead)
    for day in days:
        used = used_matrix(day, ahead.objects)
        within = np.zeros((len(day), 1, len(ahead.objects)), dtype=bool)
        for t in range(len(day)):
            within[t, 0] = used[t + lo: t + window + 1].any(axis=0)
        since = minutes_since_use(used, day.minutes) if ahead.clock else None
        ahead.add(day.activities, day.minutes, within, None, day.weekday, since)
    return ahead
