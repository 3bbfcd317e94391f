"""A model that knows the clock: the next activity given the current one and the time of day.

Real homes are not scripted: the same person makes breakfast at 07:10 one day and 07:50 the
next, drifts between resting and doing nothing for hours, and no long context repeats. What does
repeat is *when* things happen. This model predicts the activity at step t from the activity at
t-1 and the time slot of t (``slot_minutes`` wide, counted from the day's first step), with
hierarchical shrinkage:

    P(b)            = (n(b) + 1) / (n + A)                                  add-one
    P(b | a)        = (n(a -> b) + k P(b)) / (n(a -> .) + k)
    P(b | a, slot)  = (n(a -> b, slot) + k P(b | a)) / (n(a -> ., slot) + k)

so a slot seen rarely falls back on the time-free bigram, and that on how common each activity
is. The first step is P(a | slot of the first step), shrunk to P(a). Training is counting; its
probabilities are never 0 or 1, which is what a proper scoring rule rewards on real homes.

Where the days carry dates, ``day_types`` adds one more level: ``"weekend"`` (Monday to Friday,
Saturday and Sunday) or ``"weekday"`` (each day of the week),

    P(b | a, slot, type) = (n(a -> b, slot, type) + k P(b | a, slot)) / (n(a -> ., slot, type) + k)

and the first step likewise; a day of no known type (no date) gets the level below.

With ``by_activity=False`` the previous activity is not read: every level's counts are pooled
over it, ``P(b | slot) = (n(. -> b, slot) + k P(b)) / (n(. -> ., slot) + k)``, the time-of-day
baseline as a model (with ample counts its mode is the slot's most frequent activity, whatever
is under way),
so cross-validation can deploy it where it beats the models on the training days.

Shrinkage vanishes where counts are large: a transition never seen after an activity seen a
thousand times gets k P(b) / 1000. ``floor`` interpolates every row with the add-one unigram,
``(1 - floor) P + floor P(b)``, so nothing gets less than ``floor`` times its back-off; it is read
only when predicting, and chosen by cross-validation on log loss (``selection.clock_floors``). The type is
part of the state (:meth:`ClockStates.root_of`), so the filter and the forecaster carry it along
a day with no other code.
"""

from __future__ import annotations

from collections import Counter
from typing import Literal, Sequence, TypeVar

import numpy as np

from globe.errors import ConfigError
from globe.models.base import ActivityModelBase, Weekdays
from globe.models.state_space import StateSpace

_STEP_BITS = 24
_TYPE_SHIFT = 2 * _STEP_BITS  # a state packs (day type, previous activity + 1, step)
_MASK = (1 << _STEP_BITS) - 1
Steps = TypeVar("Steps", int, np.ndarray)
DayTypes = Literal["none", "weekend", "weekday"]
DAY_TYPES: tuple[DayTypes, ...] = ("none", "weekend", "weekday")


def day_type(weekday: int | None, day_types: DayTypes) -> int:
    """The type of a day of ``weekday`` (Monday 0): 0 when not known or not used; under
    ``"weekend"`` 1 for Monday to Friday and 2 for the weekend; under ``"weekday"`` 1 + weekday."""
    if weekday is None or day_types == "none":
        return 0
    if day_types == "weekend":
        return 1 + (weekday >= 5)
    return 1 + weekday


