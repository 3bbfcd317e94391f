"""Movement evidence: how likely the objects seen moving at a step are under each activity.

The activity filter weighs its histories by this likelihood, so what a robot sees move tells it
what the person is doing even when no activity label arrives.
"""

from __future__ import annotations

import copy
from collections import Counter
from typing import Any, Collection, Sequence

import numpy as np

from globe.data.records import Day
from globe.errors import ConfigError
from globe.models.base import CountingModel
from globe.models.vocabulary import Vocabulary
from globe.sequences.movements import moved_steps

DayMoves = Sequence[Sequence[tuple[int, tuple[str, ...]]]]
"""Each day's :func:`~globe.sequences.movements.moved_steps`: (step, the objects that moved there)."""

_MEMO = 20_000  # likelihood matrices kept per emission (the same sets of moved objects recur)


class MovementEmission(CountingModel):
    """P(the set of objects seen moving at step s | the activities at steps s-1 and s).

    A movement seen at step s happened during the interval that began at s-1, so it may belong
    to either activity (SLaTe-PRO credits the earlier one). The likelihood is the mixture
    ``previous_share`` * P(moved | a_{s-1}) + (1 - previous_share) * P(moved | a_s), each part a
    table of independent Bernoullis, one per (activity, object), counted on training days with
    that attachment: p(a, o) = (c(a, o) + s * p(o)) / (n(a) + s), shrunk towards the object's
    overall rate p(o) (add-one smoothed) with pseudo-count ``smoothing``, so "nothing moved" is
    evidence too. With ``boundary`` the rates also depend on whether the activity changes at s
    (shrunk towards the rate over both cases); with ``switch`` (and ``boundary``), the part
    credited to a_{s-1} at a change is also told which activity starts: what is taken out depends
    on it (p(a -> b, o), shrunk towards p(a, o | changed); switches never seen keep the latter).
    The log-likelihood is multiplied by ``weight`` (< 1 tempers the independence assumption:
    objects used together move together). Objects unknown to training carry no evidence.
    """

    _parameter_constraints = {"smoothing": float, "weight": float, "previous_share": float, "boundary": bool,
                              "switch": bool}
    kind = "movement_emission"

    def __init__(self, *, smoothing: float = 1.0, weight: float = 0.5, previous_share: float = 1.0,
                 boundary: bool = True, switch: bool = True) -> None:
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

    # -- counting ----------------------------------------------------------------------------
    def fit(self, days: Sequence[Day], objects: Sequence[str], day_moves: DayMoves | None = None) -> "MovementEmission":
        """Count from scratch over ``days`` whose object columns are ``objects`` (``day_moves``:
        each day's moved steps, when the caller has them)."""
        self._reset()
        return self.partial_fit(days, objects, day_moves)

    def partial_fit(self, days: Sequence[Day], objects: Sequence[str],
                    day_moves: DayMoves | None = None) -> "MovementEmission":
        """Add days to the counts (the service learns each day as it ends)."""
        if not hasattr(self, "training_data_"):
            self._validate_params()
            self.training_data_: list[str] = []
            self.objects_ = tuple(objects)
            # keys (part, activity) and (part, activity, changed); part 0 credits a_{s-1}, part 1
            # a_s, part 2 the switch (a_{s-1}, a_s) at a change
            self.steps_: Counter[tuple] = Counter()
            self.moves_: Counter[tuple] = Counter()
            self.transitions_ = 0
            self.overall_: Counter[str] = Counter()
        elif tuple(objects) != self.objects_:
            raise ConfigError("MovementEmission.partial_fit: the object columns differ from the ones it was fitted on")
        if day_moves is not None and len(day_moves) != len(days):
            raise ValueError(f"moved steps of {len(day_moves)} days for {len(days)} days")
        # Counted per distinct (a_{s-1}, a_s) and (a_{s-1}, a_s, object moved), then spread over the keys.
        all_steps: list[tuple[str, str]] = []
        all_moves: list[tuple[str, str, str]] = []
        all_objects: list[str] = []
        for i, day in enumerate(days):
            self.training_data_.append(day.name)
            acts = day.activities
            all_steps.extend(zip(acts, acts[1:]))
            for t, moved in moved_steps(day, self.objects_) if day_moves is None else day_moves[i]:
                b, a = acts[t - 1], acts[t]
                all_moves.extend((b, a, o) for o in moved)
                all_objects.extend(moved)
        self.overall_.update(all_objects)
        for (b, a), n in Counter(all_steps).items():
            self.transitions_ += n
            for key in _keys(b, a):
                self.steps_[key] += n
        for (b, a, o), n in Counter(all_moves).items():
            for key in _keys(b, a):
                self.moves_[(*key, o)] += n
        self.activities_ = tuple(sorted({key[1] for key in self.steps_}))
        self._tables: dict[tuple, tuple[np.ndarray, ...]] = {}  # by (labels, boundary, switch): counts only
        self._parts: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}  # ... and by the objects moved
        self._matrices: dict[tuple, np.ndarray] = {}
        return self

    def with_params(self, **params: Any) -> "MovementEmission":
        """The same counts with other ``weight``, ``previous_share``, ``boundary`` or ``switch``
        (cross-validation counts each fold once for every candidate)."""
        self._check_fitted()
        other = copy.copy(self)
        for name, value in params.items():
            if name not in ("weight", "previous_share", "boundary", "switch"):
                raise ConfigError(f"MovementEmission.with_params: {name!r} changes the counts; fit a new one")
            setattr(other, name, value)
        other._validate_params()
        other._matrices = {}  # the tables and parts depend on the counts (and the flags) only: shared
        return other

    # -- the likelihood ---------------------------------------------------------------------
    def _rates(self, labels: Vocabulary) -> tuple[np.ndarray, ...]:
        """For the part credited to a_{s-1} ((previous, current) over ``labels``) and to a_s
        ((previous or none, current): the last row is "no previous activity"): the log-likelihood
        of nothing moving, sum over objects of log (1 - p), and each object's log odds,
        log p - log (1 - p), (..., object), added for the objects that did move."""
        key = (labels, self.boundary, self.switch)
        tables = self._tables.get(key)
        if tables is not None:
            return tables
        s, objects, n = self.smoothing, self.objects_, len(labels)
        rate = np.array([(self.overall_[o] + 1) / (self.transitions_ + 2) for o in objects])

        def shrunk(keys: list[tuple], towards: np.ndarray) -> np.ndarray:
            moved = np.array([[self.moves_.get((*k, o), 0) for o in objects] for k in keys], dtype=float)
            steps = np.array([self.steps_.get(k, 0) for k in keys], dtype=float)
            return (moved + s * towards) / (steps[:, None] + s)

        acts = list(labels)
        base = [shrunk([(part, a) for a in acts], rate[None, :]) for part in (0, 1)]  # (A, J)
        p0 = np.broadcast_to(base[0][:, None, :], (n, n, len(objects))).copy()  # (prev, current, J)
        p1 = np.broadcast_to(base[1][None, :, :], (n + 1, n, len(objects))).copy()  # (prev | none, current, J)
        if self.boundary:
            changed = ~np.eye(n, dtype=bool)
            for flag in (False, True):
                mask = changed if flag else ~changed
                by0 = shrunk([(0, a, flag) for a in acts], base[0])
                by1 = shrunk([(1, a, flag) for a in acts], base[1])
                p0[mask] = np.broadcast_to(by0[:, None, :], p0.shape)[mask]
                p1[:n][mask] = np.broadcast_to(by1[None, :, :], (n, n, len(objects)))[mask]
            if self.switch:
                seen = [(i, j) for i, a in enumerate(acts) for j, b in enumerate(acts)
                        if i != j and (2, a, b) in self.steps_]
                if seen:
                    rows, cols = np.array(seen).T
                    p0[rows, cols] = shrunk([(2, acts[i], acts[j]) for i, j in seen], p0[rows, cols])
        tables = tuple(x for p in (p0, p1) for x in (np.log1p(-p).sum(axis=2), np.log(p) - np.log1p(-p)))
        if len(self._tables) > 16:
            self._tables.clear()
        self._tables[key] = tables
        return tables

    def flags(self, moved: Collection[str]) -> np.ndarray:
        """Which of the counted objects are in ``moved`` (others carry no evidence)."""
        return np.array([o in moved for o in self.objects_], dtype=bool)

    def likelihoods(self, labels: Vocabulary, moved: frozenset[str]) -> np.ndarray:
        """((previous activity or none) x current activity): P(exactly the objects ``moved``
        moved | them) ** ``weight``, relative to its largest value (a filter renormalises every
        step, so only ratios matter, and they stay in floating-point range). Rows and columns
        follow the codes of ``labels``; the last row is the first step's (no previous activity).
        Memoised: the same sets recur (mostly "nothing moved")."""
        self._check_fitted()
        key = (labels, moved)
        out = self._matrices.get(key)
        if out is None:
            out = self.log_likelihoods(labels, self.flags(moved))
            top = out.max(initial=-np.inf)
            out = np.exp(out - (top if np.isfinite(top) else 0.0))
            if len(self._matrices) >= _MEMO:
                self._matrices.clear()
            self._matrices[key] = out
        return out

    def log_likelihoods(self, labels: Vocabulary, moved: np.ndarray) -> np.ndarray:
        """``weight`` * log P(exactly the objects flagged in ``moved`` moved | previous, current)
        over ``labels`` (see :meth:`likelihoods`; not relative)."""
        part0, part1 = self._parts_of(labels, np.asarray(moved, dtype=bool))
        n = len(labels)
        lam = float(self.previous_share)
        out = np.empty((n + 1, n))
        out[n] = part1[n]  # no previous activity: all credited to the current one
        if lam <= 0.0:
            out[:n] = part1[:n]
        elif lam >= 1.0:
            out[:n] = part0
        else:
            out[:n] = np.logaddexp(np.log(lam) + part0, np.log1p(-lam) + part1[:n])
        return self.weight * out

    def _parts_of(self, labels: Vocabulary, moved: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """log P(exactly the flagged objects moved) for the part credited to a_{s-1} ((prev,
        current)) and to a_s ((prev | none, current)), untempered: shared by every ``weight`` and
        ``previous_share`` (a search compares them on the same days)."""
        key = (labels, self.boundary, self.switch, moved.tobytes())
        out = self._parts.get(key)
        if out is None:
            nothing0, odds0, nothing1, odds1 = self._rates(labels)
            which = np.flatnonzero(moved)
            out = (nothing0 + odds0[:, :, which].sum(axis=2), nothing1 + odds1[:, :, which].sum(axis=2))
            if len(self._parts) >= _MEMO:
                self._parts.clear()
            self._parts[key] = out
        return out

    def log_likelihood(self, previous: str | None, current: str, moved: Collection[str]) -> float:
        """``weight`` * log P(exactly ``moved`` moved | a_{s-1} = previous, a_s = current): one
        cell of :meth:`log_likelihoods`."""
        self._check_fitted()
        labels = Vocabulary(self.activities_).extended([current] + ([] if previous is None else [previous]))
        table = self.log_likelihoods(labels, self.flags(moved))
        return float(table[len(labels) if previous is None else labels.index(previous), labels.index(current)])


def _keys(previous: str, current: str) -> tuple[tuple, ...]:
    """Every count key a step from ``previous`` to ``current`` adds to (see partial_fit)."""
    changed = previous != current
    keys: tuple[tuple, ...] = ((0, previous), (0, previous, changed), (1, current), (1, current, changed))
    return keys + ((2, previous, current),) if changed else keys
