"""Predicting ahead: where every tracked object will first be in the next 10-60 minutes.

A robot needs time to fetch, so one-step guesses are not enough, and feeding a guess back as if
it were the truth throws away everything the model is unsure about. The forecaster instead
propagates the whole activity distribution (:mod:`globe.inference.paths`) and the objects'
movements (:mod:`globe.inference.movements`) forward together.

For each object the first departure from its current place at step u has probability
h_u * prod_{v<u} (1 - h_v) along a path (its place stays the current one until it departs, so the
hazards are read at that place); summing over paths gives P(first departure at u, to x). Things
are put away when an activity ends, so the paths run one step past the horizon.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from globe.inference import _propagate
from globe.inference.movements import MovementModel
from globe.inference.paths import ActivityPaths, Roots, TreeBatch, known_trees
from globe.models.base import check_is_fitted


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
        return len(self.departure) - 1

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


def mix(values: np.ndarray, owners: np.ndarray, ranks: np.ndarray, weights: np.ndarray, size: int) -> np.ndarray:
    """``values`` (one row per forecast) mixed per owner: row o of the result is the sum of
    ``weights[q] * values[q]`` over the forecasts q of owner o, added in the order of their
    ``ranks`` (most probable first, as a running sum would), so a mixture of one forecast of
    weight 1 is that forecast to the bit."""
    out = np.zeros((size,) + values.shape[1:])
    shape = (-1,) + (1,) * (values.ndim - 1)
    for k in range(int(ranks.max(initial=-1)) + 1):
        mine = ranks == k
        out[owners[mine]] += weights[mine].reshape(shape) * values[mine]
    return out


def mixture(forecasts: Forecasts, weights: np.ndarray) -> Forecast:
    """One forecast from several of the same day (say, from its most probable histories), each
    weighted (``weights`` summing to 1, most probable first)."""
    n = len(forecasts)
    if n == 1 and weights[0] == 1.0:
        return forecasts[0]
    owners, ranks = np.zeros(n, dtype=np.int64), np.arange(n)
    departure = mix(forecasts.departure, owners, ranks, weights, 1)[0]
    compact = mix(forecasts.destination, owners, ranks, weights, 1)[0]
    full = np.zeros(compact.shape[:2] + (len(forecasts.locations),))
    j, x = np.nonzero(forecasts.real)
    full[:, j, forecasts.targets[j, x]] = compact[:, j, x]
    activity: list[dict[str, float]] = []
    for q, w in enumerate(weights.tolist()):
        for k, dist in enumerate(forecasts.trees.activity(q)):
            if k == len(activity):
                activity.append({})
            for a, p in dist.items():
                activity[k][a] = activity[k].get(a, 0.0) + w * p
    return Forecast(int(forecasts.start[0]), forecasts.objects, forecasts.locations, tuple(activity), departure, full)


def first_locations(destination: np.ndarray, targets: np.ndarray, horizons: int) -> tuple[np.ndarray, np.ndarray]:
    """:meth:`Forecasts.first_locations` of a (queries x steps x objects x targets) array: the
    destinations summed step by step, each step's most likely target (the first of ties)."""
    nq, nsteps, nj, width = destination.shape
    steps = max(0, min(horizons, nsteps))
    best = np.empty((nq, steps, nj), dtype=np.int64)
    prob = np.empty((nq, steps, nj))
    joint = np.zeros((nq, nj, width))
    for s in range(steps):
        joint += destination[:, s]
        best[:, s] = joint.argmax(axis=2)
        prob[:, s] = np.take_along_axis(joint, best[:, s, :, None], axis=2)[..., 0]
    return targets[np.arange(targets.shape[0])[None, None, :], best], prob


Query = tuple[Sequence[str], Sequence[Sequence[str]]]
"""(activities a_0.., the places of every object at steps 0..m): what one forecast starts from."""


def _run_start(roots: Roots, q: int, m: int) -> int | None:
    """The first step of the last known activity's run (a_m's when it is known, else a_{m-1}'s),
    or None when no activity is known."""
    prev, duration = int(roots.prev[q]), int(roots.duration[q])
    if roots.head is not None and int(roots.head[q]) != prev:
        return m
    return None if prev < 0 else m - 1 - duration


