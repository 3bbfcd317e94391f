"""A forward filter over the current activity when activity labels are missing.

A robot rarely gets an activity label for every step. Feeding its best guess back as if it were
the truth throws away what the model is unsure about, so the filter keeps a distribution over the
day's possible activity *histories* instead:

- **Transition.** Each history is extended by the fitted activity model's own next-step
  distribution given that history: for the routine model its stay hazard (activity, how long it
  has lasted, hour), its n-gram over runs and its time-of-day start prior; for the n-gram model
  its backoff over the whole day; any other model through ``predict_proba``. Time of day enters
  through these distributions.
- **Evidence.** A visible label pins the activity of its step (histories that disagree get
  weight 0). The set of objects seen moving at a step is scored by :class:`MovementEmission`,
  P(moved set | the activities at the step before and at the step), learned by counting on
  training days: smoothed Bernoullis per (activity, object), so "nothing moved" is evidence too.
- **State.** Histories that imply the same future are merged exactly: for the routine model the
  last ``order`` run labels and the current run's start (the hidden state is (activity, how long
  it has lasted, the runs before it)); for the n-gram model the suffix-automaton match. At most
  ``max_hypotheses`` states are kept per step (the most probable; those below ``min_weight`` of
  the total are dropped); with no pruning this is the exact forward algorithm.

With every label visible there is exactly one history, so :func:`filtered_scan` returns exactly
the model's ``scan_proba``. Training is counting only.

The per-step work runs in C (:mod:`globe.models._filter_core`) where the install compiled it, for
the routine, n-gram and persistence models and this module's movement evidence: the same
operations in the same order, so the same weights to the bit, histories and dict orders (tested
side by side). This Python code is the reference, and runs everything else.
"""

from __future__ import annotations

import copy
import math
import weakref
from collections import Counter
from dataclasses import dataclass
from typing import Any, Callable, Collection, Hashable, Protocol, Sequence, cast

from globe.data.records import Day
from globe.errors import ConfigError
from globe.models.activity import DAY_START as NGRAM_DAY_START
from globe.models.activity import ActivityModel
from globe.models.backoff import witten_bell_distribution
from globe.models.base import CountingModel, windowed_prior
from globe.models.baselines import PersistenceModel
from globe.models.routine import DAY_START as RUN_DAY_START
from globe.models.routine import RoutineModel
from globe.sequences.movements import moved_steps

try:  # compiled at install where a C compiler is found (optional): the same filter, faster
    from globe.models import _filter_core as _native
except ImportError:  # pragma: no cover - depends on the install
    _native = None  # type: ignore[assignment]

COMPILED = True
"""Whether filters made from now on take the compiled step where it is built (for their whole
life). Tests and benchmarks set it to False to run the Python implementation, the reference."""

_CORE_STATES = 2_000_000
"""States a compiled core numbers before the next filter over its model starts a fresh one (its
memos are bounded; its state numbers cannot be forgotten while a filter may hold them)."""


class NextActivityModel(Protocol):
    def predict_proba(self, history: Sequence[str]) -> dict[str, float]: ...


_EMPTY: frozenset[str] = frozenset()


def moved_objects(day: Day, objects: Sequence[str]) -> list[frozenset[str]]:
    """Per step, the objects whose location differs from the step before (empty at step 0)."""
    out: list[frozenset[str]] = [_EMPTY] * len(day)
    for t, moved in moved_steps(day, objects):
        out[t] = frozenset(moved)
    return out


