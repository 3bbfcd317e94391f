"""What a format's reader found in a log, in one shape for every format, and the rule for records
lying far outside the rest of it.

Each reader fills one :class:`SensorLog` (annotated activity intervals, when each object sensor
fired or was on, every sensor with its type and room and when each fired or was on, when any
sensor was heard, and the file and line of every record) and hands it to
:func:`globe.data.importers.grid.write_import`, so no rule of the grid is written per format.
Every sensor's activations are kept in compact arrays (a year of a busy home is a million of
them): they become the household's ``sensors.csv`` and ``events/`` (:mod:`globe.data.sensors`).
"""

from __future__ import annotations

from array import array
from collections import Counter
from dataclasses import dataclass, field
from datetime import datetime, timedelta
from typing import Any

import numpy as np

from globe.errors import DataError

EPOCH = datetime(1970, 1, 1)
"""Times are kept as seconds since this (naive, local wall-clock) instant in compact arrays."""
FAR_GAP, STRAY_RECORDS, STRAY_SHARE = timedelta(days=30), 10, 0.01
"""A log's records split where FAR_GAP passes with none; beside the part holding most of them
(more than STRAY_RECORDS), a part holding at most STRAY_RECORDS or STRAY_SHARE of them lies far
outside the log: a corrupt timestamp (a year 9999 or 0001, an end dated years later), refused,
or left out with --skip-bad-lines. A part holding more is a second stretch of recording: kept."""


@dataclass(frozen=True, slots=True)
class Annotation:
    """One annotated activity, ``[start, end)``, with the line that began it."""

    activity: str
    start: datetime
    end: datetime
    source: str
    line: int
    origin: str  # what the log wrote for it, for the report ('7', 'Sleeping', 'input_select.activity: cooking')


@dataclass(frozen=True, slots=True)
class Activation:
    """A sensor fired (``start == end``) or was on from ``start`` to ``end``, both included."""

    start: datetime
    end: datetime


@dataclass
class SensorLog:
    """What a format's reader found, in local wall-clock time (naive datetimes)."""

    format: str
    sources: tuple[str, ...]
    annotations: list[Annotation] = field(default_factory=list)
    activations: dict[str, list[Activation]] = field(default_factory=dict)  # object sensors only (their uses)
    events: Counter[str] = field(default_factory=Counter)  # records per sensor, every sensor
    first: datetime | None = None  # the log's span: its earliest and latest timestamps
    last: datetime | None = None
    notes: list[str] = field(default_factory=list)  # what else the report must say
    annotation_field: str = "start"  # the field an overlap error names (CASAS: 'activity')
    moments: array = field(default_factory=lambda: array("d"))  # when a sensor was heard, seconds since 1970
    skip_bad_lines: bool | None = None  # whether the format leaves bad lines out (None: it offers no such option)
    stamps: array = field(default_factory=lambda: array("d"))  # every record's time, seconds since 1970 ...
    stamp_lines: array = field(default_factory=lambda: array("q"))  # ... its line, and its file (sources index)
    stamp_sources: array = field(default_factory=lambda: array("b"))
    left_out: list[dict[str, Any]] = field(default_factory=list)  # records left out for lying far outside the log
    bad_lines: list[DataError] = field(default_factory=list)  # lines left out (skip_bad_lines)
    sensors: dict[str, tuple[str, str]] = field(default_factory=dict)  # every kept sensor -> (type, room), first seen
    on_sensor: array = field(default_factory=lambda: array("q"))  # every sensor's activations: its index in
    on_start: array = field(default_factory=lambda: array("d"))  # ``sensors`` and [start, end], seconds since 1970
    on_end: array = field(default_factory=lambda: array("d"))
    sensor_rule: str = ""  # how the format gives a sensor its type and room, for the report
    _sensor_index: dict[str, int] = field(default_factory=dict, repr=False)

    def sensor(self, key: str, kind: str, room: str = "") -> None:
        """A sensor the household keeps (``sensors.csv``): its type and room as first met."""
        if key not in self._sensor_index:
            self._sensor_index[key] = len(self.sensors)
            self.sensors[key] = (kind, room)

    def sensor_on(self, key: str, start: datetime, end: datetime) -> None:
        """A kept sensor fired (``start == end``) or was on from ``start`` to ``end`` (any sensor:
        objects' too, so that ``events/`` holds every activation)."""
        self.on_sensor.append(self._sensor_index[key])
        self.on_start.append((start - EPOCH).total_seconds())
        self.on_end.append((end - EPOCH).total_seconds())

    def bad(self, err: DataError) -> None:
        """A line that breaks a rule of the format: the error, or with ``skip_bad_lines`` left
        out and kept for the report (real logs carry a few corrupt lines). A reader calls this
        before the line changes anything, so a line left out leaves no trace."""
        if not self.skip_bad_lines:
            raise err
        self.bad_lines.append(err)

    def heard(self, start: datetime, end: datetime | None = None, *, line: int = 0, source: int = 0) -> None:
        """A sensor's record (on ``line`` of the ``source``-th file): an event at ``start``, or on
        from ``start`` to ``end`` (heard throughout: a stretch it is on is no silence)."""
        self.saw(start, line=line, source=source)
        if end is not None and end != start:
            self.saw(end, line=line, source=source)
        end = start if end is None else end
        lo, hi = (start - EPOCH).total_seconds(), (end - EPOCH).total_seconds()
        if hi - lo < FAR_GAP.total_seconds():  # a stretch on for longer lies far outside the log by itself
            self.moments.extend(np.arange(lo, hi, 3600.0).tolist() if hi - lo > 3600.0 else [lo])
        self.moments.append(hi)

    def saw(self, moment: datetime, *, line: int = 0, source: int = 0) -> None:
        """A record at ``moment`` (the log's span)."""
        if self.first is None or moment < self.first:
            self.first = moment
        if self.last is None or moment > self.last:
            self.last = moment
        self.stamps.append((moment - EPOCH).total_seconds())
        self.stamp_lines.append(line)
        self.stamp_sources.append(source)