class Forecaster:
    """An activity model and a movement model, propagated together (see module doc)."""

    def __init__(self, activity: Any, movements: MovementModel, *, min_path_probability: float = 1e-3,
                 max_paths: int = 64) -> None:
        self.activity = activity
        self.movements = movements
        self.min_path_probability = min_path_probability
        self.max_paths = max_paths
        self._paths = ActivityPaths(activity, min_path_probability=min_path_probability, max_paths=max_paths)

    def paths(self, history: Sequence[str], steps: int,
              weekday: int | None = None) -> list[tuple[float, tuple[str, ...]]]:
        """The next ``steps`` activities after ``history``: (probability, path), most likely first,
        probabilities summing to 1 (the forward pass; pruned as configured)."""
        return self._paths.paths(history, steps, weekday)

    def roots(self, histories: Sequence[Sequence[str]], starts: Sequence[int],
              weekdays: Sequence[int | None] | None = None) -> Roots:
        """Where the paths of queries given as histories start (:meth:`ActivityPaths.roots`)."""
        return self._paths.roots(histories, starts, weekdays)

    def trees(self, roots: Roots, horizon: int) -> TreeBatch:
        """The forward pass of :meth:`forecast_roots` alone (shareable between movement models)."""
        return self._paths.trees(roots, horizon)

    def forecast(self, activities: Sequence[str], locations: Sequence[Sequence[str]], horizon: int,
                 weekday: int | None = None) -> Forecast:
        """Forecast movements at steps m+1..m+1+horizon, where m = len(locations) - 1 is the last
        step whose locations are known and ``activities`` holds a_0.. (m or m+1 of them: the
        activity at step m may be unknown). Movements at step u belong to the activity at u-1;
        ``weekday``: the day's day of the week (Monday 0), when known."""
        return self.forecast_many([(activities, locations)], horizon, weekdays=[weekday])[0]

    def forecast_many(self, queries: Sequence[Query], horizon: int, trees: TreeBatch | None = None,
                      weekdays: Sequence[int | None] | None = None) -> Forecasts:
        """:meth:`forecast` for every (activities, locations) of ``queries`` at once. Each query's
        activities end at the same offset from its last location step (m - 1 for all or m for
        all). ``trees`` (of the same queries) saves the forward pass when several movement models
        forecast the same histories."""
        for activities, locations in queries:
            m, n = len(locations) - 1, len(activities)
            if m < 0 or n not in (m, m + 1):
                raise ValueError(f"need the locations of steps 0..m and the activities of 0..m-1 or 0..m; got "
                                 f"{len(locations)} location rows and {n} activities")
        roots = self.roots([a for a, _ in queries], [len(loc) - 1 for _, loc in queries], weekdays)
        return self.forecast_roots(roots, [loc for _, loc in queries], horizon, trees)

    def forecast_roots(self, roots: Roots, locations: Sequence[Sequence[Sequence[str]]], horizon: int,
                       trees: TreeBatch | None = None) -> Forecasts:
        """Forecasts from paths starting at ``roots`` (or their ``trees``), each query's places
        known at steps 0..m (``locations``): :func:`propagate` over this model's paths."""
        return propagate(self.movements, roots, locations, self.trees(roots, horizon) if trees is None else trees)


def forecast_known(movements: MovementModel, queries: Sequence[Query], futures: Sequence[Sequence[str]],
                   horizon: int) -> Forecasts:
    """Movements forecast along the activities each query is told lie ahead (``futures[q]``: those at
    steps m..m+horizon+1): the *oracle* that knows the true activity, whose movements alone are
    predicted (:func:`~globe.inference.paths.known_trees`). What perfect activity knowledge would give."""
    histories = [a for a, _ in queries]
    trees, roots = known_trees(histories, [len(loc) - 1 for _, loc in queries], futures, horizon)
    return propagate(movements, roots, [loc for _, loc in queries], trees)


def propagate(mv: MovementModel, roots: Roots, locations: Sequence[Sequence[Sequence[str]]],
              trees: TreeBatch) -> Forecasts:
    """The objects' first departures and destinations along the weighted paths of ``trees`` (from
    ``roots``), each query's places known at steps 0..m (``locations``). The objects that moved
    since the run under way at m-1 began are read from ``roots.duration`` (for hazards that
    remember them)."""
    check_is_fitted(mv)
    horizon = trees.horizon
    nj, nq = len(mv.objects_), len(locations)
    memory = mv.hazard_.shape[3] == 2
    starts = np.array([len(loc) - 1 for loc in locations], dtype=np.int64)
    src = np.zeros((nq, nj), dtype=np.int64)
    cells = np.zeros((nq, nj), dtype=np.int64)
    seen = np.ones((nq, nj), dtype=bool)
    earlier = np.zeros((nq, nj), dtype=bool)
    for q, rows in enumerate(locations):
        m = len(rows) - 1
        src[q], cells[q], seen[q] = mv.sources(rows[m])
        begin = _run_start(roots, q, m) if memory else None
        if begin is not None:  # the objects moved since the run under way began
            for v in range(begin + 1, m + 1):
                if rows[v] != rows[v - 1]:
                    earlier[q] |= np.array([x != y for x, y in zip(rows[v], rows[v - 1])])
    translate = mv.activity_codes(trees.names)
    targets, real, _ = mv.target_table()
    departure = np.zeros((nq, horizon + 1, nj))
    destination = np.zeros((nq, horizon + 1, nj, targets.shape[1]))
    if nj:  # a home with no object to track has activities to forecast, and nothing to move
        _levels(mv, trees, translate, src, cells, seen, earlier, departure, destination)
    return Forecasts(starts, mv.objects_, mv.locations_, trees, departure, destination, targets, real)


def _levels(mv: MovementModel, trees: TreeBatch, translate: np.ndarray, src: np.ndarray, cells: np.ndarray,
            seen: np.ndarray, earlier: np.ndarray, departure: np.ndarray, destination: np.ndarray) -> None:
    """Fill ``departure`` and ``destination`` level by level over the paths of ``trees``
    (:mod:`globe.inference._propagate`; every destination row the levels read is filled in
    first)."""
    hazard = mv.hazard_
    nq, nsteps, nj = departure.shape
    shape = (*hazard.shape, nj, nq, nsteps)
    model = (hazard.reshape(-1), mv.object_hazard_, mv.switch_index_, mv.switch_seen_, mv.switch_moved_,
             cells, seen, earlier)
    wanted = [(level.group_act, level.group_query) for level in trees.levels[1:]]
    index, values = mv.fill_destination_rows(translate, src, wanted)
    where = (nq, nsteps, nj, destination.shape[3], len(mv.locations_))
    survive = np.ones((len(trees.levels[0].act) if trees.levels else 0, nj))
    for i, level in enumerate(trees.levels[1:], start=1):
        nodes = (level.query, translate[level.up], level.dur_up, level.ends, level.first_up, translate[level.act],
                 level.parent, level.weight, level.group)
        after = np.empty((len(level.act), nj))
        per = np.zeros((len(level.group_query), nj))
        _propagate.level(shape, float(mv.hazard_shrinkage), model, nodes, survive, after, per, departure, i - 1)
        _propagate.destinations(where, per, level.group_query, translate[level.group_act], src, index, values,
                                destination, i - 1)
        survive = after