class MovementEmission(CountingModel):
    """P(the set of objects seen moving at step s | the activities at steps s-1 and s).

    A movement seen at step s happened during the interval that began at s-1, so it may belong
    to either activity (SLaTe-PRO credits the earlier one). The likelihood is the mixture
    ``previous_share`` * P(moved | a_{s-1}) + (1 - previous_share) * P(moved | a_s), each part a
    table of independent Bernoullis, one per (activity, object), counted on training days with
    that attachment: p(a, o) = (c(a, o) + s * p(o)) / (n(a) + s), shrunk towards the object's
    overall rate p(o) (add-one smoothed) with pseudo-count ``smoothing``, so "nothing moved" is
    evidence too. The log-likelihood is multiplied by ``weight`` (< 1 tempers the independence
    assumption: objects used together move together). Objects unknown to training carry no
    evidence. With ``switch`` (and ``boundary``), the part credited to a_{s-1} at a step where
    the activity changes is also told which activity starts: what is taken out depends on it
    (p(a -> b, o), shrunk towards p(a, o | changed); switches never seen keep the latter).
    """

    _parameter_constraints = {"smoothing": float, "weight": float, "previous_share": float, "boundary": bool,
                              "switch": bool}
    kind = "movement_emission"

    def __init__(self, *, smoothing: float = 1.0, weight: float = 1.0, previous_share: float = 1.0,
                 boundary: bool = False, switch: bool = False) -> None:
        self.smoothing = smoothing
        self.weight = weight
        self.previous_share = previous_share
        self.boundary = boundary
        self.switch = switch

    def _validate_params(self) -> None:
        for name in ("boundary", "switch"):
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(f"MovementEmission: {name}={getattr(self, name)!r}; expected True or False")
        for name in ("smoothing", "weight", "previous_share"):
            value = getattr(self, name)
            if not isinstance(value, (int, float)) or value < 0 or (name == "previous_share" and value > 1):
                raise ConfigError(f"MovementEmission: {name}={value!r}; expected a number >= 0"
                                  + (" and <= 1" if name == "previous_share" else ""))

    def fit(self, days: Sequence[Day], objects: Sequence[str],
            day_moves: Sequence[Sequence[tuple[int, tuple[str, ...]]]] | None = None) -> "MovementEmission":
        """Count from scratch over ``days`` whose object columns are ``objects`` (``day_moves``:
        each day's :func:`~globe.sequences.movements.moved_steps`, when the caller has them)."""
        self._reset()
        return self.partial_fit(days, objects, day_moves)

    def partial_fit(self, days: Sequence[Day], objects: Sequence[str],
                    day_moves: Sequence[Sequence[tuple[int, tuple[str, ...]]]] | None = None) -> "MovementEmission":
        """Add days to the counts (the service learns each day as it ends)."""
        if not hasattr(self, "training_data_"):
            self._validate_params()
            self.training_data_: list[str] = []
            self.objects_ = tuple(objects)
            # keys: (part, activity) and (part, activity, changed); part 0 credits a_{s-1}, 1 credits a_s
            self.steps_: Counter[tuple] = Counter()
            self.moves_: Counter[tuple] = Counter()
            self.transitions_ = 0
            self.overall_: Counter[str] = Counter()
        elif tuple(objects) != self.objects_:
            raise ConfigError("MovementEmission.partial_fit: the object columns differ from the ones it was fitted on")
        # Counted per distinct (a_{s-1}, a_s) pair and (a_{s-1}, a_s, object moved), then spread
        # over the keys below: the same counts as one increment per step and key, a third of the time.
        if day_moves is not None and len(day_moves) != len(days):
            raise ValueError(f"moved steps of {len(day_moves)} days for {len(days)} days")
        all_steps: list[tuple[str, str]] = []  # every (a_{s-1}, a_s), every (a_{s-1}, a_s, object moved) ...
        all_moves: list[tuple[str, str, str]] = []
        all_objects: list[str] = []  # ... and every object moved: counted at once, in this order
        for i, day in enumerate(days):
            self.training_data_.append(day.name)
            acts = day.activities
            all_steps.extend(zip(acts, acts[1:]))
            for t, moved in moved_steps(day, self.objects_) if day_moves is None else day_moves[i]:
                b, a = acts[t - 1], acts[t]
                all_moves.extend((b, a, o) for o in moved)
                all_objects.extend(moved)
        pairs, moved_pairs = Counter(all_steps), Counter(all_moves)
        self.overall_.update(all_objects)
        steps, moves = self.steps_, self.moves_
        # every step counts under both attachments, with and without the change flag; a step
        # where the activity changes also counts under its switch (part 2: a_{s-1} -> a_s)
        for (b, a), n in pairs.items():
            c = b != a
            self.transitions_ += n
            for key in ((0, b), (0, b, c), (1, a), (1, a, c)) + (((2, b, a),) if c else ()):
                steps[key] += n
        for (b, a, o), n in moved_pairs.items():
            c = b != a
            for key in ((0, b), (0, b, c), (1, a), (1, a, c)) + (((2, b, a),) if c else ()):
                moves[(*key, o)] += n
        self.activities_ = tuple(sorted({key[1] for key in self.steps_}))
        self.switches_ = tuple(sorted(key[1:] for key in self.steps_ if key[0] == 2))
        self.rate_ = {o: (self.overall_[o] + 1) / (self.transitions_ + 2) for o in self.objects_}
        self._base: dict[tuple, float] = {}
        self._memo: dict[tuple, float] = {}
        self._evidence: dict[tuple, tuple[float, dict]] = {}
        # the compiled filter's evidence by model dynamics (weakly: it dies with the model), see
        # _compiled_evidence; its logs by context depend on the counts only (shared by with_params)
        self._compiled: weakref.WeakKeyDictionary[Any, tuple] = weakref.WeakKeyDictionary()
        self._contexts: weakref.WeakKeyDictionary[Any, tuple] = weakref.WeakKeyDictionary()
        return self

    def with_params(self, **params: Any) -> "MovementEmission":
        """The same counts with other ``weight``, ``previous_share`` or ``boundary`` (the counts do
        not depend on them): cross-validation counts each fold once for every candidate."""
        self._check_fitted()
        other = copy.copy(self)
        for name, value in params.items():
            if name not in ("weight", "previous_share", "boundary", "switch"):
                raise ConfigError(f"MovementEmission.with_params: {name!r} changes the counts; fit a new one")
            setattr(other, name, value)
        other._validate_params()
        other._base, other._memo, other._evidence = {}, {}, {}
        other._compiled = weakref.WeakKeyDictionary()
        return other

    def evidence(self, activities: Collection[str], moved: frozenset[str]) -> tuple[float, dict]:
        """(:meth:`upper_bound` over ``activities``, a memo of likelihood rows relative to it by
        previous activity) for the set ``moved``: the same sets recur (mostly "nothing moved"),
        across steps and days."""
        key = (tuple(activities), moved)
        out = self._evidence.get(key)
        if out is None:
            if len(self._evidence) >= 20_000:
                self._evidence.clear()
            out = self._evidence[key] = (self.upper_bound(activities, moved), {})
        return out

    def probability(self, activity: str, obj: str, part: int = 0, changed: bool | None = None,
                    following: str | None = None) -> float:
        """p(activity, obj): the chance that ``obj`` moves at a step credited to ``activity``
        (``part`` 0: the activity at s-1, 1: the activity at s); with ``boundary``, also given
        whether the activity changes at s (shrunk towards the rate over both cases); with
        ``switch`` and part 0 at a change, also given the activity that starts (``following``)."""
        key: tuple = (part, activity)
        p = (self.moves_.get((*key, obj), 0) + self.smoothing * self.rate_[obj]) / (self.steps_.get(key, 0) + self.smoothing)
        if self.boundary and changed is not None:
            key = (part, activity, changed)
            p = (self.moves_.get((*key, obj), 0) + self.smoothing * p) / (self.steps_.get(key, 0) + self.smoothing)
            if following is not None and changed and part == 0 and self.switch:
                key = (2, activity, following)
                p = (self.moves_.get((*key, obj), 0) + self.smoothing * p) / (self.steps_.get(key, 0) + self.smoothing)
        return p

    def _nothing(self, part: int, activity: str, changed: bool | None, following: str | None = None) -> float:
        key = (part, activity, changed, following)
        base = self._base.get(key)
        if base is None:
            base = self._base[key] = sum(math.log1p(-self.probability(activity, o, part, changed, following))
                                         for o in self.objects_)
        return base

    def _following(self, part: int, activity: str, changed: bool | None, following: str | None) -> str | None:
        """``following`` where the switch table applies (a switch seen in training), else None."""
        if following is None or part != 0 or not changed or not (self.switch and self.boundary):
            return None
        return following if (2, activity, following) in self.steps_ else None

    def part_log_likelihood(self, part: int, activity: str, moved: frozenset[str], changed: bool | None = None,
                            following: str | None = None) -> float:
        """log P(exactly ``moved`` moved | the activity credited by ``part``), untempered."""
        changed = changed if self.boundary else None
        following = self._following(part, activity, changed, following)
        key = (part, activity, changed, following, moved)
        out = self._memo.get(key)
        if out is None:
            if len(self._memo) >= 500_000:
                self._memo.clear()
            ll = self._nothing(part, activity, changed, following)
            for o in sorted(moved):  # a fixed order: a set's follows the hash seed, and so would the sum
                if o in self.rate_:
                    ll += self._log_odds(part, activity, changed, following, o)
            out = self._memo[key] = ll
        return out

    def _log_odds(self, part: int, activity: str, changed: bool | None, following: str | None, obj: str) -> float:
        """log(p / (1 - p)) for ``obj`` moving in this context: one moved object's term of
        :meth:`part_log_likelihood` (the compiled filter asks it too, for the same floats)."""
        p = self.probability(activity, obj, part, changed, following)
        return math.log(p) - math.log1p(-p)

    def log_likelihood(self, previous: str | None, current: str, moved: frozenset[str]) -> float:
        """``weight`` * log P(exactly ``moved`` moved | a_{s-1} = previous, a_s = current)."""
        self._check_fitted()
        lam = self.previous_share if previous is not None else 0.0
        changed = None if previous is None else previous != current
        parts = []
        if lam > 0.0 and previous is not None:  # lam > 0 only when there is a previous activity
            parts.append(math.log(lam) + self.part_log_likelihood(0, previous, moved, changed, current))
        if lam < 1.0:
            parts.append(math.log1p(-lam) + self.part_log_likelihood(1, current, moved, changed))
        top = max(parts)
        return self.weight * (top + math.log(sum(math.exp(x - top) for x in parts)))

    def upper_bound(self, activities: Collection[str], moved: frozenset[str]) -> float:
        """At least every :meth:`log_likelihood` over ``activities`` (for scaling weights)."""
        acts = set(activities) | set(self.activities_)
        flags: tuple[bool | None, ...] = (None, False, True) if self.boundary else (None,)
        plain = (self.part_log_likelihood(part, a, moved, c) for part in (0, 1) for a in acts for c in flags)
        switches = (self.part_log_likelihood(0, a, moved, True, b) for a, b in self.switches_) if self.switch and self.boundary else ()
        return self.weight * max((*plain, *switches), default=0.0)


