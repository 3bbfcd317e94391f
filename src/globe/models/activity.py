"""Next-activity model: an n-gram Markov model over the day's activity sequence."""

from __future__ import annotations

from collections import Counter
from typing import Sequence

from globe.models.backoff import (
    ESTIMATORS,
    longest_distribution,
    witten_bell_distribution,
)
from globe.models.base import ActivityModelBase, Weekdays
from globe.models.state_space import NumberedStates
from globe.models.suffix_index import SuffixIndex

DAY_START = "<day>"


class ActivityModel(ActivityModelBase):
    """P(a_t | a_0 .. a_{t-1}) with a day-start token and backoff (maximum n = ``max_order``;
    None: the longest training day, whatever the step: 109 on HOMER+'s days, the paper's n).

    ``estimator="longest"`` (default) is the paper's rule: the longest context seen in training
    decides. ``"witten_bell"`` interpolates all context lengths. ``time_weight`` > 0 multiplies
    in a time-of-day expert P(a | step)^w, which knows that breakfast happens in the morning.
    """

    _parameter_constraints = {"estimator": ESTIMATORS, "max_order": int, "time_weight": float, "time_window": int}
    _prediction_params = frozenset(_parameter_constraints)  # the automaton holds every order
    _optional_params = frozenset({"max_order"})
    kind = "activity"

    def __init__(self, *, estimator: str = "longest", max_order: int | None = None, time_weight: float = 0.0,
                 time_window: int = 2) -> None:
        self.estimator = estimator
        self.max_order = max_order
        self.time_weight = time_weight
        self.time_window = time_window

    # -- training ---------------------------------------------------------------------------
    def partial_fit(self, days: Sequence[Sequence[str]], weekdays: Weekdays = None) -> "ActivityModel":
        """Add observed days to the counts (no retraining of what was seen before)."""
        if not hasattr(self, "training_data_"):
            self._validate_params()
            self.training_data_: list[tuple[str, ...]] = []
            self.index_ = SuffixIndex(never_predicted=[DAY_START])
            self.frequency_: Counter[str] = Counter()
            self.by_step_: list[Counter[str]] = []
            self.longest_day_ = 1
        at_step: Counter[tuple[int, str]] = Counter()  # (step, activity): counted at C speed, then spread
        added = []
        for day in days:
            day = tuple(day)
            self.training_data_.append(day)
            added.append((DAY_START, *day))
            self.frequency_.update(day)
            self.longest_day_ = max(self.longest_day_, len(day))
            at_step.update(enumerate(day))
        self.index_.add_all(added)  # compacted: typed arrays, a tenth of the memory
        for (t, a), n in at_step.items():
            while len(self.by_step_) <= t:
                self.by_step_.append(Counter())
            self.by_step_[t][a] += n
        self.classes_ = tuple(sorted(self.frequency_))
        self._learnt()
        return self

    # -- the hook: the state is the suffix-automaton match of the day so far -------------------
    def root_state(self) -> tuple[int, int]:
        return self.index_.match((DAY_START,))

    def advance(self, state: tuple[int, int], step: int, activity: str) -> tuple[int, int]:
        return self.index_.step(*state, activity)

    def next_distribution(self, state: tuple[int, int], step: int) -> dict[str, float]:
        matched_state, matched = state
        max_context = (self.max_order or self.longest_day_) - 1
        if self.estimator == "longest":
            dist = longest_distribution(self.index_, matched_state, matched, max_context)
        else:
            dist = witten_bell_distribution(self.index_, matched_state, matched, max_context, self.classes_)
        if self.time_weight > 0 and dist:
            dist = self._with_time(dist, step)
        return dist

    def _with_time(self, dist: dict[str, float], step: int) -> dict[str, float]:
        prior = self.step_prior(self.by_step_, step, self.time_window)
        mixed = {a: p * prior.get(a, 1e-9) ** self.time_weight for a, p in dist.items()}
        total = sum(mixed.values())
        return {a: p / total for a, p in mixed.items()} if total > 0 else dict(dist)

    def _build_states(self) -> NumberedStates:
        return NumberedStates(self, self.classes_, self.root_state(), self.advance, self.next_distribution)
