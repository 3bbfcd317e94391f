"""Every sensor of an imported home and its activations on each kept day: what the household's
``sensors.csv`` and ``events/`` hold (:mod:`globe.data.sensors`), so that a home nobody labels can
have its activities recognised from all of its sensors, not only those that became objects.

The readers list every sensor they keep with its type and room, and each activation (a firing,
or a stretch when the sensor was on) in :class:`~globe.data.importers.sensor_log.SensorLog`.
Here:

- A sensor left on is cut as an object's is (:mod:`globe.data.importers.uses`): an activation
  longer than its limit becomes a firing at its start. An object's sensor has its object's limit,
  so its events agree with the day's ``in_use`` cells (and its cuts are the report's
  ``left_on``); any other sensor has the same rule's limit from its own activations (a door open
  for a week is not a week of evidence), its cuts listed in the report's ``sensors.left_on``.
- A day's events are the activations meeting the span its rows cover (its first row's start to
  its last row's end, as :func:`~globe.data.importers.grid.write_import` places uses), cut to
  it, in seconds after the day's midnight, to the millisecond. Every kept day has an events file
  (one with no activation is a quiet day, not an unrecorded one); days left out have none.
"""

from __future__ import annotations

from collections import Counter
from datetime import date, datetime, time, timedelta
from typing import Any

import numpy as np

from globe.data.importers.objects import ObjectSelection
from globe.data.importers.options import GridOptions
from globe.data.importers.sensor_log import EPOCH, SensorLog
from globe.data.importers.uses import ObjectUses, left_on_rule, use_limit
from globe.data.sensors import EVENTS_FOLDER, SENSORS_FILE, Sensor, SensorData, SensorDay


def sensor_data(sensor_log: SensorLog, selection: ObjectSelection, uses: dict[str, ObjectUses],
                kept: dict[date, datetime], options: GridOptions) -> tuple[SensorData | None, dict[str, Any]]:
    """The kept days' sensor data (None when the log kept no sensor) and the report's ``sensors``
    section: how many sensors of each type, the rules, the activations written and those cut as
    left on."""
    sensors = tuple(Sensor(key, kind, room, _object_of(selection, key))
                    for key, (kind, room) in sensor_log.sensors.items())
    codes = np.frombuffer(sensor_log.on_sensor, dtype=np.int64)
    starts = np.frombuffer(sensor_log.on_start, dtype=np.float64)
    ends = np.frombuffer(sensor_log.on_end, dtype=np.float64).copy()
    left_on = _cut_left_on(sensors, codes, starts, ends, uses, options)
    days: dict[str, SensorDay] = {}
    order = np.argsort(starts, kind="stable")
    by_start = starts[order]
    longest = float((ends - starts).max()) if len(starts) else 0.0
    window = options.step_minutes * options.steps * 60.0
    for day, base in sorted(kept.items()):
        lo = (base - EPOCH).total_seconds()
        hi = lo + window
        midnight = (datetime.combine(day, time()) - EPOCH).total_seconds()
        pick = order[np.searchsorted(by_start, lo - longest):np.searchsorted(by_start, hi)]
        pick = pick[ends[pick] >= lo]  # begins before the span ends and ends in it or after: meets it
        start = np.round(np.maximum(starts[pick], lo) - midnight, 3)
        end = np.round(np.minimum(ends[pick], hi) - midnight, 3)
        sensor = codes[pick]
        rank = np.lexsort((sensor, end, start))
        days[day.isoformat()] = SensorDay(day.isoformat(), sensor[rank], start[rank], end[rank])
    types = Counter(s.type for s in sensors)
    section: dict[str, Any] = {
        "files": f"{SENSORS_FILE}, {EVENTS_FOLDER}/<day>.csv" if sensors else "none: the log kept no sensor",
        "count": len(sensors),
        "types": dict(sorted(types.items())),
        "rooms": dict(sorted(Counter(s.room or "(none)" for s in sensors).items())),
        "rule": sensor_log.sensor_rule,
        "activations": int(sum(len(d) for d in days.values())),
        "days": len(days) if sensors else 0,
        "left_on_rule": left_on_rule(options) + " (an object's sensor: its object's limit; any other: its own)",
        "left_on": left_on,
    }
    return (SensorData(sensors, days) if sensors else None), section


def _object_of(selection: ObjectSelection, key: str) -> str:
    choice = selection.choices.get(key)
    return choice.object if choice is not None and choice.object is not None else ""


def _cut_left_on(sensors: tuple[Sensor, ...], codes: np.ndarray, starts: np.ndarray, ends: np.ndarray,
                 uses: dict[str, ObjectUses], options: GridOptions) -> list[dict[str, Any]]:
    """Cut each activation longer than its sensor's limit to a firing (``ends`` in place); the
    cuts of sensors of no object, for the report (an object's are its ``left_on`` already)."""
    rows: list[dict[str, Any]] = []
    if not len(codes):
        return rows
    order = np.argsort(codes, kind="stable")
    bounds = np.searchsorted(codes[order], np.arange(len(sensors) + 1))
    for code, sensor in enumerate(sensors):
        mine = order[bounds[code]:bounds[code + 1]]
        if not len(mine):
            continue
        durations = ends[mine] - starts[mine]
        found = uses.get(sensor.object) if sensor.object else None
        limit = found.limit if found is not None else use_limit(durations.tolist(), options)
        for i in mine[durations > limit].tolist():
            if found is None:
                rows.append({"sensor": sensor.name, "type": sensor.type, "start": _when(starts[i]),
                             "end": _when(ends[i]), "minutes": round((ends[i] - starts[i]) / 60, 1),
                             "limit_minutes": round(limit / 60, 1)})
            ends[i] = starts[i]
    return sorted(rows, key=lambda r: (r["start"], r["sensor"]))


def _when(seconds: float) -> str:
    return f"{EPOCH + timedelta(seconds=float(seconds)):%Y-%m-%d %H:%M:%S}"