# -- dynamics: how each kind of activity model extends a history ---------------------------------

class _Dynamics:
    """Any model with ``predict_proba``: the state is the whole history (nothing merges).

    A *cursor* summarises a history a_0..a_{step-1}; ``key(cursor)`` is equal for histories with
    the same future (merged exactly), and ``distribution(cursor, step)`` is the model's
    P(a_step | the history), memoised by (key, step)."""

    def __init__(self, model: NextActivityModel) -> None:
        # Weakly: the shared registry maps the model to this object, which must not keep it alive.
        try:
            self._model: Callable[[], Any] = weakref.ref(model)
        except TypeError:
            self._model = lambda: model
        self._memo: dict[Hashable, dict[str, float]] = {}
        self._child_keys: dict[Hashable, Hashable] = {}
        self.version = model_version(model)
        self.core: Any = None  # the compiled filter's numbers and memos over these dynamics (_compiled_core)

    @property
    def model(self) -> Any:
        return self._model()

    def start(self) -> Hashable:
        return ()

    def advance(self, cursor: Any, step: int, activity: str) -> Hashable:
        """The cursor of the history ``cursor`` (``step`` activities long) followed by ``activity``."""
        return cursor + (activity,)

    def key(self, cursor: Any) -> Hashable:
        """Histories with equal keys (and lengths) have the same future (merged exactly)."""
        return cursor

    def _compute(self, cursor: Any, step: int) -> dict[str, float]:
        return self.model.predict_proba(cursor)

    def child_key(self, cursor: Any, key: Hashable, step: int, activity: str) -> Hashable:
        """``key(advance(cursor, step, activity))``, memoised: equal keys have equal futures, so
        the key of a history and the next activity determine the next key."""
        memo_key = (key, step, activity)
        out = self._child_keys.get(memo_key)
        if out is None:
            if len(self._child_keys) >= 200_000:
                self._child_keys.clear()
            out = self._child_keys[memo_key] = self.key(self.advance(cursor, step, activity))
        return out

    def distribution(self, cursor: Any, step: int, key: Hashable = None) -> dict[str, float]:
        """P(a_step | the history ``cursor``); ``key`` is ``key(cursor)`` when the caller has it."""
        key = (self.key(cursor) if key is None else key, step)
        dist = self._memo.get(key)
        if dist is None:
            if len(self._memo) >= 200_000:
                self._memo.clear()
            dist = self._memo[key] = self._compute(cursor, step)
        return dist


