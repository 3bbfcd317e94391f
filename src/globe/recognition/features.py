"""What the sensors say about each step of a day, as the activity-recognition literature reads them.

Per step of a day's grid (row minute m stands for [m, m + step)), after van Kasteren et al.
(UbiComp 2008):

- ``raw``: each sensor is on at some time in the step (a firing inside it counts);
- ``change``: each sensor changes state in the step (an activation begins or ends there);
- ``last``: which sensor changed state last, up to the end of the step (none yet: its own value);
- ``room``: for each room with a motion sensor, how long ago motion was last seen there at the
  end of the step, in :data:`ROOM_BINS` (in the step, within 5 minutes, 30 minutes, 2 hours, longer
  or never): where the person is, and how settled.

Every feature is a small categorical column, so one emission model reads them all
(:class:`~globe.recognition.emission.SensorEmission`) and any subset can be offered to
cross-validation (:data:`REPRESENTATIONS`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from globe.data.sensors import Sensor, SensorDay

FEATURES = ("raw", "change", "last", "room")
REPRESENTATIONS: tuple[tuple[str, ...], ...] = (
    ("change", "last"), ("raw", "change", "last"), ("raw", "last", "room"), ("change", "last", "room"),
    ("raw", "change", "last", "room"))
"""The feature sets cross-validation chooses among (van Kasteren's best, "change + last", first)."""
ROOM_BINS = (5 * 60.0, 30 * 60.0, 2 * 3600.0)
"""Upper edges (seconds) of the time-since-motion classes after "in the step"; longer is the last class."""
MOTION_TYPES = frozenset({"motion", "occupancy", "presence"})


@dataclass(frozen=True, slots=True)
class Layout:
    """Which columns a home's feature matrix has: ``names`` (for people) and ``sizes`` (the
    number of values of each column), given its sensors and a feature set."""

    features: tuple[str, ...]
    sensors: tuple[Sensor, ...]
    rooms: tuple[str, ...]
    names: tuple[str, ...]
    sizes: np.ndarray

    @classmethod
    def of(cls, sensors: Sequence[Sensor], features: Sequence[str] = FEATURES) -> "Layout":
        unknown = [f for f in features if f not in FEATURES]
        if unknown or not features:
            raise ValueError(f"features {list(features)}: expected some of {', '.join(FEATURES)}")
        sensors = tuple(sensors)
        rooms = tuple(sorted({s.room for s in sensors if s.type in MOTION_TYPES and s.room}))
        names: list[str] = []
        sizes: list[int] = []
        for feature in FEATURES:
            if feature not in features:
                continue
            if feature in ("raw", "change"):
                names += [f"{feature}:{s.name}" for s in sensors]
                sizes += [2] * len(sensors)
            elif feature == "last":
                names.append("last")
                sizes.append(len(sensors) + 1)
            else:
                names += [f"room:{r}" for r in rooms]
                sizes += [len(ROOM_BINS) + 2] * len(rooms)
        return cls(tuple(f for f in FEATURES if f in features), sensors, rooms, tuple(names),
                   np.array(sizes, dtype=np.int64))

    @property
    def offsets(self) -> np.ndarray:
        """Where each column's values start in a flat table of all columns' values."""
        return column_offsets(self.sizes)


def column_offsets(sizes: np.ndarray) -> np.ndarray:
    """Where each column's values start in a flat table of all columns' values (``sizes``: each
    column's number of values)."""
    return np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)


def step_features(layout: Layout, day: SensorDay | None, minutes: Sequence[int], step_minutes: int) -> np.ndarray:
    """(steps x columns) int matrix of the day's features on the grid ``minutes`` (see the module
    doc); a day with no recording (None) reads as every sensor quiet."""
    steps = len(minutes)
    starts = np.asarray(minutes, dtype=np.float64) * 60.0
    ends = starts + step_minutes * 60.0
    n = len(layout.sensors)
    sensor = np.zeros(0, dtype=np.int64) if day is None else day.sensor
    begin = np.zeros(0) if day is None else day.start
    finish = np.zeros(0) if day is None else day.end
    columns: list[np.ndarray] = []
    if "raw" in layout.features:
        first = np.searchsorted(ends, begin, side="right")  # the first step ending after it begins
        last = np.searchsorted(starts, finish, side="right") - 1  # the last step starting at or before its end
        ok = (first <= last) & (first < steps) & (last >= 0)
        marks = np.zeros((steps + 1, n), dtype=np.int64)
        np.add.at(marks, (first[ok], sensor[ok]), 1)
        np.add.at(marks, (last[ok] + 1, sensor[ok]), -1)
        columns.append((np.cumsum(marks, axis=0)[:steps] > 0).astype(np.int64))
    moments = np.concatenate([begin, finish])
    who = np.concatenate([sensor, sensor])
    order = np.argsort(moments, kind="stable")
    moments, who = moments[order], who[order]
    if "change" in layout.features:
        at = np.searchsorted(starts, moments, side="right") - 1
        ok = (at >= 0) & (moments < ends[np.clip(at, 0, max(steps - 1, 0))]) if steps else np.zeros(0, dtype=bool)
        change = np.zeros((steps, n), dtype=np.int64)
        change[at[ok], who[ok]] = 1
        columns.append(change)
    if "last" in layout.features:
        before = np.searchsorted(moments, ends, side="left") - 1  # changes strictly before the step's end
        columns.append(np.where(before >= 0, who[np.clip(before, 0, None)], n)[:, None] if len(moments)
                       else np.full((steps, 1), n, dtype=np.int64))
    if "room" in layout.features:
        columns.append(_room_columns(layout, sensor, begin, finish, starts, ends))
    return np.concatenate(columns, axis=1) if columns else np.zeros((steps, 0), dtype=np.int64)


def _room_columns(layout: Layout, sensor: np.ndarray, begin: np.ndarray, finish: np.ndarray, starts: np.ndarray,
                  ends: np.ndarray) -> np.ndarray:
    out = np.full((len(starts), len(layout.rooms)), len(ROOM_BINS) + 1, dtype=np.int64)
    room_of = np.array([layout.rooms.index(s.room) if s.type in MOTION_TYPES and s.room in layout.rooms else -1
                        for s in layout.sensors] + [-1], dtype=np.int64)
    rooms = room_of[sensor] if len(sensor) else np.zeros(0, dtype=np.int64)
    for r in range(len(layout.rooms)):
        mine = rooms == r
        if not mine.any():
            continue
        b, f = begin[mine], finish[mine]
        order = np.argsort(b, kind="stable")
        b, f = b[order], np.maximum.accumulate(f[order])  # the latest end among those begun so far
        k = np.searchsorted(b, ends, side="left") - 1  # the last activation begun before the step ends
        seen = k >= 0
        last_end = np.where(seen, f[np.clip(k, 0, None)], -np.inf)
        during = seen & (last_end >= starts)
        since = ends - np.minimum(last_end, ends)
        col = np.where(during, 0, 1 + np.searchsorted(np.asarray(ROOM_BINS), since, side="left"))
        out[:, r] = np.where(seen, np.minimum(col, len(ROOM_BINS) + 1), len(ROOM_BINS) + 1)
    return out
