"""A semi-Markov routine model of activities: *how long* an activity lasts and *what follows it*.

The paper's n-gram predicts from the longest context seen in training, which on real routines
tends to copy one remembered day. This model factors the next step instead:

    P(a_t = a_{t-1})        = P(stay | activity, duration so far, hour)   (hazard, smoothed)
    P(a_t = b), b != a_{t-1} = (1 - P(stay)) * P(b | previous runs) * P(start b | step)^w / Z

- the *stay* probability is estimated hierarchically: P(stay | a) <- P(stay | a, d) <-
  P(stay | a, d, hour), each level shrunk towards the one below with pseudo-count ``shrinkage``;
- the *next* activity is an interpolated Witten-Bell n-gram over the sequence of runs (each run
  is one activity, however long), of order ``order``, with a day-start token;
- the time-of-day expert is how often each activity *starts* within ``time_window`` steps of
  now, add-one smoothed, raised to ``time_weight``.

Training is counting; ``partial_fit`` adds days; parameters are chosen by cross-validation over
training days (:mod:`globe.evaluation.tuning`).
"""

from __future__ import annotations

from collections import Counter
from typing import Sequence

from globe.models.backoff import witten_bell_distribution
from globe.models.base import ActivityModelBase
from globe.models.suffix_index import SuffixIndex
from globe.sequences.runs import run_bounds

DAY_START = "<day>"


def runs_of(day: Sequence[str]) -> list[tuple[str, int, int]]:
    """(activity, first step, last step) of each maximal run."""
    return [(day[first], first, last) for first, last in run_bounds(day)]


class RoutineModel(ActivityModelBase):
    """Semi-Markov activity model with duration and time-of-day awareness (see module doc)."""

    _parameter_constraints = {"order": int, "time_weight": float, "time_window": int,
                              "shrinkage": float, "duration_cap": int, "hour_steps": int}
    _prediction_params = frozenset({"order", "time_weight", "time_window", "shrinkage"})  # counts: durations, hours
    kind = "routine"

    def __init__(self, *, order: int = 3, time_weight: float = 1.0, time_window: int = 3,
                 shrinkage: float = 1.0, duration_cap: int = 30, hour_steps: int = 6) -> None:
        self.order = order
        self.time_weight = time_weight
        self.time_window = time_window
        self.shrinkage = shrinkage
        self.duration_cap = duration_cap
        self.hour_steps = hour_steps

    def partial_fit(self, days: Sequence[Sequence[str]]) -> "RoutineModel":
        if not hasattr(self, "training_data_"):
            self._validate_params()
            self.training_data_: list[tuple[str, ...]] = []
            self.frequency_: Counter[str] = Counter()
            self.first_: Counter[str] = Counter()
            self.seen_: Counter[tuple] = Counter()  # (a,), (a, d), (a, d, hour) -> steps observed
            self.stayed_: Counter[tuple] = Counter()  # ... of which the activity went on
            self.starts_: list[Counter[str]] = []  # step -> activities starting there
            self.runs_ = SuffixIndex(never_predicted=[DAY_START])
        added = []
        for day in days:
            day = tuple(day)
            self.training_data_.append(day)
            self.frequency_.update(day)
            if day:
                self.first_[day[0]] += 1
            runs = runs_of(day)
            added.append((DAY_START, *(a for a, _, _ in runs)))
            while len(self.starts_) < len(day):
                self.starts_.append(Counter())
            seen: list[tuple] = []  # every step's keys, counted at once below
            stayed: list[tuple] = []
            for a, first, last in runs:
                self.starts_[first][a] += 1
                for t in range(first, min(last + 1, len(day) - 1)):
                    keys = self._keys(a, t - first + 1, t + 1)
                    seen.extend(keys)
                    if t + 1 <= last:
                        stayed.extend(keys)
            self.seen_.update(seen)
            self.stayed_.update(stayed)
        self.runs_.add_all(added)  # compacted: typed arrays, a tenth of the memory, the same answers
        self.classes_ = tuple(sorted(self.frequency_))
        return self

    def _keys(self, activity: str, duration: int, step: int) -> tuple[tuple, ...]:
        """The stay-hazard levels of a step, counted by :meth:`partial_fit`."""
        d = min(duration, self.duration_cap)
        return (activity,), (activity, d), (activity, d, step // self.hour_steps)

    def stay_probability(self, activity: str, duration: int, step: int) -> float:
        """P(the activity goes on at ``step`` | it has lasted ``duration`` steps)."""
        p = 0.5
        for i, key in enumerate(self._keys(activity, duration, step)):
            k = 2.0 if i == 0 else self.shrinkage  # the base level shrinks to 1/2 (Laplace)
            p = (self.stayed_[key] + k * p) / (self.seen_[key] + k)
        return p

    def _distribution(self, runs: list[tuple[str, int, int]], step: int,
                      match: tuple[int, int] | None = None) -> dict[str, float]:
        """The next step's distribution after ``runs`` (``match``: the run automaton's match of
        them, if the caller tracks it)."""
        if not runs:
            total = sum(self.first_.values())
            return {a: c / total for a, c in self.first_.items()} if total else {}
        current, first, _ = runs[-1]
        stay = self.stay_probability(current, step - first, step)
        state, matched = match or self.runs_.match((DAY_START, *(a for a, _, _ in runs)))
        nxt = witten_bell_distribution(self.runs_, state, matched, self.order, self.classes_)
        nxt.pop(current, None)
        if self.time_weight > 0:
            prior = self.step_prior(self.starts_, step, self.time_window)
            nxt = {b: p * prior[b] ** self.time_weight for b, p in nxt.items()}
        z = sum(nxt.values())
        dist = {b: (1.0 - stay) * p / z for b, p in nxt.items()} if z > 0 else {}
        dist[current] = stay if z > 0 else 1.0
        return dist

    def predict_proba(self, history: Sequence[str]) -> dict[str, float]:
        self._check_fitted()
        return self._distribution(runs_of(history), len(history))

    def scan_proba(self, day: Sequence[str]) -> list[dict[str, float]]:
        """``[predict_proba(day[:t]) for t in range(len(day))]``, tracking runs incrementally."""
        self._check_fitted()
        out: list[dict[str, float]] = []
        runs: list[tuple[str, int, int]] = []
        match = self.runs_.match((DAY_START,))
        for t in range(len(day)):
            out.append(self._distribution(runs, t, match))
            if runs and runs[-1][0] == day[t]:
                runs[-1] = (day[t], runs[-1][1], t)
            else:
                runs.append((day[t], t, t))
                match = self.runs_.step(*match, day[t])
        return out