class _PersistenceDynamics(_Dynamics):
    """Persistence: the future depends only on the last activity."""

    def start(self) -> Hashable:
        return None

    def advance(self, cursor: Any, step: int, activity: str) -> Hashable:
        return activity

    def _compute(self, cursor: Any, step: int) -> dict[str, float]:
        return self.model.predict_proba(() if cursor is None else (cursor,))


class _RoutineDynamics(_Dynamics):
    """Routine model: the state is the runs so far; the future depends only on the last ``order``
    run labels (with the day-start token) and when the current run began. The cursor also
    carries the match of the runs in the model's run index, so a step costs O(1); the
    distribution is :meth:`RoutineModel._distribution` with its parts (stay probability, run
    n-gram, time-of-day prior) memoised (the same numbers, tested)."""

    def __init__(self, model: RoutineModel) -> None:
        super().__init__(model)
        self._stay: dict[tuple[str, int, int], float] = {}
        self._prior: dict[int, dict[str, float]] = {}

    def start(self) -> Hashable:
        return (), *self.model.runs_.match((RUN_DAY_START,))

    def advance(self, cursor: Any, step: int, activity: str) -> Hashable:
        runs, state, matched = cursor
        if runs and runs[-1][0] == activity:
            return runs[:-1] + ((activity, runs[-1][1], step),), state, matched
        return (runs + ((activity, step, step),), *self.model.runs_.step(state, matched, activity))

    def key(self, cursor: Any) -> Hashable:
        runs: tuple[tuple[str, int, int], ...] = cursor[0]
        order = self.model.order
        tokens = tuple(a for a, _, _ in runs[-order:])
        if len(runs) < order:
            tokens = ((RUN_DAY_START,) + tokens)[-order:]
        return tokens, runs[-1][1] if runs else -1

    def child_key(self, cursor: Any, key: Hashable, step: int, activity: str) -> Hashable:
        """``key(advance(cursor, step, activity))`` from ``key`` alone (tested against it): the
        same key when the current run goes on, else the last ``order`` labels with ``activity``
        appended and the run starting at ``step``."""
        order = self.model.order
        if order < 1:
            return super().child_key(cursor, key, step, activity)
        tokens, start = cast(tuple[tuple[str, ...], int], key)
        if start >= 0 and tokens[-1] == activity:
            return key
        return (tokens + (activity,))[-order:], step

    def _compute(self, cursor: Any, step: int) -> dict[str, float]:
        runs, state, matched = cursor
        if not runs:
            return self.model._distribution([], step)
        current, first, _ = runs[-1]
        stay = self.stay(current, step - first, step)
        nxt, z = self.next_runs(state, matched, current, step)
        # (the compiled filter mixes the two parts the same way: _filter_core.c, routine_dist)
        dist = {b: (1.0 - stay) * p / z for b, p in nxt.items()} if z > 0 else {}
        dist[current] = stay if z > 0 else 1.0
        return dist

    def stay(self, current: str, duration: int, step: int) -> float:
        """P(the run of ``current`` goes on at ``step`` | it has lasted ``duration`` steps), memoised."""
        key = (current, duration, step)
        stay = self._stay.get(key)
        if stay is None:
            stay = self._stay[key] = self.model.stay_probability(current, duration, step)
        return stay

    def next_runs(self, state: int, matched: int, current: str, step: int) -> tuple[dict[str, float], float]:
        """The next run's activity (not ``current``) after the runs matched by ``(state, matched)``:
        the run n-gram times the start prior, unnormalised, and its total. It depends on the last
        ``order`` run labels only, and on ``step`` only through the prior."""
        model = self.model
        nxt = witten_bell_distribution(model.runs_, state, matched, model.order, model.classes_)
        nxt.pop(current, None)
        if model.time_weight > 0:
            prior = self._prior.get(step)
            if prior is None:
                prior = self._prior[step] = windowed_prior(model.starts_, step, model.time_window, model.classes_)
            nxt = {b: p * prior[b] ** model.time_weight for b, p in nxt.items()}
        return nxt, sum(nxt.values())


