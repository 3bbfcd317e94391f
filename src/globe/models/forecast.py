"""Predicting ahead: where every tracked object will first be in the next 10-60 minutes.

A robot needs time to fetch, so one-step guesses are not enough, and feeding a guess back as if
it were the truth throws away everything the model is unsure about. The forecaster instead
propagates the whole activity distribution and the objects' movements forward:

- **Activities.** A forward pass over activity *paths* (the activities of the next steps): each
  path is extended by the activity model's own next-step distribution given the day so far plus
  the path (for the routine model that is its semi-Markov stay hazard and run n-gram), paths
  below ``min_path_probability`` are pruned, at most ``max_paths`` are kept, and the beam is
  renormalised. With no pruning this is the exact distribution over paths.
- **Movements** (:class:`MovementModel`). An object leaves its place at step u with hazard
  P(move | activity at u-1, steps into that activity's run, whether that run ends at u-1,
  object, place), estimated by counting with hierarchical shrinkage: object -> (activity,
  object) -> (activity, object, place) -> (activity, run ends, object, place) -> (activity,
  steps into the run, run ends, object, place). Things are put away when an activity ends, so
  the paths run one step past the horizon. ``run_end=False`` drops that distinction (the
  simpler model; cross-validation chooses). ``run_memory=True`` also tells apart objects that
  already moved earlier in the run (what came out during an activity goes back when it ends).
  ``run_next=True`` also tells apart, at a run's last step, which activity starts: a movement
  seen as the next activity begins is credited to the one ending (the interval began in it), but
  what is taken out depends on what comes next (the paths know it); those switch counts per
  (activity ending, activity starting, object, place) are shrunk towards the run-end hazard.
- **Destinations.** Where an object goes when it moves, P(target | activity, object, source),
  shrunk towards P(target | object, source) and P(target | object): learned from where objects
  went in training (nothing in the one-step models predicts *where* an object goes).

For each object the first departure from its current place at step u has probability
h_u * prod_{v<u} (1 - h_v) along a path (its place stays the current one until it departs, so the
hazards are read at that place); summing over paths gives P(first departure at u, to x).
Training is counting only.

The hot loops run in C (:mod:`globe.models._forecast_core`) where the install compiled it: the
hazards, departures and destinations of every level of paths, the first new places, and the
forward pass (for the routine model with its own state numbers and distributions mixed there; for
any other model asking it per new state). The same operations in the same order, so the same
bits, paths and activity numbering (tested side by side on HOMER+ queries); what depends only on
the training places and destinations is shared by the movement models of one set of days (the
settings cross-validation compares). This numpy and Python code is the reference, and the
fallback where the C part is not built.
"""

from __future__ import annotations

import weakref
from collections import Counter, defaultdict
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np

from globe.data.records import Day
from globe.models.activity_filter import _RoutineDynamics, dynamics_for, model_version
from globe.models.base import ActivityModelBase, CountingModel
from globe.models.packed_days import PackedDays
from globe.models.routine import DAY_START as RUN_DAY_START

try:  # compiled at install where a C compiler is found (optional): the same numbers, faster
    from globe.models import _forecast_core as _native
except ImportError:  # pragma: no cover - depends on the install
    _native = None  # type: ignore[assignment]

COMPILED = True
"""Whether forecasts take the compiled path where it is built. Tests and benchmarks set it to False
to run the numpy and Python code, the reference."""


def _compiled() -> bool:
    """Whether forecasts take the compiled path now (:data:`COMPILED`, where it is built)."""
    return COMPILED and _native is not None


UNKNOWN = "<unknown>"


