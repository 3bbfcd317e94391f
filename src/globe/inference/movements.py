"""How objects move: per-step hazards of leaving a place, and where they go.

An object leaves its place at step u with hazard P(move | activity at u-1, steps into that
activity's run, whether that run ends at u-1, object, place), estimated by counting with
hierarchical shrinkage: object -> (activity, object) -> (activity, object, place) -> (activity,
run ends, object, place) -> (activity, steps into the run, run ends, object, place). Things are
put away when an activity ends. ``run_end=False`` drops that distinction (the simpler model;
cross-validation chooses). ``run_memory=True`` also tells apart objects that already moved
earlier in the run (what came out during an activity goes back when it ends). ``run_next=True``
also tells apart, at a run's last step, which activity starts: a movement seen as the next
activity begins is credited to the one ending, but what is taken out depends on what comes next;
those switch counts per (activity ending, activity starting, object, place) are shrunk towards
the run-end hazard. Where an object goes when it moves, P(target | activity, object, source), is
shrunk towards P(target | object, source) and P(target | object). Training is counting only.
"""

from __future__ import annotations

import threading
import weakref
from collections import Counter, defaultdict
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from globe.data.records import Day
from globe.models.base import CountingModel
from globe.sequences.packed_days import PackedDays

UNKNOWN = "<unknown>"