class _NgramDynamics(_Dynamics):
    """n-gram model: the state is the suffix-automaton match of the day so far."""

    def start(self) -> Hashable:
        return self.model.index_.match((NGRAM_DAY_START,))

    def advance(self, cursor: Any, step: int, activity: str) -> Hashable:
        state, matched = cursor
        return self.model.index_.step(state, matched, activity)

    def _compute(self, cursor: Any, step: int) -> dict[str, float]:
        state, matched = cursor
        return self.model._distribution(state, matched, step)


def model_version(model: Any) -> tuple[int, int]:
    """Changes when the model is fitted again or learns more days (memos over it are then stale)."""
    data = getattr(model, "training_data_", ())
    return id(data), len(data)


_SHARED: "weakref.WeakKeyDictionary[Any, _Dynamics]" = weakref.WeakKeyDictionary()


def dynamics_for(model: NextActivityModel) -> _Dynamics:
    """The dynamics of ``model``, shared by every filter and forecaster over the same fitted
    model (their memos of the model's distributions too); rebuilt when the model learns."""
    try:
        dyn = _SHARED.get(model)
    except TypeError:  # not weakly referenceable: a private one
        dyn = None
    if dyn is not None and dyn.version == model_version(model):
        return dyn
    if isinstance(model, RoutineModel):
        dyn = _RoutineDynamics(model)
    elif isinstance(model, ActivityModel):
        dyn = _NgramDynamics(model)
    elif isinstance(model, PersistenceModel):
        dyn = _PersistenceDynamics(model)
    else:
        dyn = _Dynamics(model)
    try:
        _SHARED[model] = dyn
    except TypeError:
        pass
    return dyn


# -- the compiled step (globe.models._filter_core) -----------------------------------------------

def _compiled_core(dyn: _Dynamics) -> Any:
    """The compiled core over ``dyn`` (made on first use, shared by every filter over it), or None
    where the compiled step is not built or does not know these dynamics (Python runs them)."""
    if _native is None:
        return None
    if dyn.core is not None and dyn.core.size <= _CORE_STATES:
        return dyn.core
    if type(dyn) is _RoutineDynamics and dyn.model.order >= 1:
        # the run n-gram part depends on the step only through the time-of-day prior
        dyn.core = _native.Core(_native.ROUTINE, int(dyn.model.order), _compiled_distribution, _compiled_child,
                                _RoutineDynamics.stay, _compiled_next_runs, not dyn.model.time_weight > 0)
    elif type(dyn) in (_NgramDynamics, _PersistenceDynamics):  # their key is their cursor
        dyn.core = _native.Core(_native.OPAQUE, 0, _compiled_distribution, _compiled_child)
    return dyn.core


def _compiled_emission(emission: Any) -> bool:
    """Whether the compiled step knows ``emission`` (none, or exactly a MovementEmission)."""
    return emission is None or type(emission) is MovementEmission


def _compiled_distribution(dyn: _Dynamics, key: Hashable, step: int, beam: Any, index: int) -> dict[str, float]:
    """What the compiled step asks when its memo misses: ``dyn``'s distribution of ``key`` at
    ``step``; the cursor of the history (``beam``'s ``index``-th) is built only if ``dyn``'s memo misses too."""
    dist = dyn._memo.get((key, step))
    return dist if dist is not None else dyn.distribution(beam.cursor(dyn, index), step, key)


