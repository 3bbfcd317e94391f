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

import numpy as np

from globe.models.backoff import witten_bell_distribution
from globe.models.base import ActivityModelBase, Weekdays
from globe.models.state_space import StateSpace, first_met
from globe.models.suffix_index import SuffixIndex
from globe.sequences.runs import run_bounds

DAY_START = "<day>"


def runs_of(day: Sequence[str]) -> list[tuple[str, int, int]]:
    """(activity, first step, last step) of each maximal run."""
    return [(day[first], first, last) for first, last in run_bounds(day)]


class RoutineModel(ActivityModelBase):
    """Semi-Markov activity model with duration and time-of-day awareness (see module doc).

    Its state (:mod:`globe.models.state_space`) is the last ``order`` run labels (with the
    day-start token while there are fewer runs) and the step at which the current run began:
    everything its next step depends on, so the activity filter merges histories with equal
    states exactly."""

    _parameter_constraints = {"order": int, "time_weight": float, "time_window": int,
                              "shrinkage": float, "duration_cap": int, "step_minutes": int}
    _prediction_params = frozenset({"order", "time_weight", "time_window", "shrinkage"})  # counts: durations, hours
    kind = "routine"

    def __init__(self, *, order: int = 3, time_weight: float = 1.0, time_window: int = 3,
                 shrinkage: float = 1.0, duration_cap: int = 30, step_minutes: int = 10) -> None:
        self.order = order
        self.time_weight = time_weight
        self.time_window = time_window
        self.shrinkage = shrinkage
        self.duration_cap = duration_cap
        self.step_minutes = step_minutes

    def partial_fit(self, days: Sequence[Sequence[str]], weekdays: Weekdays = None) -> "RoutineModel":
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
        self._learnt()
        return self

    def _keys(self, activity: str, duration: int, step: int) -> tuple[tuple, ...]:
        """The stay-hazard levels of a step, counted by :meth:`partial_fit`."""
        d = min(duration, self.duration_cap)
        return (activity,), (activity, d), (activity, d, step * self.step_minutes // 60)

    def stay_probability(self, activity: str, duration: int, step: int) -> float:
        """P(the activity goes on at ``step`` | it has lasted ``duration`` steps)."""
        p = 0.5
        for i, key in enumerate(self._keys(activity, duration, step)):
            k = 2.0 if i == 0 else self.shrinkage  # the base level shrinks to 1/2 (Laplace)
            p = (self.stayed_[key] + k * p) / (self.seen_[key] + k)
        return p

    def _build_states(self) -> "RoutineStates":
        return RoutineStates(self)


_STEP_BITS = 20  # a state packs (context, run start + 1, step) into one integer, 20 bits each for the steps
_STEP_MASK = (1 << _STEP_BITS) - 1


class RoutineStates(StateSpace):
    """The routine model's states and its next-step rule, the one place it is written.

    A state is the last ``order`` run labels (with the day-start token while there are fewer
    runs; numbered here as *contexts*), the step at which the current run began and the step:
    everything the next step depends on, so the activity filter merges histories with equal
    states exactly. The next step is: stay with P(stay | activity, duration, hour); else the next
    run's activity from the run n-gram (without the current one) times the start prior,
    renormalised. Rows are computed for many states at once from per-context and per-step rows
    and a stay table, each computed once."""

    def __init__(self, model: RoutineModel) -> None:
        super().__init__(model, model.classes_)
        self._model = model
        width = len(self.labels)
        self._contexts: list[tuple[str, ...]] = []
        self._context_ids: dict[tuple[str, ...], int] = {}
        self._current = np.zeros(0, dtype=np.int64)  # per context: the code of its last run (-1: none yet)
        self._child = np.full((0, width), -1, dtype=np.int64)  # per (context, code): the context after a new run
        self._next = np.zeros((0, width))  # per context: the run n-gram of the next run, without the current one
        self._prior = np.zeros((0, width))  # per step: the start prior ** time_weight
        self._stay = np.zeros((width, model.duration_cap + 1, 0))  # (code, duration, hour) -> P(stay)
        total = sum(model.first_.values())
        self._first = np.zeros(width)
        if total:
            self._first[[self.labels.index(a) for a in model.first_]] = [c / total for c in model.first_.values()]
        self.root = self._pack(np.array([self._context((DAY_START,))]), np.array([-1]), np.array([0]))[0]

    # -- packing --------------------------------------------------------------------------------
    @staticmethod
    def _pack(context: np.ndarray, start: np.ndarray, step: np.ndarray) -> np.ndarray:
        return (context << (2 * _STEP_BITS)) | ((start + 1) << _STEP_BITS) | step

    @staticmethod
    def _unpack(states: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return states >> (2 * _STEP_BITS), ((states >> _STEP_BITS) & _STEP_MASK) - 1, states & _STEP_MASK

    def _context(self, tokens: tuple[str, ...]) -> int:
        """The number of a context (its run labels), computing its next-run row on first sight."""
        ctx = self._context_ids.get(tokens)
        if ctx is None:
            model, width = self._model, len(self.labels)
            ctx = self._context_ids[tokens] = len(self._contexts)
            self._contexts.append(tokens)
            current = -1 if tokens[-1] == DAY_START else self.code(tokens[-1])
            width = len(self.labels)
            nxt = witten_bell_distribution(model.runs_, *model.runs_.match(tokens), model.order, model.classes_)
            nxt.pop(tokens[-1], None)
            row = np.zeros((1, width))
            row[0, [self.labels.index(b) for b in nxt]] = list(nxt.values())
            self._current = np.append(self._current, current)
            self._next = np.vstack([self._next, row])
            self._child = np.vstack([self._child, np.full((1, width), -1, dtype=np.int64)])
        return ctx

    def _grow_labels(self) -> None:
        more = len(self.labels) - self._next.shape[1]
        if more > 0:
            self._next = np.hstack([self._next, np.zeros((len(self._next), more))])
            self._child = np.hstack([self._child, np.full((len(self._child), more), -1, dtype=np.int64)])
            self._prior = np.hstack([self._prior, np.zeros((len(self._prior), more))])
            self._first = np.concatenate([self._first, np.zeros(more)])
            self._stay = np.zeros((len(self.labels), self._stay.shape[1], 0))  # recomputed for every code

    # -- the state space ------------------------------------------------------------------------
    def size(self) -> int:
        return len(self._contexts)

    def last(self, states: np.ndarray) -> np.ndarray:
        context, start, _ = self._unpack(states)
        return np.where(start >= 0, self._current[context], -1)

    def children(self, states: np.ndarray, codes: np.ndarray) -> np.ndarray:
        """The same state a step later while the current run goes on; else the context with the new
        run appended (the last ``order`` labels), the run beginning at this step."""
        context, start, step = self._unpack(np.asarray(states, dtype=np.int64))
        codes = np.asarray(codes, dtype=np.int64)
        same = (start >= 0) & (codes == self._current[context])
        new = self._child[context, codes]
        missing = np.flatnonzero(~same & (new < 0))
        if len(missing):
            for c, code in first_met(context[missing], codes[missing], self._child.shape[1]):
                tokens = (*self._contexts[c], self.labels[code])[-self._model.order:]
                self._child[c, code] = self._context(tokens)
            new[missing] = self._child[context[missing], codes[missing]]
        return self._pack(np.where(same, context, new), np.where(same, start, step), step + 1)

    def child(self, state: int, code: int) -> int:
        context, start, step = state >> (2 * _STEP_BITS), ((state >> _STEP_BITS) & _STEP_MASK) - 1, state & _STEP_MASK
        if start >= 0 and code == self._current[context]:
            return (context << (2 * _STEP_BITS)) | ((start + 1) << _STEP_BITS) | (step + 1)
        new = int(self._child[context, code])
        if new < 0:
            tokens = (*self._contexts[context], self.labels[code])[-self._model.order:]
            new = self._child[context, code] = self._context(tokens)
        return (new << (2 * _STEP_BITS)) | ((step + 1) << _STEP_BITS) | (step + 1)

    def rows(self, states: np.ndarray) -> np.ndarray:
        states = np.asarray(states, dtype=np.int64)
        if len(states) > 64:  # many histories share a state (the filter's days, the paths' queries)
            unique, inverse = np.unique(states, return_inverse=True)
            if 2 * len(unique) < len(states):
                return self._rows_of(unique)[inverse.reshape(-1)]
        return self._rows_of(states)

    def _rows_of(self, states: np.ndarray) -> np.ndarray:
        model = self._model
        context, start, step = self._unpack(states)
        out = np.zeros((len(context), len(self.labels)))
        root = start < 0
        out[root] = self._first
        live = np.flatnonzero(~root)
        if not len(live):
            return out
        context, start, step = context[live], start[live], step[live]
        current = self._current[context]
        stay = self._stay_at(current, step - start, step)
        weights = self._next[context]
        if model.time_weight > 0:
            weights = weights * self._prior_at(step)
        total = weights.sum(axis=1)
        moving = total > 0
        rows = np.zeros_like(weights)
        rows[moving] = (1.0 - stay[moving])[:, None] * weights[moving] / total[moving, None]
        rows[np.arange(len(live)), current] = np.where(moving, stay, 1.0)
        out[live] = rows
        return out

    def _stay_at(self, codes: np.ndarray, duration: np.ndarray, step: np.ndarray) -> np.ndarray:
        """P(the run of ``codes`` goes on at ``step`` | it has lasted ``duration`` steps): the stay
        hazard shrunk from (activity) to (activity, duration) to (activity, duration, hour)."""
        model = self._model
        hour = step * model.step_minutes // 60
        if int(hour.max(initial=0)) >= self._stay.shape[2]:
            self._stay = self._stay_table(int(hour.max()) + 1)
        return self._stay[codes, np.minimum(duration, model.duration_cap), hour]

    def _stay_table(self, hours: int) -> np.ndarray:
        model = self._model
        labels, cap, k = list(self.labels), model.duration_cap, model.shrinkage
        seen, stayed = model.seen_, model.stayed_

        def level(keys: list) -> tuple[np.ndarray, np.ndarray]:
            return (np.array([stayed[key] for key in keys], dtype=float),
                    np.array([seen[key] for key in keys], dtype=float))

        up, n = level([(a,) for a in labels])
        p1 = (up + 2.0 * 0.5) / (n + 2.0)  # the base level shrinks to 1/2 (Laplace)
        up, n = level([(a, d) for a in labels for d in range(cap + 1)])
        p2 = (up.reshape(-1, cap + 1) + k * p1[:, None]) / (n.reshape(-1, cap + 1) + k)
        up, n = level([(a, d, h) for a in labels for d in range(cap + 1) for h in range(hours)])
        shape = (len(labels), cap + 1, hours)
        return (up.reshape(shape) + k * p2[:, :, None]) / (n.reshape(shape) + k)

    def _prior_at(self, step: np.ndarray) -> np.ndarray:
        """The start prior ** time_weight at each of ``step``: how often each activity starts
        within ``time_window`` steps of it (add-one smoothed)."""
        model = self._model
        top = int(step.max(initial=0)) + 1
        if top > len(self._prior):
            more = np.zeros((top - len(self._prior), len(self.labels)))
            for i, t in enumerate(range(len(self._prior), top)):
                prior = model.step_prior(model.starts_, t, model.time_window)
                more[i, [self.labels.index(b) for b in prior]] = [p ** model.time_weight for p in prior.values()]
            self._prior = np.vstack([self._prior, more])
        return self._prior[step]