class MovementModel(CountingModel):
    """Per-step movement hazards and destinations of every tracked object (see module doc)."""

    _parameter_constraints = {"hazard_shrinkage": float, "duration_cap": int, "destination_shrinkage": float,
                              "run_end": (True, False), "run_memory": (True, False), "run_next": (True, False)}
    kind = "movement"

    def __init__(self, *, hazard_shrinkage: float = 2.0, duration_cap: int = 8, destination_shrinkage: float = 1.0,
                 run_end: bool = True, run_memory: bool = False, run_next: bool = False) -> None:
        self.hazard_shrinkage = hazard_shrinkage
        self.duration_cap = duration_cap
        self.destination_shrinkage = destination_shrinkage
        self.run_end = run_end
        self.run_memory = run_memory
        self.run_next = run_next

    # -- training ---------------------------------------------------------------------------
    def fit(self, days: Sequence[Day], objects: Sequence[str]) -> "MovementModel":
        """Count, over ``days``, how often each object left its place and where it went."""
        self._reset()
        self._validate_params()
        days = tuple(days)
        packed = self.training_data_ = PackedDays(days)  # counted again when a day is learned; a tenth of the memory
        self.objects_ = tuple(objects)
        # A day's rows repeat until something moves: the packing numbered the distinct ones already.
        steps, row_labels, labels = packed.coded_rows(len(self.objects_))
        step_labels = packed.coded_activities()
        seen_labels = np.unique(step_labels).tolist()
        self.activities_ = tuple(sorted(labels[i] for i in seen_labels)) + (UNKNOWN,)
        places = np.flatnonzero(np.bincount(row_labels.ravel(), minlength=len(labels)))
        self.locations_ = tuple(sorted(labels[i] for i in places.tolist())) + (UNKNOWN,)
        self._act_index = {a: i for i, a in enumerate(self.activities_)}
        self._loc_index = {loc: i for i, loc in enumerate(self.locations_)}
        na, c, nj, nl = len(self.activities_), self.duration_cap, len(self.objects_), len(self.locations_)
        cols = np.arange(nj)
        place_of = np.zeros(len(labels), dtype=int)
        place_of[places] = [self._loc_index[labels[i]] for i in places.tolist()]
        table = place_of[row_labels]
        act_of = np.zeros(len(labels), dtype=int)
        act_of[seen_labels] = [self._act_index[labels[i]] for i in seen_labels]
        e_size, m_size = (2 if self.run_end else 1), (2 if self.run_memory else 1)
        # Every day at once: the steps of all days in order, and the transitions u -> u + 1 inside a day.
        acts_all = act_of[step_labels]
        offsets = np.asarray(packed.offsets)
        dur_all = np.minimum(durations(acts_all, offsets[:-1]), c - 1)
        inside = np.ones(max(len(acts_all) - 1, 0), dtype=bool)
        inside[offsets[1:-1][(offsets[1:-1] > 0) & (offsets[1:-1] < len(acts_all))] - 1] = False
        u = np.flatnonzero(inside)  # the step before each transition
        acts, after, dur = acts_all[u], acts_all[u + 1], dur_all[u]
        rs, rd = steps[u], steps[u + 1]  # each transition's rows of places, before and after
        ends = (after != acts).astype(int) * (e_size - 1)  # things get put away when it ends ...
        cell = ((acts * c + dur) * e_size + ends) * m_size  # (activity, steps into run, run ends, moved earlier = 0)
        # Objects stay put at most transitions and a household has few distinct rows of places,
        # so nothing is expanded to (transitions x objects): what stays is counted once per
        # distinct (cell, row), and only the transitions whose row changes are looked into.
        moving = np.flatnonzero(rs != rd)
        src_m = table[rs[moving]]
        mt, mj = np.nonzero(src_m != table[rd[moving]])  # every move, in transition order
        # Only (object, place) pairs seen in training get cells: objects visit few places.
        used_rows = np.unique(rs)
        self._pairs = np.nonzero(np.bincount((cols[None, :] * nl + table[used_rows]).ravel(), minlength=nj * nl))[0]
        npairs = len(self._pairs)
        self._pair_object = self._pairs // nl
        lookup = np.zeros(nj * nl, dtype=int)
        lookup[self._pairs] = np.arange(npairs)
        size = na * c * e_size * m_size * npairs
        group, per_group = np.unique(cell * len(table) + rs, return_counts=True)
        g_cell, g_row = np.divmod(group, len(table))
        seen_keys = (g_cell[:, None] * npairs + lookup[cols[None, :] * nl + table[g_row]]).ravel()
        seen_counts = np.bincount(seen_keys, weights=np.repeat(per_group, nj), minlength=size)
        move_t, move_pair = moving[mt], lookup[mj * nl + src_m[mt, mj]]
        move_cell = cell[move_t]
        if self.run_memory:  # ... what came out during it: the cells of objects that moved earlier in the run
            change = np.zeros((len(u), nj), dtype=bool)
            change[move_t, mj] = True
            earlier = moved_in_run(dur, change)
            et, ej = np.nonzero(earlier)
            at_zero = cell[et] * npairs + lookup[ej * nl + table[rs[et], ej]]
            seen_counts -= np.bincount(at_zero, minlength=size)  # counted with moved earlier = 0 above
            seen_counts += np.bincount(at_zero + npairs, minlength=size)
            move_cell = move_cell + earlier[move_t, mj]
        seen = seen_counts.reshape(na, c, e_size, m_size, npairs)
        moved = np.bincount(move_cell * npairs + move_pair, minlength=size).astype(float).reshape(na, c, e_size, m_size, npairs)
        switches = None  # run ends: (activity ending, activity starting), whether moved, (object, place)
        if self.run_next and self.run_end:
            b = np.flatnonzero(after != acts)
            src_b = table[rs[b]]
            switches = np.repeat(acts[b] * na + after[b], nj), (src_b != table[rd[b]]).ravel(), (cols[None, :] * nl + src_b).ravel()
        self._dest = self._count_destinations(acts[moving], src_m, table[rd[moving]])
        self._places_key = (self.objects_, self.locations_, self.activities_, self.destination_shrinkage,
                            self._dest_counted, self._pairs.tobytes())
        self._places: _Places | None = None
        k = self.hazard_shrinkage
        to_object = np.zeros((npairs, nj))
        to_object[np.arange(npairs), self._pair_object] = 1.0
        base = (moved.sum() + 1.0) / (seen.sum() + 2.0)  # Laplace: the rate of any object moving in a step
        p0 = (moved.sum(axis=(0, 1, 2, 3)) @ to_object + k * base) / (seen.sum(axis=(0, 1, 2, 3)) @ to_object + k)  # (J,)
        self._p1 = (moved.sum(axis=(1, 2, 3)) @ to_object + k * p0[None, :]) / (seen.sum(axis=(1, 2, 3)) @ to_object + k)  # (A, J)
        p2 = (moved.sum(axis=(1, 2, 3)) + k * self._p1[:, self._pair_object]) / (seen.sum(axis=(1, 2, 3)) + k)  # (A, P)
        p3 = (moved.sum(axis=(1, 3)) + k * p2[:, None]) / (seen.sum(axis=(1, 3)) + k)  # (A, E, P)
        p4 = (moved.sum(axis=3) + k * p3[:, None]) / (seen.sum(axis=3) + k)  # (A, C, E, P)
        self.hazard_ = (moved + k * p4[:, :, :, None]) / (seen + k)  # (A, C, E, M, P); E, M of size 1 if pooled
        self._fit_switches(switches, lookup, npairs)
        self._dest_memo: dict[tuple[int, int, int], tuple[np.ndarray, np.ndarray]] = {}
        return self

    def _count_destinations(self, acts: np.ndarray, src: np.ndarray, dst: np.ndarray) -> dict[tuple, Counter[int]]:
        """Where objects went: (activity, object, source) / (object, source) / (object,) -> target
        counts, from each transition's activity and places (transitions x objects). Each distinct
        move is counted once, then added in the order moves were first seen (the counters' order
        is the one of one increment per move, so sums over them are too)."""
        nj, nl = len(self.objects_), len(self.locations_)
        t, j = np.nonzero(src != dst)
        codes = ((acts[t] * nj + j) * nl + src[t, j]) * nl + dst[t, j]
        dest: dict[tuple, Counter[int]] = defaultdict(Counter)
        distinct, first, counts = np.unique(codes, return_index=True, return_counts=True)
        order = np.argsort(first, kind="stable")
        distinct, counts = distinct[order], counts[order]
        self._dest_counted = distinct.tobytes() + counts.tobytes()  # what the counters hold, in their order
        rest, x = np.divmod(distinct, nl)
        rest, source = np.divmod(rest, nl)
        a, j = np.divmod(rest, nj)
        for a_, j_, s_, x_, n in zip(a.tolist(), j.tolist(), source.tolist(), x.tolist(), counts.tolist()):
            dest[(a_, j_, s_)][x_] += n
            dest[(j_, s_)][x_] += n
            dest[(j_,)][x_] += n
        return dest

    def _fit_switches(self, switches: tuple[np.ndarray, np.ndarray, np.ndarray] | None, lookup: np.ndarray, npairs: int) -> None:
        """With ``run_next``: counts of moves at the last step of a run per (activity ending,
        activity starting, object, place): what is taken out for the next activity depends on
        which one it is. ``switch_index_`` maps a switch code a * A + b to its row (-1: never seen)."""
        na = len(self.activities_)
        self.switch_index_ = np.full(na * na if switches is not None else 0, -1, dtype=int)
        self.switch_seen_: np.ndarray = np.zeros((0, npairs))
        self.switch_moved_: np.ndarray = np.zeros((0, npairs))
        if switches is None:
            return
        codes, changes, pairs = switches
        used = np.unique(codes)
        self.switch_index_[used] = np.arange(len(used))
        keys = self.switch_index_[codes] * npairs + lookup[pairs]
        size = len(used) * npairs
        self.switch_seen_ = np.bincount(keys, minlength=size).astype(float).reshape(len(used), npairs)
        self.switch_moved_ = np.bincount(keys, weights=changes.astype(float),
                                         minlength=size).reshape(len(used), npairs)

    def switch_hazards(self, ending: np.ndarray, starting: np.ndarray, pairs: np.ndarray, at_end: np.ndarray) -> np.ndarray:
        """``at_end`` (the run-end hazards of (object, place) cells ``pairs``, rows of ``ending``
        activity indices) shrunk towards the counts of the switch to ``starting`` (unchanged
        where that switch was never seen, or without ``run_next``)."""
        if not len(self.switch_index_):
            return at_end
        rows = self.switch_index_[ending * len(self.activities_) + starting]
        k = self.hazard_shrinkage
        known = rows >= 0
        r = np.where(known, rows, 0)[:, None]
        mixed = (self.switch_moved_[r, pairs] + k * at_end) / (self.switch_seen_[r, pairs] + k)
        return np.where(known[:, None], mixed, at_end)

    def shared_places(self) -> "_Places":
        """The memos of what depends on the training places and destinations only, not on the
        hazards (destination rows, targets, each row of places' cells): shared by every movement
        model fitted on the same days and objects, whatever its setting (equal counts, equal values)."""
        self._check_fitted()
        if self._places is None:
            places = _SHARED_PLACES.get(self._places_key)
            if places is None:
                places = _SHARED_PLACES[self._places_key] = _Places()
            self._places = places
        return self._places

    # -- lookups ----------------------------------------------------------------------------
    def activity_index(self, activity: str) -> int:
        return self._act_index.get(activity, len(self.activities_) - 1)

    def location_index(self, location: str) -> int:
        return self._loc_index.get(location, len(self.locations_) - 1)

    def hazards(self, activity: str, duration: int, sources: np.ndarray, ends: bool = False,
                moved: np.ndarray | None = None, next_activity: str | None = None) -> np.ndarray:
        """P(each object leaves its place ``sources`` (location indices) in the step after one of
        ``activity``, ``duration`` steps into its run, that is its run's last (``ends``) or not,
        given whether each object already moved earlier in this run (``moved``, default none))
        and, at a run's end with ``run_next``, which activity starts (``next_activity``)."""
        self._check_fitted()
        a, d = self.activity_index(activity), min(duration, self.duration_cap - 1)
        e = int(ends) if self.hazard_.shape[2] == 2 else 0
        nj = len(self.objects_)
        m = np.zeros(nj, dtype=int) if moved is None or self.hazard_.shape[3] == 1 else np.asarray(moved, dtype=int)
        codes = np.arange(nj) * len(self.locations_) + np.asarray(sources)
        idx = np.minimum(np.searchsorted(self._pairs, codes), max(len(self._pairs) - 1, 0))
        if not len(self._pairs):
            return self._p1[a].copy()
        found = self._pairs[idx] == codes  # an object never seen at this place: P(move | activity, object)
        h = self.hazard_[a, d, e, m, idx]
        if e and next_activity is not None:
            h = self.switch_hazards(np.array([a]), np.array([self.activity_index(next_activity)]), idx[None, :], h[None, :])[0]
        return np.where(found, h, self._p1[a])

    def destination(self, activity: str, obj: int, source: int) -> tuple[np.ndarray, np.ndarray]:
        """(location indices, probabilities) of where object ``obj`` goes from ``source`` when it
        moves during ``activity``; empty when the object was never seen moving."""
        self._check_fitted()
        a = self.activity_index(activity)
        key = (a, obj, source)
        if key not in self._dest_memo:
            self._dest_memo[key] = self._destination(a, obj, source)
        return self._dest_memo[key]

    def _destination(self, a: int, j: int, s: int) -> tuple[np.ndarray, np.ndarray]:
        k = self.destination_shrinkage
        prob: dict[int, float] = {}
        for counts in (self._dest.get((j,)), self._dest.get((j, s)), self._dest.get((a, j, s))):
            if not counts:
                continue
            total = sum(counts.values())
            weight = k if prob else 0.0
            prob = {x: (counts.get(x, 0) + weight * prob.get(x, 0.0)) / (total + weight) for x in set(prob) | set(counts)}
        prob.pop(s, None)  # an object cannot move to where it already is
        z = sum(prob.values())
        if z <= 0:
            return np.zeros(0, dtype=int), np.zeros(0)
        idx = np.array(sorted(prob), dtype=int)
        return idx, np.array([prob[i] / z for i in idx])

    def destination_matrix(self, activity: str, sources: np.ndarray) -> np.ndarray:
        """(objects x locations): each object's destination distribution from its place."""
        out = np.zeros((len(self.objects_), len(self.locations_)))
        for j, s in enumerate(sources):
            idx, p = self.destination(activity, j, int(s))
            out[j, idx] = p
        return out