def _compiled_next_runs(dyn: _RoutineDynamics, step: int, beam: Any, index: int) -> tuple[dict[str, float], float]:
    """What the compiled step asks when its memo of :meth:`_RoutineDynamics.next_runs` misses (for
    ``beam``'s ``index``-th history at ``step``; it mixes the result with the stay probability as
    :meth:`_RoutineDynamics._compute` does)."""
    runs, state, matched = beam.cursor(dyn, index)
    return dyn.next_runs(state, matched, runs[-1][0], step)


def _compiled_child(dyn: _Dynamics, key: Hashable, step: int, activity: str) -> Hashable:
    """The compiled step's child key where the key is the cursor (n-gram, persistence)."""
    return dyn.child_key(key, key, step, activity)


def _compiled_evidence(em: MovementEmission, dyn: _Dynamics, core: Any, activities: Sequence[str]) -> Any:
    """``em`` over the model's ``activities`` in the numbers of ``core`` (over ``dyn``), memoised on
    the emission. Its logs by context depend on the counts only, so every
    :meth:`~MovementEmission.with_params` setting shares them (each is asked from Python once per
    model)."""
    memo = em._compiled.get(dyn)
    if memo is not None and memo[0] is core and (memo[1] is activities or memo[1] == activities):
        return memo[2]
    contexts = em._contexts.get(dyn)
    if contexts is None or contexts[0] is not core:
        contexts = em._contexts[dyn] = (core, core.contexts(tuple(em.objects_), MovementEmission._nothing, MovementEmission._log_odds))
    lam = em.previous_share
    upper = tuple(set(activities) | set(em.activities_))  # as upper_bound iterates them
    switches = tuple(em.switches_) if em.switch and em.boundary else ()
    evidence = core.evidence(contexts[1], upper, switches, em.weight, lam, math.log(lam) if lam > 0 else math.nan,
                             math.log1p(-lam) if lam < 1 else math.nan, math.log1p(-0.0), em.boundary, em.switch)
    em._compiled[dyn] = (core, activities, evidence)
    return evidence


# -- the filter ----------------------------------------------------------------------------------

@dataclass(frozen=True, slots=True)
class Hypothesis:
    """One possible history a_0..a_s of the day, with its posterior weight."""

    weight: float
    history: tuple[str, ...]
    cursor: Any