def keep_to_the_log(sensor_log: SensorLog) -> None:
    """Records lying far outside the rest of the log (see :data:`FAR_GAP`) are refused, naming
    the first of them, or, where the format leaves bad lines out and is asked to, left out with
    every annotation and sensor stretch reaching them, and listed in the report."""
    times = np.frombuffer(sensor_log.stamps, dtype=np.float64)
    if not len(times):
        return
    order = np.argsort(times, kind="stable")
    cuts = np.flatnonzero(np.diff(times[order]) > FAR_GAP.total_seconds()) + 1
    parts = np.split(order, cuts)
    main = max(range(len(parts)), key=lambda i: len(parts[i]))
    stray = [p for i, p in enumerate(parts) if i != main and len(p) <= max(STRAY_RECORDS, STRAY_SHARE * len(times))]
    if not stray or len(parts[main]) <= STRAY_RECORDS:  # too few records to judge the others by
        return
    lo, hi = (EPOCH + timedelta(seconds=float(times[parts[main]].min())),
              EPOCH + timedelta(seconds=float(times[parts[main]].max())))
    where = sensor_log.stamp_sources, sensor_log.stamp_lines
    first = min((int(i) for p in stray for i in p), key=lambda i: (where[0][i], where[1][i]))
    line, source = where[1][first] or None, sensor_log.sources[where[0][first]]
    when = EPOCH + timedelta(seconds=float(times[first]))
    span = f"the rest of the log ({len(parts[main])} of its {len(times)} records) runs {lo} .. {hi}"
    if not sensor_log.skip_bad_lines:
        fix = ("fix the line, or pass --skip-bad-lines to leave such records out" if sensor_log.skip_bad_lines is False
               else "fix the line")
        raise DataError(f"{when} lies far outside the log ({span}): a corrupt timestamp? {fix}", source=source,
                        line=line, field="time")
    inside = (lambda t: lo <= t <= hi)  # noqa: E731
    sensor_log.annotations = [a for a in sensor_log.annotations if inside(a.start) and inside(a.end)]
    for key, stretches in sensor_log.activations.items():
        sensor_log.activations[key] = [a for a in stretches if inside(a.start) and inside(a.end)]
    lo_s, hi_s = (lo - EPOCH).total_seconds(), (hi - EPOCH).total_seconds()
    starts = np.frombuffer(sensor_log.on_start, dtype=np.float64)
    ends = np.frombuffer(sensor_log.on_end, dtype=np.float64)
    within = (starts >= lo_s) & (starts <= hi_s) & (ends >= lo_s) & (ends <= hi_s)
    if not within.all():
        codes = np.frombuffer(sensor_log.on_sensor, dtype=np.int64)
        sensor_log.on_sensor = array("q", codes[within].tolist())
        sensor_log.on_start, sensor_log.on_end = array("d", starts[within].tolist()), array("d", ends[within].tolist())
    sensor_log.first, sensor_log.last = lo, hi
    moments = np.frombuffer(sensor_log.moments, dtype=np.float64)
    keep = moments[(moments >= (lo - EPOCH).total_seconds()) & (moments <= (hi - EPOCH).total_seconds())]
    sensor_log.moments = array("d", keep.tolist())
    sensor_log.left_out = [{"source": sensor_log.sources[where[0][i]], "line": where[1][i],
                            "time": str(EPOCH + timedelta(seconds=float(times[i])))}
                           for p in stray for i in p.tolist()]
    sensor_log.notes.append(f"{len(sensor_log.left_out)} records far outside the rest of the log ({lo} .. {hi}) left "
                            "out (--skip-bad-lines), with the annotations and sensor stretches reaching them: see "
                            "far_outside in the report")