def moved_in_run(dur: np.ndarray, change: np.ndarray) -> np.ndarray:
    """(T-1, J): whether each object already moved earlier in the run of the activity at u-1,
    for the movement step u = 1..T-1 (``change[u-1]``: it moved at u; ``dur``: steps into runs)."""
    counts = change.astype(int)
    before = np.cumsum(counts, axis=0) - counts  # moves in rows 0..i-1
    rows = np.arange(len(change))
    start = rows - dur[: len(change)]  # first row of the run of the activity at row i
    return ((before - before[start]) > 0).astype(int)


def durations(activities: Sequence[Any], day_starts: Sequence[int] | np.ndarray = ()) -> np.ndarray:
    """Steps since the current run began, at every step (0 on a run's first step); a run also
    begins at every index of ``day_starts`` (days laid end to end)."""
    acts = np.asarray(activities)
    steps = np.arange(len(acts))
    starts = np.ones(len(acts), dtype=bool)
    starts[1:] = acts[1:] != acts[:-1]
    begin = np.asarray(day_starts, dtype=int)
    starts[begin[begin < len(acts)]] = True
    return steps - np.maximum.accumulate(np.where(starts, steps, 0))


@dataclass(frozen=True, slots=True)
class Forecast:
    """What the forecaster expects after the last known locations (step ``start`` = m).

    ``activity[k]``: the distribution of the activity at step m + k (k = 0..horizon).
    ``departure[k, j]``: P(object j first leaves its place at step m + 1 + k).
    ``destination[k, j, x]``: the same, and it goes to location x (row sums may fall short of
    ``departure`` when an object was never seen moving, so where it goes is unknown).
    """

    start: int
    objects: tuple[str, ...]
    locations: tuple[str, ...]
    activity: tuple[Mapping[str, float], ...]
    departure: np.ndarray
    destination: np.ndarray

    @property
    def horizon(self) -> int:
        return len(self.activity) - 1

    def change_probability(self, s: int) -> np.ndarray:
        """P(each object is somewhere else than now at some step m+1..m+1+s)."""
        return self.departure[: s + 1].sum(axis=0)

    def first_location(self, s: int) -> tuple[list[str | None], np.ndarray]:
        """Per object, the most likely first new location within m+1..m+1+s and P(it is that)."""
        joint = self.destination[: s + 1].sum(axis=0)
        best = joint.argmax(axis=1)
        prob = joint[np.arange(len(best)), best]
        return [self.locations[x] if p > 0 else None for x, p in zip(best, prob)], prob

    def useful_probability(self, first: int, last: int) -> np.ndarray:
        """P(each object first leaves its place at a step m+first..m+last (first >= 1))."""
        lo, hi = max(first - 1, 0), min(last, self.horizon + 1)
        return self.departure[lo:hi].sum(axis=0)

    def likely_target(self, first: int, last: int) -> list[str | None]:
        """Per object, where it most likely goes when it first moves in m+first..m+last."""
        joint = self.destination[max(first - 1, 0): min(last, self.horizon + 1)].sum(axis=0)
        best = joint.argmax(axis=1)
        return [self.locations[x] if joint[j, x] > 0 else None for j, x in enumerate(best)]


def _rank_in_group(groups: np.ndarray, order: np.ndarray) -> np.ndarray:
    """Position of each element within its group, in ``order`` (which sorts by group first)."""
    ranked = groups[order]
    pos = np.arange(len(order)) - np.searchsorted(ranked, ranked)
    out = np.empty(len(order), dtype=int)
    out[order] = pos
    return out