class ActivityFilter:
    """The belief over the day's activities, updated one step at a time (online or offline).

    ``update(step, label, moved)`` takes what was seen at ``step`` (0, 1, ... from the day start):
    the activity label or None, and the objects seen moving since the step before, or None when
    object locations were not observed. ``predictive()`` is then P(a_{step+1} | all seen so far);
    ``posterior()`` is P(a_step | all seen so far). Skipped steps are filled with "nothing seen".
    """

    def __init__(self, model: NextActivityModel, emission: MovementEmission | None = None, *,
                 max_hypotheses: int = 64, min_weight: float = 1e-4) -> None:
        if max_hypotheses < 1:
            raise ConfigError(f"ActivityFilter: max_hypotheses={max_hypotheses}; expected a positive integer")
        if not 0.0 <= min_weight < 1.0:
            raise ConfigError(f"ActivityFilter: min_weight={min_weight}; expected a number in [0, 1)")
        self.model = model
        self.emission = emission
        self.max_hypotheses = max_hypotheses
        self.min_weight = min_weight
        self._dynamics = dynamics_for(model)
        self._compiled = COMPILED
        self._evidence_memo: tuple | None = None  # (emission, activities, core, its compiled evidence)
        self.reset()

    def reset(self) -> None:
        """Start a new day: one empty history (kept by the compiled step where it applies)."""
        self.step = -1
        core = _compiled_core(self._dynamics) if self._compiled and _compiled_emission(self.emission) else None
        self._state: Any = None if core is None else core.root(self._dynamics)
        if self._state is None:
            start = self._dynamics.start()
            self._beam = [Hypothesis(1.0, (), start)]
            self._keys: list[Hashable] = [self._dynamics.key(start)]

    def _next(self, h: Hypothesis, key: Hashable = None) -> dict[str, float]:
        dist = self._dynamics.distribution(h.cursor, len(h.history), key)
        if not dist and h.history:  # a model with nothing to say: the activity stays the same
            return {h.history[-1]: 1.0}
        return dist

    def predictive(self) -> dict[str, float]:
        """P(the activity at the next step | everything seen so far), mixed over the beam."""
        if self._state is not None:
            return self._state.predictive(self._dynamics)
        out: dict[str, float] = {}
        for h, key in zip(self._beam, self._keys):
            for a, p in self._next(h, key).items():
                out[a] = out.get(a, 0.0) + h.weight * p
        total = sum(out.values())
        return {a: p / total for a, p in out.items()} if total > 0 else {}

    def posterior(self) -> dict[str, float]:
        """P(the activity at the last updated step | everything seen so far)."""
        if self._state is not None:
            return self._state.posterior()
        out: dict[str, float] = {}
        for h in self._beam:
            if h.history:
                out[h.history[-1]] = out.get(h.history[-1], 0.0) + h.weight
        return out

    def hypotheses(self) -> list[Hypothesis]:
        """The weighted histories a_0..a_step kept now (most probable first, weights sum to 1)."""
        if self._state is not None:
            return [Hypothesis(w, history, cursor) for w, history, cursor in self._state.hypotheses(self._dynamics)]
        return list(self._beam)

    def update(self, step: int, label: str | None, moved: Collection[str] | None) -> None:
        """Condition on what was seen at ``step`` (see the class doc)."""
        if step <= self.step:
            raise ValueError(f"step {step} is not after the last updated step {self.step}")
        while self.step + 1 < step:
            self._advance(None, None)
        self._advance(label, None if moved is None else frozenset(moved))

    def _advance(self, label: str | None, moved: frozenset[str] | None) -> None:
        if self._state is not None:
            if _compiled_emission(self.emission):
                self._advance_compiled(label, moved)
                return
            self._leave_compiled()
        self.step += 1
        first = self.step == 0
        evidence = self._evidence(moved) if moved is not None and not first else None
        merged: dict[Hashable, list] = {}
        grown: list[tuple[float, Hypothesis, Hashable, str]] = []
        # The evidence is at most 1 (relative to its upper bound), so an extension already below
        # min_weight of the best one so far cannot reach the floor below: it is not scored.
        best, lowest = 0.0, self.min_weight
        bounded = self._bounded()
        next_of, grow = self._next, grown.append
        for h, key in zip(self._beam, self._keys):
            dist = next_of(h, key)
            if label is not None:
                dist = {label: dist.get(label, 0.0)}
            prev = h.history[-1] if h.history else None
            row: dict[str, float]
            if evidence is None:  # every extension keeps its weight (times 1.0, exactly)
                row, prev_bounded, any_bounded = _UNIT, True, True
            else:
                row, prev_bounded, any_bounded = evidence(prev), prev is None or prev in bounded, False
            hw = h.weight
            for a, p in dist.items():
                w = hw * p
                if w < lowest * best and prev_bounded and (any_bounded or a in bounded):
                    continue
                if w > 0.0:
                    w *= row[a]
                if w > 0.0:
                    grow((w, h, key, a))
                    if w > best:
                        best = w
        # Extensions far below the best cannot reach min_weight of the total: skip building them.
        floor = self.min_weight * best
        for w, h, key, a in grown:
            if w >= floor:
                self._add(merged, h, key, a, w)
        if not merged:
            # Nothing kept: the label (or movement) is impossible under the model. The evidence
            # wins over the model: keep the histories' weights and extend them as observed.
            for h, key in zip(self._beam, self._keys):
                dist = self._next(h, key)
                guess = max(dist, key=lambda k: dist[k]) if dist else (h.history[-1] if h.history else None)
                chosen = label if label is not None else guess
                if chosen is not None:
                    self._add(merged, h, key, chosen, h.weight)
        if not merged:
            raise ValueError("the activity model predicts nothing for the first step; is it fitted?")
        # most probable first; ties by the history (all as long, so by the parent's, then the activity)
        kept = sorted(merged.items(), key=lambda kv: (-kv[1][0], kv[1][1].history, kv[1][2]))[: self.max_hypotheses]
        total = sum(m[0] for _, m in kept)
        kept = [km for km in kept if km[1][0] >= self.min_weight * total] or kept[:1]
        total = sum(m[0] for _, m in kept)
        dyn = self._dynamics
        self._beam = [Hypothesis(w / total, h.history + (a,), dyn.advance(h.cursor, len(h.history), a))
                      for _, (w, h, a, _) in kept]
        self._keys = [key for key, _ in kept]

    def _advance_compiled(self, label: str | None, moved: frozenset[str] | None) -> None:
        """:meth:`_advance` in C: the same weights (to the bit), histories and orders."""
        self.step += 1
        evidence = None
        if moved is not None and self.step != 0 and self.emission is not None:
            evidence = self._evidence_of(self.emission)
        self._state = self._state.advance(self._dynamics, self.step, label, evidence, moved, self.min_weight,
                                          self.max_hypotheses, self.emission)

    def _evidence_of(self, em: MovementEmission) -> Any:
        """The compiled evidence of ``em`` (:func:`_compiled_evidence`), remembered for this filter's
        next steps."""
        activities = getattr(self.model, "classes_", ())
        memo = self._evidence_memo
        if memo is None or memo[0] is not em or memo[1] is not activities or memo[2] is not self._state.core:
            core = self._state.core
            memo = self._evidence_memo = (em, activities, core, _compiled_evidence(em, self._dynamics, core, activities))
        return memo[3]

    def _leave_compiled(self) -> None:
        """Go on in Python from the compiled state (the emission became one the C step does not know)."""
        self._beam = self.hypotheses()
        self._keys = self._state.keys()
        self._state = None

    def _bounded(self) -> frozenset[str]:
        """Activities whose movement evidence is at most 1 (those its upper bound covers)."""
        em = self.emission
        if not isinstance(em, MovementEmission):
            return frozenset()
        if getattr(self, "_bounded_for", None) is not em:
            self._bounded_set = frozenset(getattr(self.model, "classes_", ())) | frozenset(em.activities_)
            self._bounded_for = em
        return self._bounded_set

    def _add(self, merged: dict[Hashable, list], h: Hypothesis, key: Hashable, a: str, w: float) -> None:
        """Merge the extension of ``h`` (whose state is ``key``) by ``a`` into its next state; the
        most probable member represents it (the first among equals)."""
        child = self._dynamics.child_key(h.cursor, key, len(h.history), a)
        slot = merged.get(child)
        if slot is None:
            merged[child] = [w, h, a, w]
        else:
            slot[0] += w
            if w > slot[3]:
                slot[1], slot[2], slot[3] = h, a, w

    def _evidence(self, moved: frozenset[str]) -> Callable[[str | None], "_EvidenceRow"] | None:
        """For the set ``moved``: a function from the previous activity to its row of likelihoods
        by current activity (relative to an upper bound, so that weights stay in floating-point
        range), filled on first use and shared across steps and days by the emission's memo."""
        em = self.emission
        if em is None:
            return None
        activities = getattr(self.model, "classes_", ())
        if isinstance(em, MovementEmission):
            top, rows = em.evidence(activities, moved)
        else:
            top, rows = em.upper_bound(activities, moved), {}

        def row(prev: str | None) -> _EvidenceRow:
            out = rows.get(prev)
            if out is None:
                out = rows[prev] = _EvidenceRow(em, prev, moved, top)
            return out

        return row


