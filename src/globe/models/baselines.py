"""Reference activity models that share the n-gram model's interface."""

from __future__ import annotations

from collections import Counter
from itertools import repeat
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


class HourActivityBaseline:
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

    def __init__(self, horizons: int, *, slot_minutes: int = 60, shrinkage: float = 0.5, eps: float = 0.01) -> None:
        self.horizons = horizons
        self.slot_minutes = slot_minutes
        self.shrinkage = shrinkage
        self.eps = eps

    def fit(self, days: Sequence) -> "HourActivityBaseline":
        """Count ``days`` (:class:`~globe.data.records.Day`: activities and clock minutes)."""
        h, width = self.horizons, self.slot_minutes
        seen: Counter[tuple[int, int, str, str]] = Counter()  # (horizon, hour, a_r, a_{r+j}); horizon 0: next different
        labels: set[str] = set()
        for day in days:
            acts, n = day.activities, len(day.activities)
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
        self._answers: dict[tuple[int, str, int, bool], dict[str, float]] = {}
        return self

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