def _first_seen(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(the distinct keys in the order they first appear, each element's index into them)."""
    uniq, first, inverse = np.unique(keys, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")
    rank = np.empty(len(uniq), dtype=int)
    rank[order] = np.arange(len(uniq))
    return uniq[order], rank[inverse.reshape(-1)]


@dataclass(frozen=True, slots=True)
class _BeamLevel:
    """The kept paths after one more step, for every query of a batch (grouped by query, in the
    order the forward pass keeps them): probability, last activity (local id), the entry of the
    level before it extends, its rank among its query's paths in lexicographic order, state."""

    query: np.ndarray
    p: np.ndarray
    act: np.ndarray
    parent: np.ndarray
    lex: np.ndarray
    sid: np.ndarray


@dataclass(frozen=True, slots=True)
class TreeLevel:
    """The activities at step m + i of every kept prefix of every query (nodes grouped by query,
    in the order the query's paths, most likely first, first name them). For i >= 1 each node
    also carries what the hazard of the step into it reads: its parent node, the parent's
    activity, how long the parent's run had lasted, whether the parent's run is the one under
    way at m-1 (``first_up``) and whether the run ends (``ends``); ``group`` numbers the
    distinct (query, parent activity) in the order they first appear (``group_query``,
    ``group_act``)."""

    query: np.ndarray
    act: np.ndarray
    weight: np.ndarray
    dur: np.ndarray
    first: np.ndarray
    parent: np.ndarray
    up: np.ndarray
    dur_up: np.ndarray
    first_up: np.ndarray
    ends: np.ndarray
    group: np.ndarray
    group_query: np.ndarray
    group_act: np.ndarray


@dataclass(frozen=True, slots=True)
class TreeBatch:
    """The weighted activity prefixes of several forecasts (levels i = 0..horizon+1); activity
    ids are local to ``names`` (:class:`ActivityPaths`)."""

    size: int
    horizon: int
    levels: tuple[TreeLevel, ...]
    names: tuple[str, ...]

    def activity(self, q: int) -> tuple[dict[str, float], ...]:
        """P(activity at m + k) for k = 0..horizon of query ``q``."""
        out: list[dict[str, float]] = []
        for level in self.levels[: self.horizon + 1]:
            lo, hi = np.searchsorted(level.query, [q, q + 1])
            marg: dict[str, float] = {}
            for a, w in zip(level.act[lo:hi].tolist(), level.weight[lo:hi].tolist()):
                name = self.names[a]
                marg[name] = marg.get(name, 0.0) + w
            out.append(marg)
        return tuple(out)

    def activity_matrix(self) -> np.ndarray:
        """(queries x horizon+1 x names): the same distributions, dense."""
        width = len(self.names)
        out = np.zeros((self.size, self.horizon + 1, width))
        for k, level in enumerate(self.levels[: self.horizon + 1]):
            out[:, k] = np.bincount(level.query * width + level.act, weights=level.weight,
                                    minlength=self.size * width).reshape(self.size, width)
        return out


class ActivityPaths:
    """The forward pass over activity paths of one fitted activity model (see module doc), for
    many histories at once.

    Histories are summarised by the model's own state (:func:`globe.models.activity_filter.dynamics_for`:
    for the routine model the last runs and when the current one began), so each state's
    next-step distribution is computed once; every forecaster over the same model object shares
    one instance (:meth:`shared`), whatever its movement model. The paths of all histories of a
    batch are extended together, step by step, as arrays; the result is exactly the one-history
    forward pass (same order of operations)."""

    _registry: "weakref.WeakKeyDictionary[Any, dict[tuple[float, int], ActivityPaths]]" = weakref.WeakKeyDictionary()

    def __init__(self, model: ActivityModelBase, *, min_path_probability: float = 1e-3, max_paths: int = 64,
                 memo_size: int = 200_000) -> None:
        # Weakly: the shared registry maps the model to this object, which must not keep it alive.
        try:
            self._model: Any = weakref.ref(model)
        except TypeError:
            self._model = lambda: model
        self.min_path_probability = min_path_probability
        self.max_paths = max_paths
        self.memo_size = memo_size
        self.names: dict[str, int] = {}  # activity -> local id (kept across resets)
        self._name_list: list[str] = []
        self._strrank = np.zeros(0, dtype=int)
        self._reset()

    @property
    def model(self) -> ActivityModelBase:
        return self._model()

    @classmethod
    def shared(cls, model: ActivityModelBase, *, min_path_probability: float = 1e-3, max_paths: int = 64,
               memo_size: int = 200_000) -> "ActivityPaths":
        try:
            mine = cls._registry.setdefault(model, {})
        except TypeError:  # not weakly referenceable
            return cls(model, min_path_probability=min_path_probability, max_paths=max_paths, memo_size=memo_size)
        key = (min_path_probability, max_paths)
        if key not in mine:
            mine[key] = cls(model, min_path_probability=min_path_probability, max_paths=max_paths, memo_size=memo_size)
        return mine[key]

    def _reset(self) -> None:
        self._dyn = dynamics_for(self.model)
        self._version = model_version(self.model)
        self._states: list[tuple[Any, int, str | None]] = []  # id -> (cursor, step, last activity)
        self._keys: list[Any] = []  # id -> the dynamics' key of its cursor
        self._ids: dict[tuple, int] = {}
        self._children: dict[tuple[int, int], int] = {}
        self._ext_act = np.zeros((64, 4), dtype=int)  # per state: next activities in the model's order
        self._ext_p = np.zeros((64, 4))
        self._ext_best = np.full(64, -1, dtype=int)
        self._ext_done = np.zeros(64, dtype=bool)
        self._root = self._state(self._dyn.start(), 0, None)
        self._histories: dict[tuple[str, ...], int] = {}
        self._engine: Any = None  # the compiled forward pass, made on first use (:meth:`_compiled_pass`)

    def check(self) -> None:
        """Forget every memo when the model has been fitted again or has learnt more days."""
        if model_version(self.model) != self._version or len(self._states) > self.memo_size:
            self._reset()

    def _compiled_pass(self) -> Any:
        """The compiled forward pass over this model (:class:`globe.models._forecast_core.Paths`),
        or None where it is not built. For the routine model it numbers the states itself (a
        fresh one past ``memo_size`` states); for any other it extends this object's states, asking
        for their distributions and children (:meth:`_child`) as :meth:`_beams` does."""
        if not _compiled():
            return None
        if self._engine is None or (self._routine() and self._engine.size > self.memo_size):
            if self._routine():
                model = self._dyn.model
                self._engine = _native.Paths(_native.ROUTINE, model.order, not model.time_weight > 0, self.names,
                                             self._name_list, RUN_DAY_START)
            else:
                self._engine = _native.Paths(_native.OPAQUE, 0, False, self.names, self._name_list, None)
        return self._engine

    def _routine(self) -> bool:
        """Whether the compiled forward pass numbers this model's states itself (its keys are the
        last ``order`` run labels and the current run's start)."""
        return type(self._dyn) is _RoutineDynamics and 1 <= self._dyn.model.order <= 64

    def _roots(self, engine: Any, histories: Sequence[tuple[str, ...]]) -> np.ndarray:
        """The state after each history (``engine``'s numbers for the routine model, else this object's)."""
        if engine is None or not self._routine():
            return np.array([self.state(h) for h in histories], dtype=int)
        return np.frombuffer(engine.roots(histories), dtype=np.int64)

    def _forward(self, engine: Any, roots: np.ndarray, steps: int) -> list[_BeamLevel]:
        """:meth:`_beams`, in C where ``engine`` is not None. The routine model's distributions are
        mixed there from its stay probabilities and next-run distributions (asked from the
        dynamics once each; a next run depends on the last ``order`` run labels only, so it is
        matched from them), exactly as :meth:`_RoutineDynamics._compute` mixes them; any other
        model's are asked per new state, as :meth:`_ensure` asks them."""
        if engine is None:
            return self._beams(roots, steps)
        dyn = self._dyn
        if isinstance(dyn, _RoutineDynamics) and self._routine():
            runs = dyn.model.runs_

            def next_runs(labels: tuple[str, ...], current: str, step: int) -> tuple[dict[str, float], float]:
                state, matched = runs.match(labels)
                return dyn.next_runs(state, matched, current, step)

            def first(step: int) -> dict[str, float]:
                return dyn.distribution(dyn.start(), step)

            levels = engine.beams(roots, steps, self.min_path_probability, self.max_paths, dyn.stay, next_runs, first)
        else:
            def distribution(sid: int) -> tuple[dict[str, float], str | None]:
                cursor, step, last = self._states[sid]
                return dyn.distribution(cursor, step, self._keys[sid]), last

            levels = engine.beams(roots, steps, self.min_path_probability, self.max_paths, distribution, self._child, None)
        return [_BeamLevel(*(np.frombuffer(x, dtype=np.float64 if i == 1 else np.int64) for i, x in enumerate(level)))
                for level in levels]

    def local(self, activity: str) -> int:
        i = self.names.get(activity)
        if i is None:
            i = self.names[activity] = len(self._name_list)
            self._name_list.append(activity)
        return i

    def _ranks(self) -> np.ndarray:
        """Rank of every local id's name in sorted order (paths tie-break lexicographically)."""
        if len(self._strrank) != len(self._name_list):
            order = sorted(range(len(self._name_list)), key=lambda i: self._name_list[i])
            self._strrank = np.empty(len(order), dtype=int)
            self._strrank[order] = np.arange(len(order))
        return self._strrank

    def _state(self, cursor: Any, step: int, last: str | None, key: Any = None) -> int:
        full = (self._dyn.key(cursor) if key is None else key, step, last)
        sid = self._ids.get(full)
        if sid is None:
            sid = self._ids[full] = len(self._states)
            self._states.append((cursor, step, last))
            self._keys.append(full[0])
        return sid

    def _child(self, sid: int, act: int) -> int:
        """The state after ``sid`` and activity ``act``: its key comes from the parent's key
        (:meth:`~globe.models.activity_filter._Dynamics.child_key`), so the cursor is advanced
        only for a state not seen before."""
        out = self._children.get((sid, act))
        if out is None:
            cursor, step, _ = self._states[sid]
            name = self._name_list[act]
            key = self._dyn.child_key(cursor, self._keys[sid], step, name)
            out = self._ids.get((key, step + 1, name))
            if out is None:
                out = self._state(self._dyn.advance(cursor, step, name), step + 1, name, key)
            self._children[(sid, act)] = out
        return out

    def state(self, history: tuple[str, ...]) -> int:
        """The state id after ``history`` (memoised per history; a history is usually one
        activity longer than one asked before, so it is walked from there)."""
        known = self._histories
        sid = known.get(history)
        if sid is not None:
            return sid
        start = len(history) - 1
        while start > 0 and history[:start] not in known:
            start -= 1
        sid = known.get(history[:start], self._root) if start > 0 else self._root
        for a in history[max(start, 0):]:
            sid = self._child(sid, self.local(a))
        if len(known) >= self.memo_size:
            known.clear()
        known[history] = sid
        return sid

    def _ensure(self, sids: np.ndarray) -> None:
        """Fill the next-step table of every state in ``sids``: the activities with probability
        > 0 in the model's order (a model with nothing to say keeps the activity) and which of
        them is the most probable (ties: the larger name)."""
        n = len(self._states)
        if len(self._ext_done) < n:
            grow = max(n, 2 * len(self._ext_done)) - len(self._ext_done)
            self._ext_act = np.vstack([self._ext_act, np.zeros((grow, self._ext_act.shape[1]), dtype=int)])
            self._ext_p = np.vstack([self._ext_p, np.zeros((grow, self._ext_p.shape[1]))])
            self._ext_best = np.concatenate([self._ext_best, np.full(grow, -1, dtype=int)])
            self._ext_done = np.concatenate([self._ext_done, np.zeros(grow, dtype=bool)])
        todo = np.unique(sids[~self._ext_done[sids]])
        if not len(todo):
            return
        rows: list[int] = []  # every (state, column, activity, probability) to write, then written at once
        cols: list[int] = []
        act_ids: list[int] = []
        probs: list[float] = []
        best_rows: list[int] = []
        best_cols: list[int] = []
        names = self.names
        for sid in todo.tolist():
            cursor, step, last = self._states[sid]
            dist = self._dyn.distribution(cursor, step, self._keys[sid])
            if not dist:
                dist = {last: 1.0} if last is not None else {}
            positive = [(a, q) for a, q in dist.items() if q > 0]
            acts = [names[a] if a in names else self.local(a) for a, _ in positive]
            rows += [sid] * len(acts)
            cols += range(len(acts))
            act_ids += acts
            probs += [q for _, q in positive]
            top = max(dist.values(), default=0.0)
            if top > 0:  # the most probable (ties: the larger name)
                best = max(a for a, q in dist.items() if q == top)
                best_rows.append(sid)
                best_cols.append(acts.index(names[best]))
        width = self._ext_act.shape[1]
        need = max(cols, default=-1) + 1
        if need > width:
            more = need - width
            self._ext_act = np.hstack([self._ext_act, np.zeros((len(self._ext_act), more), dtype=int)])
            self._ext_p = np.hstack([self._ext_p, np.zeros((len(self._ext_p), more))])
        self._ext_act[rows, cols] = act_ids
        self._ext_p[rows, cols] = probs
        self._ext_best[best_rows] = best_cols
        self._ext_done[todo] = True

    def _beams(self, roots: np.ndarray, steps: int) -> list[_BeamLevel]:
        """The forward pass from every root state at once: level t holds the kept paths of t
        activities (grouped by root, renormalised; a root whose model predicts nothing has none)."""
        nq = len(roots)
        minp, most = self.min_path_probability, self.max_paths
        query, p, sid = np.arange(nq), np.ones(nq), np.asarray(roots, dtype=int)
        lex = np.zeros(nq, dtype=int)
        levels: list[_BeamLevel] = []
        for _ in range(steps):
            self._ensure(sid)
            probs = self._ext_p[sid]
            pq = p[:, None] * probs
            cols = np.arange(probs.shape[1])
            chosen = (probs > 0) & ((pq >= minp) | (cols[None, :] == self._ext_best[sid][:, None]))
            row, col = np.nonzero(chosen)  # the forward pass's order: path by path, the model's order
            cq, cp, ca = query[row], pq[row, col], self._ext_act[sid[row], col]
            keep = cp >= minp
            lacking = ~(np.bincount(cq, weights=keep.astype(float), minlength=nq) > 0)[cq]
            if lacking.any():  # nothing above the floor: the most probable extension (first of ties)
                idx = np.nonzero(lacking)[0]
                order = idx[np.lexsort((idx, -cp[idx], cq[idx]))]
                starts = np.r_[True, cq[order][1:] != cq[order][:-1]]
                keep[order[starts]] = True
            kept = np.nonzero(keep)[0]
            kq = cq[kept]
            over = np.bincount(kq, minlength=nq) > most
            if over.any():  # most probable first, then lexicographically by path
                ranks = self._ranks()
                order = np.lexsort((ranks[ca[kept]], lex[row[kept]], -cp[kept], kq))
                rank = _rank_in_group(kq, order)
                wide = over[kq]
                position = np.where(wide, rank, np.arange(len(kept)))
                final = np.lexsort((position, kq))
                final = final[~(wide & (rank >= most))[final]]
                kept = kept[final]
                kq = cq[kept]
            kp = cp[kept]
            z = np.bincount(kq, weights=kp, minlength=nq)  # summed in the kept order
            kp = kp / z[kq]
            ka, parent = ca[kept], row[kept]
            ranks = self._ranks()
            lex = _rank_in_group(kq, np.lexsort((ranks[ka], lex[parent], kq)))
            pairs = list(zip(sid[parent].tolist(), ka.tolist()))
            known = self._children
            child = np.array([known.get(pa, -1) for pa in pairs], dtype=int)
            for i in np.nonzero(child < 0)[0].tolist():
                child[i] = self._child(*pairs[i])
            levels.append(_BeamLevel(kq, kp, ka, parent, lex, child))
            query, p, sid = kq, kp, child
        return levels

    def paths(self, history: Sequence[str], steps: int) -> list[tuple[float, tuple[str, ...]]]:
        """The next ``steps`` activities after ``history``: (probability, path), most likely first."""
        self.check()
        engine = self._compiled_pass()
        levels = self._forward(engine, self._roots(engine, [tuple(history)]), steps)
        if not levels or not len(levels[-1].p):
            return []
        out = []
        for e in range(len(levels[-1].p)):
            path, i = [], e
            for level in reversed(levels):
                path.append(self._name_list[int(level.act[i])])
                i = int(level.parent[i])
            out.append((float(levels[-1].p[e]), tuple(reversed(path))))
        return sorted(out, key=lambda item: (-item[0], item[1]))

    def trees(self, histories: Sequence[tuple[str, ...]], starts: Sequence[int], horizon: int) -> TreeBatch:
        """The prefix trees of the activities at steps m..m+horizon+1 after each history
        (a_0..a_{n-1} with n = m or m + 1, the same for all), weighted by the final paths."""
        self.check()
        nq = len(histories)
        heads = {len(h) - m for h, m in zip(histories, starts)}
        if len(heads) > 1 or not heads <= {0, 1}:
            raise ValueError("every history of a batch must end at m - 1 or every one at m")
        head = heads.pop() if heads else 0
        engine = self._compiled_pass()
        roots = self._roots(engine, histories)
        prev = np.full(nq, -1, dtype=int)
        dur0 = np.full(nq, -1, dtype=int)
        for q, (h, m) in enumerate(zip(histories, starts)):
            if 1 <= m <= len(h):
                a, d = h[m - 1], 0
                while d < m - 1 and h[m - 2 - d] == a:
                    d += 1
                prev[q], dur0[q] = self.local(a), d
        steps = horizon + 2 - head
        beams = self._forward(engine, roots, steps)
        final = beams[-1] if beams else _BeamLevel(*(np.zeros(0, dtype=int),) * 6)
        order = np.lexsort((final.lex, -final.p, final.query))  # each query's paths, most likely first
        fq, fw = final.query[order], final.p[order]
        dead = np.bincount(fq, minlength=nq) == 0  # the model predicts nothing: one empty path
        anc = [order]
        for t in range(len(beams) - 1, 0, -1):
            anc.append(beams[t].parent[anc[-1]])
        anc.reverse()  # anc[t-1]: the entry of beam level t each sorted final path goes through
        levels: list[TreeLevel] = []
        up_act, up_dur, up_first = prev, dur0, np.ones(nq, dtype=bool)
        up_node_of: np.ndarray | None = None  # entry of the beam level before -> node index
        head_act = np.array([self.local(h[m]) for h, m in zip(histories, starts)] if head else [], dtype=int)
        width = len(self._name_list)
        for i in range(horizon + 2):
            if head and i == 0:
                query = np.arange(nq)
                act = head_act
                weight = np.bincount(fq, weights=fw, minlength=nq)
                weight[dead] = 1.0
                parent = np.arange(nq)
                node_of_entry = None
            else:
                t = i + 1 - head
                if t > len(anc):
                    break
                entries, node_of_path = _first_seen(anc[t - 1])
                query = beams[t - 1].query[entries]
                act = beams[t - 1].act[entries]
                weight = np.bincount(node_of_path, weights=fw, minlength=len(entries))
                node_of_entry = np.full(len(beams[t - 1].p), -1, dtype=int)
                node_of_entry[entries] = np.arange(len(entries))
                if i == 0:
                    parent = query.copy()
                elif up_node_of is None:  # the level before is the known head
                    parent = query.copy()
                else:
                    parent = up_node_of[beams[t - 1].parent[entries]]
            if not len(query):
                break
            up, dur_up, first_up = up_act[parent], up_dur[parent], up_first[parent]
            same = act == up
            dur = np.where(same, dur_up + 1, 0)
            first = first_up & same
            keys = query * (width + 1) + up + 1
            gkeys, group = _first_seen(keys)
            levels.append(TreeLevel(query, act, weight, dur, first, parent, up, dur_up, first_up, ~same, group,
                                    gkeys // (width + 1), gkeys % (width + 1) - 1))
            up_act, up_dur, up_first, up_node_of = act, dur, first, node_of_entry
        return TreeBatch(nq, horizon, tuple(levels), tuple(self._name_list))


class Forecaster:
    """An activity model and a movement model, propagated together (see module doc)."""

    def __init__(self, activity: ActivityModelBase, movements: MovementModel, *, min_path_probability: float = 1e-3,
                 max_paths: int = 64, memo_size: int = 200_000) -> None:
        self.activity = activity
        self.movements = movements
        self.min_path_probability = min_path_probability
        self.max_paths = max_paths
        self.memo_size = memo_size
        self._paths = ActivityPaths.shared(activity, min_path_probability=min_path_probability, max_paths=max_paths,
                                           memo_size=memo_size)
        self._version: tuple = ()
        self._check_version()

    def _models_version(self) -> tuple:
        """Changes when either model learns (an online assistant adds days): memos are then stale."""
        return model_version(self.activity), id(getattr(self.movements, "hazard_", None))

    def _check_version(self) -> None:
        version = self._models_version()
        if version != self._version:
            self._own = _Places()
            self._translate = np.zeros(0, dtype=int)
            self._version = version
        if self._paths.model is not self.activity:  # the activity model was replaced
            self._paths = ActivityPaths.shared(self.activity, min_path_probability=self.min_path_probability,
                                               max_paths=self.max_paths, memo_size=self.memo_size)

    def paths(self, history: Sequence[str], steps: int) -> list[tuple[float, tuple[str, ...]]]:
        """The next ``steps`` activities after ``history``: (probability, path), most likely first,
        probabilities summing to 1 (the forward pass; pruned as configured)."""
        return self._paths.paths(history, steps)

    def _places(self) -> _Places:
        """The memos the path in use reads: this forecaster's own (the reference), or those shared
        with every movement model fitted on the same days (compiled)."""
        return self.movements.shared_places() if _compiled() else self._own

    def _sources(self, row: Sequence[str], places: _Places | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Location indices of ``row``, their (object, place) cells and whether each was seen."""
        key = tuple(row)
        memo = (self._own if places is None else places).sources
        out = memo.get(key)
        if out is None:
            if len(memo) >= 4096:
                memo.clear()
            mv = self.movements
            sources = np.array([mv.location_index(x) for x in row], dtype=int)
            pairs = mv._pairs
            codes = np.arange(len(sources)) * len(mv.locations_) + sources
            idx = np.minimum(np.searchsorted(pairs, codes), max(len(pairs) - 1, 0))
            found = pairs[idx] == codes if len(pairs) else np.zeros(len(sources), dtype=bool)
            out = memo[key] = (sources, idx, found)
        return out

    def _mv_activities(self) -> np.ndarray:
        """Movement-model activity index of every local activity id of the paths."""
        names = self._paths.names
        if len(self._translate) < len(names):
            mv = self.movements
            extra = [mv.activity_index(a) for a in list(names)[len(self._translate):]]
            self._translate = np.concatenate([self._translate, np.array(extra, dtype=int)])
        return self._translate

    def forecast(self, activities: Sequence[str], locations: Sequence[Sequence[str]], horizon: int) -> Forecast:
        """Forecast movements at steps m+1..m+1+horizon, where m = len(locations) - 1 is the last
        step whose locations are known and ``activities`` holds a_0.. (m or m+1 of them: the
        activity at step m may be unknown). Movements at step u belong to the activity at u-1."""
        return self.forecast_many([(activities, locations)], horizon)[0]

    def forecast_many(self, queries: Sequence[tuple[Sequence[str], Sequence[Sequence[str]]]], horizon: int,
                      trees: TreeBatch | None = None) -> "Forecasts":
        """:meth:`forecast` for every (activities, locations) of ``queries`` at once (the same
        numbers, computed level by level over all their activity paths together). Each query's
        activities end at the same offset from its last location step (m - 1 for all or m for
        all). ``trees`` (from :meth:`trees` of the same histories) saves the forward pass when
        several movement models forecast the same histories."""
        self._check_version()
        mv = self.movements
        mv._check_fitted()
        nj = len(mv.objects_)
        nq = len(queries)
        memory = mv.hazard_.shape[3] == 2
        places = self._places()
        starts = np.zeros(nq, dtype=int)
        src = np.zeros((nq, nj), dtype=int)
        cells = np.zeros((nq, nj), dtype=int)
        seen = np.ones((nq, nj), dtype=bool)
        earlier = np.zeros((nq, nj), dtype=bool)
        for q, (activities, locations) in enumerate(queries):
            m, n = len(locations) - 1, len(activities)
            if m < 0 or n not in (m, m + 1):
                raise ValueError(f"need the locations of steps 0..m and the activities of 0..m-1 or 0..m; got "
                                 f"{len(locations)} location rows and {n} activities")
            starts[q] = m
            src[q], cells[q], seen[q] = self._sources(locations[m], places)
            if memory and n:  # objects already moved in the run under way (movements seen up to step m)
                last = activities[n - 1]
                r0 = n - 1  # the first step of the last known activity's run
                while r0 > 0 and activities[r0 - 1] == last:
                    r0 -= 1
                for v in range(r0 + 1, m + 1):
                    if locations[v] != locations[v - 1]:
                        earlier[q] |= np.array([x != y for x, y in zip(locations[v], locations[v - 1])])
        if trees is None:
            trees = self.trees([tuple(a) for a, _ in queries], starts.tolist(), horizon)
        translate = self._mv_activities()
        departure = np.zeros((nq, horizon + 1, nj))
        targets, real, _ = self._target_table(places)
        destination = np.zeros((nq, horizon + 1, nj, targets.shape[1]))
        if _compiled():
            self._propagate_compiled(trees, translate, src, cells, seen, earlier, departure, destination)
        else:
            self._propagate(trees, translate, src, cells, seen, earlier, departure, destination)
        return Forecasts(starts, mv.objects_, mv.locations_, trees, departure, destination, targets, real)

    def _propagate(self, trees: TreeBatch, translate: np.ndarray, src: np.ndarray, cells: np.ndarray, seen: np.ndarray,
                   earlier: np.ndarray, departure: np.ndarray, destination: np.ndarray) -> None:
        """Fill ``departure`` and ``destination`` level by level over the paths of ``trees`` (the
        numpy reference of :meth:`_propagate_compiled`)."""
        mv = self.movements
        hazard = mv.hazard_
        _, nc, ne, nm, npairs = hazard.shape
        memory = nm == 2
        nq, _, nj = departure.shape
        flat = hazard.reshape(-1)
        no_cells, all_seen = npairs == 0, bool(seen.all())
        switching = ne == 2 and len(mv.switch_index_) > 0
        cols = np.arange(nj)
        survive = np.ones((len(trees.levels[0].act) if trees.levels else 0, nj))
        for i, level in enumerate(trees.levels[1:], start=1):
            prev = translate[level.up]
            owner = level.query
            if no_cells:
                h = mv._p1[prev]
            else:
                d = np.minimum(level.dur_up, nc - 1)
                e = level.ends.astype(int) if ne == 2 else 0
                base = ((prev * nc + d) * ne + e) * nm
                if memory:
                    moved = level.first_up[:, None] & earlier[owner]
                    h = flat[(base[:, None] + moved) * npairs + cells[owner]]
                else:
                    h = flat[(base * npairs)[:, None] + cells[owner]]
                if switching:
                    ends = np.nonzero(level.ends)[0]
                    h[ends] = mv.switch_hazards(prev[ends], translate[level.act[ends]], cells[owner[ends]], h[ends])
                if not all_seen:  # an object never seen at its place: P(move | activity, object)
                    h = np.where(seen[owner], h, mv._p1[prev])
            up = survive[level.parent]
            leave = level.weight[:, None] * up * h
            departure[:, i - 1] = np.bincount(((owner * nj)[:, None] + cols).ravel(), weights=leave.ravel(),
                                              minlength=nq * nj).reshape(nq, nj)
            survive = up * (1.0 - h)
            # where they go: the departures summed per (query, activity left), times its destinations
            ngroups = len(level.group_query)
            per = np.bincount(((level.group * nj)[:, None] + cols).ravel(), weights=leave.ravel(),
                              minlength=ngroups * nj).reshape(ngroups, nj)
            contrib = per[:, :, None] * self._destination_rows(translate[level.group_act], src[level.group_query])
            first = np.searchsorted(level.group_query, level.group_query)
            rank = np.arange(ngroups) - first
            for r in range(int(rank.max(initial=-1)) + 1):  # in order, as a running sum would
                mine = rank == r
                destination[level.group_query[mine], i - 1] += contrib[mine]

    def _propagate_compiled(self, trees: TreeBatch, translate: np.ndarray, src: np.ndarray, cells: np.ndarray,
                            seen: np.ndarray, earlier: np.ndarray, departure: np.ndarray, destination: np.ndarray) -> None:
        """:meth:`_propagate` in C (:mod:`globe.models._forecast_core`): the same operations in the
        same order, so the same bits; every destination row the levels read is filled in first."""
        mv = self.movements
        hazard = mv.hazard_
        nq, nsteps, nj = departure.shape
        shape = (*hazard.shape, nj, nq, nsteps)
        model = (hazard.reshape(-1), mv._p1, mv.switch_index_, mv.switch_seen_, mv.switch_moved_, cells, seen, earlier)
        index, values = self._filled_rows(trees, translate, src)
        where = (nq, nsteps, nj, destination.shape[3], len(mv.locations_))
        survive = np.ones((len(trees.levels[0].act) if trees.levels else 0, nj))
        for i, level in enumerate(trees.levels[1:], start=1):
            nodes = (level.query, translate[level.up], level.dur_up, level.ends, level.first_up, translate[level.act],
                     level.parent, level.weight, level.group)
            after = np.empty((len(level.act), nj))
            per = np.zeros((len(level.group_query), nj))
            _native.level(shape, float(mv.hazard_shrinkage), model, nodes, survive, after, per, departure, i - 1)
            _native.destinations(where, per, level.group_query, translate[level.group_act], src, index, values,
                                 destination, i - 1)
            survive = after

    def _filled_rows(self, trees: TreeBatch, translate: np.ndarray, src: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The destination rows' index and values with every (activity, object, place) the levels
        of ``trees`` read filled in."""
        na = len(self.movements.activities_)
        places = self._places()
        wanted = [level.group_query * na + translate[level.group_act] for level in trees.levels[1:]]
        if wanted:
            q, a = np.divmod(np.unique(np.concatenate(wanted)), na)
            self._destination_rows(a, src[q], gather=False, places=places)
        return places.rows.index, places.rows.values

    def trees(self, histories: Sequence[tuple[str, ...]], starts: Sequence[int], horizon: int) -> TreeBatch:
        """The forward pass of :meth:`forecast_many` alone (shareable between movement models)."""
        self._check_version()
        return self._paths.trees(histories, starts, horizon)

    def _target_table(self, places: _Places | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per object, the places it was ever seen going to (ascending; padded): (objects x
        targets) location indices, which are real, and location -> position per object."""
        places = self._own if places is None else places
        if places.targets is None:
            mv = self.movements
            nj, nl = len(mv.objects_), len(mv.locations_)
            seen = [sorted(mv._dest.get((j,), {})) for j in range(nj)]
            width = max([len(x) for x in seen] + [1])
            targets = np.zeros((nj, width), dtype=int)
            real = np.zeros((nj, width), dtype=bool)
            position = np.full((nj, nl), -1, dtype=int)
            for j, xs in enumerate(seen):
                targets[j, : len(xs)] = xs
                real[j, : len(xs)] = True
                position[j, xs] = np.arange(len(xs))
            places.targets = (targets, real, position)
        return places.targets

    def _destination_rows(self, acts: np.ndarray, sources: np.ndarray, gather: bool = True,
                          places: _Places | None = None) -> np.ndarray:
        """(groups x objects x targets): where each object goes from ``sources[g]`` when it
        moves during activity ``acts[g]`` (over the object's targets; memoised per activity,
        object and place; ``gather=False`` only fills the memo)."""
        mv = self.movements
        places = self._own if places is None else places
        nj, nl = sources.shape[1], len(mv.locations_)
        targets, _, position = self._target_table(places)
        codes = (acts[:, None] * nj + np.arange(nj)) * nl + sources
        table = places.rows
        if len(table.index) < len(mv.activities_) * nj * nl:
            table.index = np.full(len(mv.activities_) * nj * nl, -1, dtype=int)
        rows = table.index[codes]
        missing = np.unique(codes[rows < 0])
        if len(missing):
            new = np.zeros((len(missing), targets.shape[1]))
            for r, code in enumerate(missing.tolist()):
                a, rest = divmod(code, nj * nl)
                j, src = divmod(rest, nl)
                idx, p = mv.destination(mv.activities_[a], j, src)
                new[r, position[j, idx]] = p
            table.index[missing] = np.arange(len(table.values), len(table.values) + len(missing))
            table.values = np.concatenate([table.values, new]) if len(table.values) else new
            rows = table.index[codes]
        return table.values[rows] if gather else table.values


@dataclass(slots=True)
class _Rows:
    index: np.ndarray
    values: np.ndarray


@dataclass(slots=True, weakref_slot=True)
class _Places:
    """Memos of a forecaster that do not depend on the hazards: each row of places' location
    indices and cells, each object's targets, the destination rows. A forecaster's own (the
    reference path), or :meth:`MovementModel.shared_places` (the compiled path)."""

    sources: dict[tuple[str, ...], tuple[np.ndarray, np.ndarray, np.ndarray]] = field(default_factory=dict)
    rows: _Rows = field(default_factory=lambda: _Rows(np.zeros(0, dtype=int), np.zeros((0, 0))))
    targets: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None


_SHARED_PLACES: "weakref.WeakValueDictionary[tuple, _Places]" = weakref.WeakValueDictionary()


@dataclass(frozen=True, slots=True)
class Forecasts:
    """Several forecasts at once (:meth:`Forecaster.forecast_many`): ``departure[q]`` is the
    q-th query's :attr:`Forecast.departure`; ``destination[q, k, j, x]`` its
    ``destination[k, j, targets[j, x]]`` over each object's possible targets (``real``: not
    padding; elsewhere the destination is 0)."""

    start: np.ndarray
    objects: tuple[str, ...]
    locations: tuple[str, ...]
    trees: TreeBatch
    departure: np.ndarray
    destination: np.ndarray
    targets: np.ndarray
    real: np.ndarray

    def __len__(self) -> int:
        return len(self.start)

    def __getitem__(self, q: int) -> Forecast:
        compact = self.destination[q]
        full = np.zeros(compact.shape[:2] + (len(self.locations),))
        j, x = np.nonzero(self.real)
        full[:, j, self.targets[j, x]] = compact[:, j, x]
        return Forecast(int(self.start[q]), self.objects, self.locations, self.trees.activity(q),
                        self.departure[q], full)

    def first_locations(self, horizons: int) -> tuple[np.ndarray, np.ndarray]:
        """(queries x horizons x objects): the location index of each object's most likely first
        new place within m+1..m+1+s, and P(it is that) (as :meth:`Forecast.first_location`)."""
        return first_locations(self.destination, self.targets, horizons)


def first_locations(destination: np.ndarray, targets: np.ndarray, horizons: int) -> tuple[np.ndarray, np.ndarray]:
    """:meth:`Forecasts.first_locations` of a (queries x steps x objects x targets) array (in C
    where it is built: the same sums in the same order, the same picks)."""
    if _compiled() and horizons >= 0:
        nq, nsteps, nj, _ = destination.shape
        shape = (nq, min(horizons, nsteps), nj)
        at, p = _native.first_locations(destination.shape, horizons, np.ascontiguousarray(destination, dtype=float),
                                        np.ascontiguousarray(targets, dtype=np.int64))
        return np.frombuffer(at, dtype=np.int64).reshape(shape), np.frombuffer(p).reshape(shape)
    joint = np.cumsum(destination[:, :horizons], axis=1)
    best = joint.argmax(axis=3)
    prob = np.take_along_axis(joint, best[..., None], axis=3)[..., 0]
    return targets[np.arange(targets.shape[0])[None, None, :], best], prob