class MovementModel(CountingModel):
    """Per-step movement hazards and destinations of every tracked object (see module doc)."""

    _parameter_constraints = {"hazard_shrinkage": float, "duration_cap": int, "destination_shrinkage": float,
                              "run_end": (True, False), "run_memory": (True, False), "run_next": (True, False)}
    kind = "movement"
    training_data_: PackedDays
    objects_: tuple[str, ...]
    _dest_counted: bytes

    def __init__(self, *, hazard_shrinkage: float = 2.0, duration_cap: int = 8, destination_shrinkage: float = 1.0,
                 run_end: bool = True, run_memory: bool = False, run_next: bool = False) -> None:
        self.hazard_shrinkage = hazard_shrinkage
        self.duration_cap = duration_cap
        self.destination_shrinkage = destination_shrinkage
        self.run_end = run_end
        self.run_memory = run_memory
        self.run_next = run_next

    # -- training ---------------------------------------------------------------------------
    def fit(self, days: Sequence[Day] | PackedDays, objects: Sequence[str]) -> "MovementModel":
        """Count, over ``days`` (or the same days packed), how often each object left its place
        and where it went."""
        self._reset()
        return self.partial_fit(days, objects)

    def partial_fit(self, days: Sequence[Day] | PackedDays, objects: Sequence[str]) -> "MovementModel":
        """Add ``days`` (an online assistant learning as it goes): everything is counted again over
        every day learned, which takes milliseconds (the shrinkage levels are not additive)."""
        if hasattr(self, "training_data_"):
            if tuple(objects) != self.objects_:
                raise ValueError("MovementModel.partial_fit: the object columns differ from the ones it was fitted on")
            days = self.training_data_.extended(days)
        self._validate_params()
        # a tenth of the memory of the parsed days (a packing made with the rest of a fit is reused)
        packed = self.training_data_ = days if isinstance(days, PackedDays) else PackedDays(days)
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
        self.pairs_ = np.nonzero(np.bincount((cols[None, :] * nl + table[used_rows]).ravel(), minlength=nj * nl))[0]
        npairs = len(self.pairs_)
        self._pair_object = self.pairs_ // nl
        lookup = np.zeros(nj * nl, dtype=int)
        lookup[self.pairs_] = np.arange(npairs)
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
        moved = np.bincount(move_cell * npairs + move_pair, minlength=size).astype(float).reshape(seen.shape)
        switches = None  # run ends: (activity ending, activity starting), whether moved, (object, place)
        if self.run_next and self.run_end:
            b = np.flatnonzero(after != acts)
            src_b = table[rs[b]]
            switches = (np.repeat(acts[b] * na + after[b], nj), (src_b != table[rd[b]]).ravel(),
                        (cols[None, :] * nl + src_b).ravel())
        self._count_destinations(acts[moving], src_m, table[rd[moving]])
        self._places_key = (self.objects_, self.locations_, self.activities_, self.destination_shrinkage,
                            self._dest_counted, self.pairs_.tobytes())
        self._places: Places | None = None
        self._codes: tuple[Sequence[str], np.ndarray] | None = None
        k = self.hazard_shrinkage
        to_object = np.zeros((npairs, nj))
        to_object[np.arange(npairs), self._pair_object] = 1.0
        base = (moved.sum() + 1.0) / (seen.sum() + 2.0)  # Laplace: the rate of any object moving in a step
        moved_a, seen_a = moved.sum(axis=(1, 2, 3)), seen.sum(axis=(1, 2, 3))  # (A, P)
        p0 = (moved.sum(axis=(0, 1, 2, 3)) @ to_object + k * base) / (seen.sum(axis=(0, 1, 2, 3)) @ to_object + k)
        self.object_hazard_ = (moved_a @ to_object + k * p0[None, :]) / (seen_a @ to_object + k)  # (A, J)
        p2 = (moved_a + k * self.object_hazard_[:, self._pair_object]) / (seen_a + k)  # (A, P)
        p3 = (moved.sum(axis=(1, 3)) + k * p2[:, None]) / (seen.sum(axis=(1, 3)) + k)  # (A, E, P)
        p4 = (moved.sum(axis=3) + k * p3[:, None]) / (seen.sum(axis=3) + k)  # (A, C, E, P)
        self.hazard_ = (moved + k * p4[:, :, :, None]) / (seen + k)  # (A, C, E, M, P); E, M of size 1 if pooled
        self._fit_switches(switches, lookup, npairs)
        return self

    def _count_destinations(self, acts: np.ndarray, src: np.ndarray, dst: np.ndarray) -> None:
        """Count where objects went, from each transition's activity and places (transitions x
        objects): each distinct move ((activity, object, source, target) code) once with its count,
        in the order moves were first seen. Kept as bytes only (also the shared places' key): the
        counters per (activity, object, source) / (object, source) / (object,) are built from them
        when a destination is asked for."""
        nj, nl = len(self.objects_), len(self.locations_)
        t, j = np.nonzero(src != dst)
        codes = ((acts[t] * nj + j) * nl + src[t, j]) * nl + dst[t, j]
        distinct, first, counts = np.unique(codes, return_index=True, return_counts=True)
        order = np.argsort(first, kind="stable")
        self._dest_counted = distinct[order].astype(np.int64).tobytes() + counts[order].astype(np.int64).tobytes()

    def _moves(self) -> tuple[list[int], list[int], list[int], list[int], list[int]]:
        """(activity, object, source, target, count) of each distinct move counted, in the order first seen."""
        flat = np.frombuffer(self._dest_counted, dtype=np.int64)
        codes, counts = flat[: len(flat) // 2], flat[len(flat) // 2:]
        nj, nl = len(self.objects_), len(self.locations_)
        rest, x = np.divmod(codes, nl)
        rest, source = np.divmod(rest, nl)
        a, j = np.divmod(rest, nj)
        return a.tolist(), j.tolist(), source.tolist(), x.tolist(), counts.tolist()

    @property
    def destinations_(self) -> dict[tuple[int, ...], Counter[int]]:
        """Target counts per (activity, object, source), (object, source) and (object,) key, each
        counter in the order its targets were first seen."""
        self._check_fitted()
        dest: dict[tuple[int, ...], Counter[int]] = defaultdict(Counter)
        for a_, j_, s_, x_, n in zip(*self._moves()):
            dest[(a_, j_, s_)][x_] += n
            dest[(j_, s_)][x_] += n
            dest[(j_,)][x_] += n
        return dict(dest)

    def _fit_switches(self, switches: tuple[np.ndarray, np.ndarray, np.ndarray] | None, lookup: np.ndarray,
                      npairs: int) -> None:
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

    def switch_hazards(self, ending: np.ndarray, starting: np.ndarray, pairs: np.ndarray,
                       at_end: np.ndarray) -> np.ndarray:
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

    def shared_places(self) -> "Places":
        """The memos of what depends on the training places and destinations only, not on the
        hazards (destination rows, targets, each row of places' cells): shared by every movement
        model fitted on the same days and objects, whatever its setting (equal counts, equal values)."""
        self._check_fitted()
        if self._places is None:
            places = _SHARED_PLACES.get(self._places_key)
            if places is None:
                places = _SHARED_PLACES[self._places_key] = Places()
            self._places = places
        return self._places

    # -- lookups ----------------------------------------------------------------------------
    def activity_index(self, activity: str) -> int:
        return self._act_index.get(activity, len(self.activities_) - 1)

    def activity_codes(self, labels: Sequence[str]) -> np.ndarray:
        """This model's activity index of each of ``labels`` (unknown ones share the last)."""
        memo = self._codes
        if memo is None or memo[0] is not labels:
            memo = self._codes = (labels, np.array([self.activity_index(a) for a in labels], dtype=np.int64))
        return memo[1]

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
        idx = np.minimum(np.searchsorted(self.pairs_, codes), max(len(self.pairs_) - 1, 0))
        if not len(self.pairs_):
            return self.object_hazard_[a].copy()
        found = self.pairs_[idx] == codes  # an object never seen at this place: P(move | activity, object)
        h = self.hazard_[a, d, e, m, idx]
        if e and next_activity is not None:
            starting = np.array([self.activity_index(next_activity)])
            h = self.switch_hazards(np.array([a]), starting, idx[None, :], h[None, :])[0]
        return np.where(found, h, self.object_hazard_[a])

    def destination(self, activity: str, obj: int, source: int) -> tuple[np.ndarray, np.ndarray]:
        """(location indices, probabilities) of where object ``obj`` goes from ``source`` when it
        moves during ``activity``; empty when the object was never seen moving."""
        self._check_fitted()
        return self._destinations([(self.activity_index(activity), obj, source)])[0]

    def _destinations(self, keys: Sequence[tuple[int, int, int]]) -> list[tuple[np.ndarray, np.ndarray]]:
        """:meth:`destination` of each (activity index, object, source) key, the moves read once."""
        moves: dict[int, list[tuple[int, int, int, int]]] = defaultdict(list)  # object -> its moves
        for a, j, s, x, n in zip(*self._moves()):
            moves[j].append((a, s, x, n))
        return [self._destination(a, s, moves.get(j, ())) for a, j, s in keys]

    def _destination(self, a: int, s: int, moves: Sequence[tuple[int, int, int, int]]) -> tuple[np.ndarray, np.ndarray]:
        """Where an object goes from ``s`` during activity ``a``, from its ``moves``: its targets'
        counts during ``a`` from ``s``, shrunk towards those from ``s``, shrunk towards all its own
        (each counter in the order its targets were first seen, so its sums are too)."""
        k = self.destination_shrinkage
        by_object: Counter[int] = Counter()
        by_source: Counter[int] = Counter()
        by_activity: Counter[int] = Counter()
        for a_, s_, x_, n in moves:
            by_object[x_] += n
            if s_ == s:
                by_source[x_] += n
                if a_ == a:
                    by_activity[x_] += n
        prob: dict[int, float] = {}
        for counts in (by_object, by_source, by_activity):
            if not counts:
                continue
            total = sum(counts.values())
            weight = k if prob else 0.0
            prob = {x: (counts.get(x, 0) + weight * prob.get(x, 0.0)) / (total + weight)
                    for x in set(prob) | set(counts)}
        prob.pop(s, None)  # an object cannot move to where it already is
        z = sum(prob.values())
        if z <= 0:
            return np.zeros(0, dtype=int), np.zeros(0)
        idx = np.array(sorted(prob), dtype=int)
        return idx, np.array([prob[i] / z for i in idx])


    # -- what a forecast reads, memoised per set of training places ------------------------------
    def sources(self, row: Sequence[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Location indices of a row of places, their (object, place) cells and whether each
        object was ever seen at its place (else its hazard is P(move | activity, object))."""
        memo = self.shared_places().sources
        key = tuple(row)
        out = memo.get(key)
        if out is None:
            if len(memo) >= 4096:
                memo.clear()
            sources = np.array([self.location_index(x) for x in row], dtype=np.int64)
            pairs = self.pairs_
            codes = np.arange(len(sources)) * len(self.locations_) + sources
            idx = np.minimum(np.searchsorted(pairs, codes), max(len(pairs) - 1, 0))
            found = pairs[idx] == codes if len(pairs) else np.zeros(len(sources), dtype=bool)
            out = memo[key] = (sources, idx, found)
        return out

    def target_table(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per object, the places it was ever seen going to (ascending; padded): (objects x
        targets) location indices, which are real, and location -> position per object."""
        places = self.shared_places()
        if places.targets is None:
            nj, nl = len(self.objects_), len(self.locations_)
            _, moved, _, went, _ = self._moves()
            seen: list[list[int]] = [[] for _ in range(nj)]
            for j, x in sorted(set(zip(moved, went))):
                seen[j].append(x)
            width = max([len(x) for x in seen] + [1])
            targets = np.zeros((nj, width), dtype=np.int64)
            real = np.zeros((nj, width), dtype=bool)
            position = np.full((nj, nl), -1, dtype=np.int64)
            for j, xs in enumerate(seen):
                targets[j, : len(xs)] = xs
                real[j, : len(xs)] = True
                position[j, xs] = np.arange(len(xs))
            places.targets = (targets, real, position)
        return places.targets

    def fill_destination_rows(self, translate: np.ndarray, src: np.ndarray,
                              wanted: Sequence[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
        """The memo of destination rows (index by (activity, object, place) code, values) with every
        row filled that ``wanted`` reads: (activity codes of ``translate``, queries of ``src``)."""
        na = len(self.activities_)
        places = self.shared_places()
        with places.lock:  # households fitted on the same days share these rows across threads
            if wanted:
                codes = np.concatenate([query * na + translate[acts] for acts, query in wanted])
                query, act = np.divmod(np.unique(codes), na)
                self.destination_rows(act, src[query], gather=False)
            return places.rows.index, places.rows.values

    def destination_rows(self, acts: np.ndarray, sources: np.ndarray, gather: bool = True) -> np.ndarray:
        """(groups x objects x targets): where each object goes from ``sources[g]`` when it moves
        during activity ``acts[g]`` (over the object's targets of :meth:`target_table`; memoised
        per activity, object and place; ``gather=False`` only fills the memo)."""
        places = self.shared_places()
        with places.lock:
            return self._destination_rows(places, acts, sources, gather)

    def _destination_rows(self, places: "Places", acts: np.ndarray, sources: np.ndarray, gather: bool) -> np.ndarray:
        nj, nl = sources.shape[1], len(self.locations_)
        targets, _, position = self.target_table()
        codes = (acts[:, None] * nj + np.arange(nj)) * nl + sources
        table = places.rows
        if len(table.index) < len(self.activities_) * nj * nl:
            table.index = np.full(len(self.activities_) * nj * nl, -1, dtype=np.int64)
        rows = table.index[codes]
        missing = np.unique(codes[rows < 0])
        if len(missing):
            new = np.zeros((len(missing), targets.shape[1]))
            act, rest = np.divmod(missing, nj * nl)
            obj, src = np.divmod(rest, nl)
            keys = list(zip(act.tolist(), obj.tolist(), src.tolist()))
            for r, (j, (idx, p)) in enumerate(zip(obj.tolist(), self._destinations(keys))):
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
class Places:
    """Memos that depend on the training places and destinations only, not on the hazards: each
    row of places' location indices and cells, each object's targets, the destination rows
    (shared by the movement models of every setting fitted on the same days)."""

    sources: dict[tuple[str, ...], tuple[np.ndarray, np.ndarray, np.ndarray]] = field(default_factory=dict)
    rows: _Rows = field(default_factory=lambda: _Rows(np.zeros(0, dtype=np.int64), np.zeros((0, 0))))
    targets: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
    lock: threading.RLock = field(default_factory=threading.RLock)  # the service forecasts on several threads


_SHARED_PLACES: "weakref.WeakValueDictionary[tuple, Places]" = weakref.WeakValueDictionary()


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
