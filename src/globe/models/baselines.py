"""Reference activity models that share the n-gram model's interface."""

from __future__ import annotations

from collections import Counter
from typing import Sequence

from globe.models.base import ActivityModelBase


class PersistenceModel(ActivityModelBase):
    """"The activity stays the same": the floor every activity model must clear.

    With no history it predicts the most frequent first activity of the training days.
    """

    kind = "persistence"

    def partial_fit(self, days: Sequence[Sequence[str]]) -> "PersistenceModel":
        if not hasattr(self, "training_data_"):
            self.training_data_: list[tuple[str, ...]] = []
            self.first_: Counter[str] = Counter()
            self.frequency_: Counter[str] = Counter()
        for day in days:
            self.training_data_.append(tuple(day))
            if day:
                self.first_[day[0]] += 1
            self.frequency_.update(day)
        return self

    def predict_proba(self, history: Sequence[str]) -> dict[str, float]:
        self._check_fitted()
        if history:
            return {history[-1]: 1.0}
        total = sum(self.first_.values())
        return {a: c / total for a, c in self.first_.items()} if total else {}
