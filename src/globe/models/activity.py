"""Next-activity model: an n-gram Markov model over the day's activity sequence."""

from __future__ import annotations

from collections import Counter
from typing import Sequence

from globe.models.backoff import (
    ESTIMATORS,
    longest_distribution,
    witten_bell_distribution,
)
from globe.models.base import ActivityModelBase
from globe.models.suffix_index import SuffixIndex

DAY_START = "<day>"


class ActivityModel(ActivityModelBase):
    """P(a_t | a_0 .. a_{t-1}) with a day-start token and backoff (maximum n = ``max_order``).

    ``estimator="longest"`` (default) is the paper's rule: the longest context seen in training
    decides. ``"witten_bell"`` interpolates all context lengths. ``time_weight`` > 0 multiplies
    in a time-of-day expert P(a | step)^w, which knows that breakfast happens in the morning.
    """

    _parameter_constraints = {"estimator": ESTIMATORS, "max_order": int, "time_weight": float, "time_window": int}
    _prediction_params = frozenset(_parameter_constraints)  # the automaton holds every order
    kind = "activity"

    def __init__(self, *, estimator: str = "longest", max_order: int = 109, time_weight: float = 0.0, time_window: int = 2) -> None:
        self.estimator = estimator
        self.max_order = max_order
        self.time_weight = time_weight
        self.time_window = time_window

    # -- training ---------------------------------------------------------------------------
    def partial_fit(self, days: Sequence[Sequence[str]]) -> "ActivityModel":
        """Add observed days to the counts (no retraining of what was seen before)."""
        if not hasattr(self, "training_data_"):
            self._validate_params()
            self.training_data_: list[tuple[str, ...]] = []
            self.index_ = SuffixIndex(never_predicted=[DAY_START])
            self.frequency_: Counter[str] = Counter()
            self.by_step_: list[Counter[str]] = []
        at_step: Counter[tuple[int, str]] = Counter()  # (step, activity): counted at C speed, then spread
        added = []
        for day in days:
            day = tuple(day)
            self.training_data_.append(day)
            added.append((DAY_START, *day))
            self.frequency_.update(day)
            at_step.update(enumerate(day))
        self.index_.add_all(added)  # compacted: typed arrays, a tenth of the memory
        for (t, a), n in at_step.items():
            while len(self.by_step_) <= t:
                self.by_step_.append(Counter())
            self.by_step_[t][a] += n
        self.classes_ = tuple(sorted(self.frequency_))
        return self

    # -- prediction -------------------------------------------------------------------------
    def _distribution(self, state: int, matched: int, step: int) -> dict[str, float]:
        max_context = self.max_order - 1
        if self.estimator == "longest":
            dist = longest_distribution(self.index_, state, matched, max_context)
        else:
            dist = witten_bell_distribution(self.index_, state, matched, max_context, self.classes_)
        if self.time_weight > 0 and dist:
            dist = self._with_time(dist, step)
        return dist

    def _with_time(self, dist: dict[str, float], step: int) -> dict[str, float]:
        prior = self.step_prior(self.by_step_, step, self.time_window)
        mixed = {a: p * prior.get(a, 1e-9) ** self.time_weight for a, p in dist.items()}
        total = sum(mixed.values())
        return {a: p / total for a, p in mixed.items()} if total > 0 else dict(dist)

    def predict_proba(self, history: Sequence[str]) -> dict[str, float]:
        """Distribution of the next activity after ``history`` (the day so far, from 06:00)."""
        self._check_fitted()
        state, matched = self.index_.match((DAY_START, *history))
        return self._distribution(state, matched, len(history))

    def scan_proba(self, day: Sequence[str]) -> list[dict[str, float]]:
        """``[predict_proba(day[:t]) for t in range(len(day))]`` in one linear pass."""
        self._check_fitted()
        out = []
        for t, (state, matched) in enumerate(self.index_.scan((DAY_START, *day[:-1]) if day else ())):
            out.append(self._distribution(state, matched, t))
        return out
