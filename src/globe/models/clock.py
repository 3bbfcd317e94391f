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
"""

from __future__ import annotations

from collections import Counter
from typing import Sequence, TypeVar

import numpy as np

from globe.errors import ConfigError
from globe.models.base import ActivityModelBase
from globe.models.state_space import StateSpace

_STEP_BITS = 24
Steps = TypeVar("Steps", int, np.ndarray)


class ClockModel(ActivityModelBase):
    """P(a_t | a_{t-1}, time slot of t), shrunk to the time-free bigram (see module doc)."""

    _parameter_constraints = {"slot_minutes": int, "shrinkage": float, "step_minutes": int}
    _prediction_params = frozenset({"shrinkage"})
    kind = "clock"

    def __init__(self, *, slot_minutes: int = 60, shrinkage: float = 5.0, step_minutes: int = 10) -> None:
        self.slot_minutes = slot_minutes
        self.shrinkage = shrinkage
        self.step_minutes = step_minutes

    def _validate_params(self) -> None:
        super()._validate_params()
        for name in ("slot_minutes", "shrinkage", "step_minutes"):
            if not getattr(self, name) > 0:
                raise ConfigError(f"ClockModel: {name}={getattr(self, name)!r}; expected a positive number")

    def partial_fit(self, days: Sequence[Sequence[str]]) -> "ClockModel":
        if not hasattr(self, "training_data_"):
            self._validate_params()
            self.training_data_: list[tuple[str, ...]] = []
            self.frequency_: Counter[str] = Counter()
            self.first_: Counter[tuple[int, str]] = Counter()  # (slot, activity) of each day's first step
            self.pairs_: Counter[tuple[int, str, str]] = Counter()  # (slot of t, a_{t-1}, a_t)
        for day in days:
            day = tuple(day)
            self.training_data_.append(day)
            self.frequency_.update(day)
            if day:
                self.first_[(0, day[0])] += 1
            self.pairs_.update((self.slot(t), day[t - 1], day[t]) for t in range(1, len(day)))
        self.classes_ = tuple(sorted(self.frequency_))
        self._learnt()
        return self

    def slot(self, step: Steps) -> Steps:
        """The time slot of ``step`` (steps counted from the day's first; one or an array)."""
        return step * self.step_minutes // self.slot_minutes

    def _build_states(self) -> "ClockStates":
        return ClockStates(self)


class ClockStates(StateSpace):
    """The state is the last activity (its code + 1; 0: none yet) and the step; the next-step rows
    come from a (slot, previous activity, next activity) table, filled per slot as it is needed."""

    def __init__(self, model: ClockModel) -> None:
        super().__init__(model, model.classes_)
        self._model = model
        self._tables: dict[int, np.ndarray] = {}
        self.root = 0

    def _grow_labels(self) -> None:
        self._tables = {}

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
            bigram = (pairs + k * unigram) / (pairs.sum(axis=1, keepdims=True) + k)
            table = np.empty((n + 1, n))
            table[1:] = (in_slot + k * bigram) / (in_slot.sum(axis=1, keepdims=True) + k)
            table[0] = (first + k * unigram) / (first.sum() + k)
            self._tables[slot] = table
        return table

    def last(self, states: np.ndarray) -> np.ndarray:
        return (np.asarray(states, dtype=np.int64) >> _STEP_BITS) - 1

    def children(self, states: np.ndarray, codes: np.ndarray) -> np.ndarray:
        step = np.asarray(states, dtype=np.int64) & ((1 << _STEP_BITS) - 1)
        return ((np.asarray(codes, dtype=np.int64) + 1) << _STEP_BITS) | (step + 1)

    def path(self, day: Sequence[str]) -> np.ndarray:
        """:meth:`StateSpace.path` at once: the state after step t is (code of step t, t + 1)."""
        if not day:
            return np.empty(0, dtype=np.int64)
        codes = np.array([self.code(a) for a in day[:-1]], dtype=np.int64)
        after = ((codes + 1) << _STEP_BITS) | np.arange(1, len(day), dtype=np.int64)
        return np.concatenate(([self.root], after)).astype(np.int64)

    def rows(self, states: np.ndarray) -> np.ndarray:
        states = np.asarray(states, dtype=np.int64)
        previous, step = states >> _STEP_BITS, states & ((1 << _STEP_BITS) - 1)
        slots = self._model.slot(step)
        out = np.empty((len(states), len(self.labels)))
        for slot in np.unique(slots).tolist():
            mine = slots == slot
            out[mine] = self._table(slot)[previous[mine]]
        return out
