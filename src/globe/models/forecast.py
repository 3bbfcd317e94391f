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
- **Destinations.** Where an object goes when it moves, P(target | activity, object, source),
  shrunk towards P(target | object, source) and P(target | object): learned from where objects
  went in training (nothing in the one-step models predicts *where* an object goes).

For each object the first departure from its current place at step u has probability
h_u * prod_{v<u} (1 - h_v) along a path (its place stays the current one until it departs, so the
hazards are read at that place); summing over paths gives P(first departure at u, to x).
Training is counting only.
"""

from __future__ import annotations

from collections import Counter, defaultdict
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from globe.data.records import Day
from globe.models.base import ActivityModelBase, CountingModel
from globe.models.packed_days import PackedDays

UNKNOWN = "<unknown>"


class MovementModel(CountingModel):
    """Per-step movement hazards and destinations of every tracked object (see module doc)."""

    _parameter_constraints = {"hazard_shrinkage": float, "duration_cap": int, "destination_shrinkage": float,
                              "run_end": (True, False), "run_memory": (True, False)}
    kind = "movement"

    def __init__(self, *, hazard_shrinkage: float = 2.0, duration_cap: int = 4, destination_shrinkage: float = 1.0,
                 run_end: bool = True, run_memory: bool = False) -> None:
        self.hazard_shrinkage = hazard_shrinkage
        self.duration_cap = duration_cap
        self.destination_shrinkage = destination_shrinkage
        self.run_end = run_end
        self.run_memory = run_memory

    # -- training ---------------------------------------------------------------------------
    def fit(self, days: Sequence[Day], objects: Sequence[str]) -> "MovementModel":
        """Count, over ``days``, how often each object left its place and where it went."""
        self._reset()
        self._validate_params()
        days = tuple(days)
        self.training_data_ = PackedDays(days)  # counted again when a day is learned; packed, a tenth of the memory
        self.objects_ = tuple(objects)
        self.activities_ = tuple(sorted(set().union(*(d.activities for d in days)))) + (UNKNOWN,)
        distinct: dict[tuple[str, ...], int] = {}  # a day's rows repeat until something moves
        row_ids = [np.array([distinct.setdefault(row, len(distinct)) for row in d.locations], dtype=int) for d in days]
        self.locations_ = tuple(sorted({loc for row in distinct for loc in row})) + (UNKNOWN,)
        self._act_index = {a: i for i, a in enumerate(self.activities_)}
        self._loc_index = {loc: i for i, loc in enumerate(self.locations_)}
        na, c, nj, nl = len(self.activities_), self.duration_cap, len(self.objects_), len(self.locations_)
        cols = np.arange(nj)
        table = np.array([[self._loc_index[x] for x in row] for row in distinct], dtype=int).reshape(len(distinct), nj)
        e_size, m_size = (2 if self.run_end else 1), (2 if self.run_memory else 1)
        cells, changes, moves = [], [], []  # (activity, steps into run, run ends, moved earlier) and (object, place)
        day_acts = []
        for day, ids in zip(days, row_ids):
            if len(day) < 2:
                continue
            acts = np.array([self._act_index[a] for a in day.activities])
            day_acts.append((acts, ids))
            dur = np.minimum(durations(day.activities), c - 1)
            locs = table[ids]
            src, dst = locs[:-1], locs[1:]
            change = src != dst
            ends = (acts[1:] != acts[:-1]).astype(int) * (e_size - 1)  # things get put away when it ends ...
            earlier = moved_in_run(dur, change) if self.run_memory else 0  # ... what came out during it
            cell = ((acts[:-1, None] * c + dur[:-1, None]) * e_size + ends[:, None]) * m_size + earlier
            cells.append(np.broadcast_to(cell, change.shape).ravel())
            changes.append(change.ravel())
            moves.append((cols[None, :] * nl + src).ravel())
        # Only (object, place) pairs seen in training get cells: objects visit few places.
        pair_codes = np.concatenate(moves) if moves else np.zeros(0, dtype=int)
        self._pairs = np.nonzero(np.bincount(pair_codes, minlength=nj * nl))[0]
        npairs = len(self._pairs)
        self._pair_object = self._pairs // nl
        lookup = np.zeros(nj * nl, dtype=int)
        lookup[self._pairs] = np.arange(npairs)
        keys = (np.concatenate(cells) * npairs + lookup[pair_codes]) if cells else np.zeros(0, dtype=int)
        size = na * c * e_size * m_size * npairs
        weights = np.concatenate(changes).astype(float) if changes else np.zeros(0)
        seen = np.bincount(keys, minlength=size).astype(float).reshape(na, c, e_size, m_size, npairs)
        moved = np.bincount(keys, weights=weights, minlength=size).reshape(na, c, e_size, m_size, npairs)
        self._dest: dict[tuple, Counter[int]] = defaultdict(Counter)  # (a, j, src) / (j, src) / (j,) -> target counts
        for acts, ids in day_acts:
            locs = table[ids]
            t, j = np.nonzero(locs[:-1] != locs[1:])
            for a, jj, src_, x in zip(acts[t].tolist(), j.tolist(), locs[t, j].tolist(), locs[t + 1, j].tolist()):
                self._dest[(a, jj, src_)][x] += 1
                self._dest[(jj, src_)][x] += 1
                self._dest[(jj,)][x] += 1
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
        self._dest_memo: dict[tuple[int, int, int], tuple[np.ndarray, np.ndarray]] = {}
        return self

    # -- lookups ----------------------------------------------------------------------------
    def activity_index(self, activity: str) -> int:
        return self._act_index.get(activity, len(self.activities_) - 1)

    def location_index(self, location: str) -> int:
        return self._loc_index.get(location, len(self.locations_) - 1)

    def hazards(self, activity: str, duration: int, sources: np.ndarray, ends: bool = False,
                moved: np.ndarray | None = None) -> np.ndarray:
        """P(each object leaves its place ``sources`` (location indices) in the step after one of
        ``activity``, ``duration`` steps into its run, that is its run's last (``ends``) or not,
        given whether each object already moved earlier in this run (``moved``, default none))."""
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
        return np.where(found, self.hazard_[a, d, e, m, idx], self._p1[a])

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


def durations(activities: Sequence[str]) -> np.ndarray:
    """Steps since the current run began, at every step (0 on a run's first step)."""
    out = np.zeros(len(activities), dtype=int)
    for t in range(1, len(activities)):
        out[t] = out[t - 1] + 1 if activities[t] == activities[t - 1] else 0
    return out


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


class Forecaster:
    """An activity model and a movement model, propagated together (see module doc)."""

    def __init__(self, activity: ActivityModelBase, movements: MovementModel, *, min_path_probability: float = 3e-3,
                 max_paths: int = 24, memo_size: int = 200_000) -> None:
        self.activity = activity
        self.movements = movements
        self.min_path_probability = min_path_probability
        self.max_paths = max_paths
        self.memo_size = memo_size
        self._memo: dict[tuple[str, ...], dict[str, float]] = {}
        self._dest_memo: dict[tuple[str, bytes], np.ndarray] = {}
        self._version = self._models_version()

    def _models_version(self) -> tuple[int, int]:
        """Changes when either model learns (an online assistant adds days): memos are then stale."""
        return len(getattr(self.activity, "training_data_", ())), id(getattr(self.movements, "hazard_", None))

    def _check_version(self) -> None:
        version = self._models_version()
        if version != self._version:
            self._memo.clear()
            self._dest_memo.clear()
            self._version = version

    def _destinations(self, activity: str, sources: np.ndarray) -> np.ndarray:
        key = (activity, sources.tobytes())
        out = self._dest_memo.get(key)
        if out is None:
            if len(self._dest_memo) >= 4096:
                self._dest_memo.clear()
            out = self._dest_memo[key] = self.movements.destination_matrix(activity, sources)
        return out

    def _next(self, history: tuple[str, ...]) -> dict[str, float]:
        dist = self._memo.get(history)
        if dist is None:
            if len(self._memo) >= self.memo_size:
                self._memo.clear()
            dist = self._memo[history] = self.activity.predict_proba(history)
        return dist

    def paths(self, history: Sequence[str], steps: int) -> list[tuple[float, tuple[str, ...]]]:
        """The next ``steps`` activities after ``history``: (probability, path), most likely first,
        probabilities summing to 1 (the forward pass; pruned as configured)."""
        history = tuple(history)
        beam: list[tuple[float, tuple[str, ...]]] = [(1.0, ())]
        for _ in range(steps):
            grown: list[tuple[float, tuple[str, ...]]] = []
            for p, path in beam:
                dist = self._next(history + path)
                if not dist:  # a model with nothing to say: the activity stays the same
                    dist = {(history + path)[-1]: 1.0} if history or path else {}
                best = max(dist, key=lambda a: (dist[a], a), default=None)
                grown.extend((p * q, path + (a,)) for a, q in dist.items()
                             if q > 0 and (p * q >= self.min_path_probability or a == best))
            if not grown:
                return []
            kept = [item for item in grown if item[0] >= self.min_path_probability]
            kept = kept or [max(grown, key=lambda item: item[0])]
            if len(kept) > self.max_paths:
                kept = sorted(kept, key=lambda item: (-item[0], item[1]))[: self.max_paths]
            z = sum(p for p, _ in kept)
            beam = [(p / z, path) for p, path in kept]
        return sorted(beam, key=lambda item: (-item[0], item[1]))

    def forecast(self, activities: Sequence[str], locations: Sequence[Sequence[str]], horizon: int) -> Forecast:
        """Forecast movements at steps m+1..m+1+horizon, where m = len(locations) - 1 is the last
        step whose locations are known and ``activities`` holds a_0.. (m or m+1 of them: the
        activity at step m may be unknown). Movements at step u belong to the activity at u-1."""
        m = len(locations) - 1
        n = len(activities)
        if m < 0 or n not in (m, m + 1):
            raise ValueError(f"need the locations of steps 0..m and the activities of 0..m-1 or 0..m; got {len(locations)} "
                             f"location rows and {n} activities")
        self._check_version()
        known = tuple(activities)
        # one step beyond the horizon: whether the activity at m+horizon ends there matters
        future = self.paths(known, m + horizon + 2 - n)
        mv = self.movements
        nj, nl = len(mv.objects_), len(mv.locations_)
        sources = np.array([mv.location_index(x) for x in locations[m]])
        base_dur = durations(known)
        departure = np.zeros((horizon + 1, nj))
        weights: list[dict[str, np.ndarray]] = [defaultdict(lambda: np.zeros(nj)) for _ in range(horizon + 1)]
        act_marg: list[dict[str, float]] = [defaultdict(float) for _ in range(horizon + 1)]
        hazard_memo: dict[tuple[str, int, bool, bool], np.ndarray] = {}
        # objects already moved in the run under way (movements seen up to step m), and none in a new run
        r0 = (n - 1) - int(base_dur[n - 1]) if n else m
        earlier = np.zeros(nj, dtype=bool)
        for v in range(r0 + 1, m + 1):
            if locations[v] != locations[v - 1]:
                earlier |= np.array([x != y for x, y in zip(locations[v], locations[v - 1])])
        none = np.zeros(nj, dtype=bool)
        # Paths share prefixes (activities at m, m+1, ...): each object's survival along a prefix
        # is computed once. The hazard of step m+1+k reads the activities at m+k and m+k+1.
        weight: dict[tuple[str, ...], float] = defaultdict(float)
        for w, path in future or [(1.0, ())]:
            seq = known + path
            for k in range(min(horizon + 2, len(seq) - m)):
                weight[seq[m: m + k + 1]] += w
        start_prev, start_dur = (known[m - 1], int(base_dur[m - 1])) if 1 <= m <= n else (None, -1)
        state: dict[tuple[str, ...], tuple[np.ndarray, int, bool]] = {(): (np.ones(nj), start_dur, True)}
        for prefix in sorted(weight, key=len):  # parents before children
            survive, dur, first_run = state[prefix[:-1]]
            a = prefix[-1]
            prev: str | None = start_prev
            if len(prefix) >= 2:
                k, prev = len(prefix) - 2, prefix[-2]
                key = (prev, dur, a != prev, first_run)
                h = hazard_memo.get(key)
                if h is None:
                    h = hazard_memo[key] = mv.hazards(prev, dur, sources, ends=a != prev, moved=earlier if first_run else none)
                leave = weight[prefix] * survive * h
                departure[k] += leave
                weights[k][prev] += leave
                survive = survive * (1.0 - h)
            if len(prefix) <= horizon + 1:
                act_marg[len(prefix) - 1][a] += weight[prefix]
            state[prefix] = (survive, dur + 1 if a == prev else 0, first_run and a == prev)
        destination = np.zeros((horizon + 1, nj, nl))
        for k in range(horizon + 1):
            for a, leave in weights[k].items():
                destination[k] += leave[:, None] * self._destinations(a, sources)
        return Forecast(m, mv.objects_, mv.locations_, tuple(dict(c) for c in act_marg), departure, destination)