class ClockModel(ActivityModelBase):
    """P(a_t | a_{t-1}, time slot of t), shrunk to the time-free bigram (see module doc)."""

    _parameter_constraints = {"slot_minutes": int, "shrinkage": float, "step_minutes": int, "day_types": DAY_TYPES,
                              "floor": float, "by_activity": bool}
    _prediction_params = frozenset({"shrinkage", "floor"})
    kind = "clock"

    def __init__(self, *, slot_minutes: int = 60, shrinkage: float = 5.0, step_minutes: int = 10,
                 day_types: DayTypes = "none", floor: float = 0.0, by_activity: bool = True) -> None:
        self.slot_minutes = slot_minutes
        self.shrinkage = shrinkage
        self.step_minutes = step_minutes
        self.day_types = day_types
        self.floor = floor
        self.by_activity = by_activity

    def _validate_params(self) -> None:
        super()._validate_params()
        for name in ("slot_minutes", "shrinkage", "step_minutes"):
            if not getattr(self, name) > 0:
                raise ConfigError(f"ClockModel: {name}={getattr(self, name)!r}; expected a positive number")
        if not 0.0 <= self.floor < 1.0:
            raise ConfigError(f"ClockModel: floor={self.floor!r}; expected 0 <= floor < 1")

    def partial_fit(self, days: Sequence[Sequence[str]], weekdays: Weekdays = None) -> "ClockModel":
        if not hasattr(self, "training_data_"):
            self._validate_params()
            self.training_data_: list[tuple[str, ...]] = []
            self.frequency_: Counter[str] = Counter()
            self.first_: Counter[tuple[int, str]] = Counter()  # (day type, activity) of each day's first step
            self.pairs_: Counter[tuple[int, str, str]] = Counter()  # (slot of t, a_{t-1}, a_t)
            self.typed_pairs_: Counter[tuple[int, int, str, str]] = Counter()  # (day type, slot of t, a_{t-1}, a_t)
            self.weekdays_: list[int | None] = []  # each training day's, kept with training_data_ (saved with it)
        if weekdays is not None and (len(weekdays) != len(days) or not all(
                w is None or (type(w) is int and 0 <= w <= 6) for w in weekdays)):
            raise ValueError(f"{len(days)} days but weekdays {list(weekdays)[:8]!r}...: expected one 0-6 (Monday 0) "
                             "or None per day")
        types = [0] * len(days) if weekdays is None else [day_type(w, self.day_types) for w in weekdays]
        self.weekdays_.extend([None] * len(days) if weekdays is None else weekdays)
        for day, kind in zip(days, types):
            day = tuple(day)
            self.training_data_.append(day)
            self.frequency_.update(day)
            if day:
                self.first_[(0, day[0])] += 1
                if kind:
                    self.first_[(kind, day[0])] += 1
            self.pairs_.update((self.slot(t), day[t - 1], day[t]) for t in range(1, len(day)))
            if kind:
                self.typed_pairs_.update((kind, self.slot(t), day[t - 1], day[t]) for t in range(1, len(day)))
        self.classes_ = tuple(sorted(self.frequency_))
        self._learnt()
        return self

    def slot(self, step: Steps) -> Steps:
        """The time slot of ``step`` (steps counted from the day's first; one or an array)."""
        return step * self.step_minutes // self.slot_minutes

    def _build_states(self) -> "ClockStates":
        return ClockStates(self)


