"""Reference activity models that share the n-gram model's interface."""

from __future__ import annotations

from collections import Counter
from typing import Sequence

import numpy as np

from globe.models.base import ActivityModelBase, Weekdays
from globe.models.state_space import StateSpace


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