class _UnitRow(dict):
    """The likelihood row when nothing was observed: 1.0 for every activity."""

    def __missing__(self, current: str) -> float:
        return 1.0


_UNIT = _UnitRow()


class _EvidenceRow(dict):
    """exp(log P(moved | prev, current) - top) by ``current``, computed on first lookup."""

    __slots__ = ("emission", "prev", "moved", "top")

    def __init__(self, emission: Any, prev: str | None, moved: frozenset[str], top: float) -> None:
        super().__init__()
        self.emission, self.prev, self.moved, self.top = emission, prev, moved, top

    def __missing__(self, current: str) -> float:
        v = self[current] = math.exp(self.emission.log_likelihood(self.prev, current, self.moved) - self.top)
        return v


def filtered_beliefs(flt: ActivityFilter, day: Day, visible: Sequence[bool], objects: Sequence[str], *,
                     nowcast: bool = False, predictive: bool = True
                     ) -> tuple[list[dict[str, float]] | None, list[dict[str, float]] | None]:
    """Run ``flt`` over ``day`` (from a reset). Returns, for every step t, the predictive
    P(a_t | visible labels of steps < t, movements seen at steps < t) (None without
    ``predictive``: mixing it costs a third of the filter) and, with ``nowcast``, P(a_t | the same
    and the movements seen at step t) (what is known about the activity under way once the
    objects' places at t are seen, before its label would arrive)."""
    if len(visible) != len(day):
        raise ValueError(f"the label mask has {len(visible)} steps; the day {day.name} has {len(day)}")
    flt.reset()
    moved = moved_objects(day, objects)
    ahead: list[dict[str, float]] | None = [] if predictive else None
    now: list[dict[str, float]] | None = [] if nowcast else None
    for t in range(len(day)):
        if ahead is not None:
            ahead.append(flt.predictive())
        if now is not None and not visible[t]:  # the update itself is the nowcast
            flt.update(t, None, moved[t])
            now.append(flt.posterior())
            continue
        if now is not None:
            peek = copy.copy(flt)
            peek.update(t, None, moved[t])
            now.append(peek.posterior())
        flt.update(t, day.activities[t] if visible[t] else None, moved[t])
    return ahead, now


def filtered_scan(model: NextActivityModel, emission: MovementEmission | None, day: Day, visible: Sequence[bool],
                  objects: Sequence[str], *, max_hypotheses: int = 64, min_weight: float = 1e-4) -> list[dict[str, float]]:
    """For every step t of ``day``: P(a_t | the visible labels and the movements seen at steps
    0..t-1). With every label visible this is exactly ``model.scan_proba(day.activities)``."""
    flt = ActivityFilter(model, emission, max_hypotheses=max_hypotheses, min_weight=min_weight)
    predictive, _ = filtered_beliefs(flt, day, visible, objects)
    assert predictive is not None
    return predictive


def label_mask(n: int, fraction: float, seed: Sequence[int]) -> list[bool]:
    """Which of ``n`` steps show their label: ``round(fraction * n)`` of them, drawn with ``seed``.
    Masks of one seed are nested (a larger fraction shows a superset), so fractions compare fairly."""
    import numpy as np

    order = np.random.default_rng(list(seed)).permutation(n)
    k = round(fraction * n)
    out = [False] * n
    for i in order[:k]:
        out[int(i)] = True
    return out