class ClockStates(StateSpace):
    """The state is the day type, the last activity (its code + 1; 0: none yet) and the step; the
    next-step rows come from a (day type, slot, previous activity, next activity) table, filled
    per (day type, slot) as it is needed."""

    def __init__(self, model: ClockModel) -> None:
        super().__init__(model, model.classes_)
        self._model = model
        self._tables: dict[int, np.ndarray] = {}
        self._typed: dict[tuple[int, int], np.ndarray] = {}
        self._unigram: np.ndarray | None = None  # floor x the add-one unigram, once
        self.root = 0

    def root_of(self, weekday: int | None) -> int:
        return day_type(weekday, self._model.day_types) << _TYPE_SHIFT

    def _grow_labels(self) -> None:
        self._tables = {}
        self._typed = {}
        self._unigram = None

    def _typed_table(self, kind: int, slot: int) -> np.ndarray:
        """:meth:`_table` on a day of type ``kind``: its own counts shrunk to the table of every day."""
        if not kind:
            return self._table(slot)
        table = self._typed.get((kind, slot))
        if table is None:
            model, labels, k = self._model, list(self.labels), self._model.shrinkage
            n, index = len(labels), {a: i for i, a in enumerate(labels)}
            counts = np.zeros((n + 1, n))
            for (t, s, a, b), c in model.typed_pairs_.items():
                if t == kind and s == slot:
                    counts[index[a] + 1, index[b]] += c
            counts[0] = [model.first_[(kind, b)] for b in labels]
            if not model.by_activity:
                counts[1:] = counts[1:].sum(axis=0)
            table = self._typed[(kind, slot)] = (counts + k * self._table(slot)) / (
                counts.sum(axis=1, keepdims=True) + k)
        return table

    def _table(self, slot: int) -> np.ndarray:
        """((previous activity + 1) x next activity) at ``slot``; row 0 is the first step's."""
        table = self._tables.get(slot)
        if table is None:
            model, labels, k = self._model, list(self.labels), self._model.shrinkage
            n = len(labels)
            counts = np.array([model.frequency_[a] for a in labels], dtype=float)
            unigram = (counts + 1.0) / (counts.sum() + n)
            pairs = np.zeros((n, n))
            in_slot = np.zeros((n, n))
            first = np.array([model.first_[(0, b)] for b in labels], dtype=float)
            index = {a: i for i, a in enumerate(labels)}
            for (s, a, b), c in model.pairs_.items():
                pairs[index[a], index[b]] += c
                if s == slot:
                    in_slot[index[a], index[b]] += c
            if model.by_activity:
                bigram = (pairs + k * unigram) / (pairs.sum(axis=1, keepdims=True) + k)
            else:  # the time of day alone: every previous activity's counts pooled, backing off to the unigram
                in_slot[:] = in_slot.sum(axis=0)
                bigram = np.broadcast_to(unigram, (n, n))
            table = np.empty((n + 1, n))
            table[1:] = (in_slot + k * bigram) / (in_slot.sum(axis=1, keepdims=True) + k)
            table[0] = (first + k * unigram) / (first.sum() + k)
            self._tables[slot] = table
        return table

    def last(self, states: np.ndarray) -> np.ndarray:
        return ((np.asarray(states, dtype=np.int64) >> _STEP_BITS) & _MASK) - 1

    def children(self, states: np.ndarray, codes: np.ndarray) -> np.ndarray:
        states = np.asarray(states, dtype=np.int64)
        kind, step = states >> _TYPE_SHIFT, states & _MASK
        return (kind << _TYPE_SHIFT) | ((np.asarray(codes, dtype=np.int64) + 1) << _STEP_BITS) | (step + 1)

    def path(self, day: Sequence[str], weekday: int | None = None) -> np.ndarray:
        """:meth:`StateSpace.path` at once: the state after step t is (day type, code of step t, t + 1)."""
        if not day:
            return np.empty(0, dtype=np.int64)
        root = self.root_of(weekday)
        codes = np.array([self.code(a) for a in day[:-1]], dtype=np.int64)
        after = root | ((codes + 1) << _STEP_BITS) | np.arange(1, len(day), dtype=np.int64)
        return np.concatenate(([root], after)).astype(np.int64)

    def rows(self, states: np.ndarray) -> np.ndarray:
        states = np.asarray(states, dtype=np.int64)
        kind, previous, step = states >> _TYPE_SHIFT, (states >> _STEP_BITS) & _MASK, states & _MASK
        slots = self._model.slot(step)
        out = np.empty((len(states), len(self.labels)))
        keys = (kind << 32) | slots
        if len(keys) and (keys == keys[0]).all():  # a filter's step: every state at one slot of one day type
            key = int(keys[0])
            out[:] = self._typed_table(key >> 32, key & 0xFFFFFFFF)[previous]
        else:
            for key in np.unique(keys).tolist():
                mine = keys == key
                out[mine] = self._typed_table(key >> 32, key & 0xFFFFFFFF)[previous[mine]]
        floor = self._model.floor
        if floor > 0:
            if self._unigram is None or len(self._unigram) != len(self.labels):
                counts = np.array([self._model.frequency_[a] for a in self.labels], dtype=float)
                self._unigram = floor * (counts + 1.0) / (counts.sum() + len(counts))
            out *= 1 - floor
            out += self._unigram
        return out
