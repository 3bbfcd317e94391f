"""Put a smart home's timestamped record on GLOBE's step grid and write it as a household folder.

Every importer reads its format into one :class:`SensorLog` (annotated activity intervals, and
when each object sensor fired or was on) and hands it here, so that the rules below hold for
every format and are written once:

- A day of date D has one row at each minute ``day_start + k * step`` up to ``day_end``
  (06:00, 06:10, ..., 24:00 by default, as HOMER+); the row at minute m stands for the step
  ``[m, m + step)``. Event times never add rows.
- A row's activity is the annotation covering the step's *start* (the current convention of the
  CSV logs); a step no annotation covers is ``idle``. Its ``covering`` cell is the activity that
  covers most of the step (``idle`` for time no annotation covers; ties: the row's activity, then
  the name), so a use can be credited to it (``sequences.alignment = "most"``). Annotations may
  not overlap, unless ``overlaps="latest"``: then the one that began last wins while it lasts
  (ties: the later line).
- An object is used in a step when one of its sensors fires, or is on, at any time inside the
  step; its cell is then its room's ``in_use`` place, otherwise its home place.
- A day with no annotation at all is left out, and so is a day on whose date no annotation
  begins and whose annotations end before its last row (one carried over from the day before is
  all it has: annotating stopped, or the recorder was down; a day one annotation covers whole,
  a day away, is kept), and a day the log does not cover from its first step to its last (the
  log's first and last days, usually). All are listed in the report.
- A kept day whose longest stretch without an event from any sensor is far longer than the
  home's usual (1.5 times the median longest of the days a sensor was heard on, and 6 hours at
  least) is listed in the report (``silent_stretches``): a recorder outage, or nobody home.
- A record far outside the rest of the log (a corrupt timestamp: a year 9999 or 0001, an end
  dated years late; see :data:`FAR_GAP`) is an error naming its line, or, where the format has
  ``--skip-bad-lines`` and it is given, left out with the annotations and sensor stretches
  reaching it and listed in the report (``far_outside``).
- The last ``test_days`` kept days (default: the last 20 %, at least one when two or more days are
  kept) are test days; the rest are training days.

The folder is written through :mod:`globe.data.csv_logs` (the writer of the shipped files) into a
temporary sibling and renamed into place, with ``import.json``: which sensor became which object
column, which annotation which activity, which days were dropped and why.
"""

from __future__ import annotations

import json
import logging
import os
import shutil
from array import array
from collections import Counter
from dataclasses import dataclass, field
from datetime import date, datetime, time, timedelta
from pathlib import Path
from typing import Any, Literal, Sequence

import numpy as np

from globe.data.csv_logs import DAY_MINUTES, write_day, write_nodes
from globe.data.importers.objects import HomeMap, ObjectSelection, ObjectSpec, build_map
from globe.data.importers.text import show
from globe.data.records import Day
from globe.errors import ConfigError, DataError

log = logging.getLogger(__name__)

DEFAULT_STEP_MINUTES = 10
DEFAULT_DAY_START = 360  # 06:00, HOMER+'s first row
DEFAULT_DAY_END = 1440  # 24:00, HOMER+'s last row
DEFAULT_TEST_FRACTION = 0.2
IDLE = "idle"
REPORT_FILE = "import.json"
FAR_GAP, STRAY_RECORDS, STRAY_SHARE = timedelta(days=30), 10, 0.01
"""A log's records split where FAR_GAP passes with none; beside the part holding most of them
(more than STRAY_RECORDS), a part holding at most STRAY_RECORDS or STRAY_SHARE of them lies far
outside the log: a corrupt timestamp (a year 9999 or 0001, an end dated years later), refused,
or left out with --skip-bad-lines. A part holding more is a second stretch of recording: kept."""
SILENCE_NOTED, SILENCE_FACTOR = timedelta(hours=6), 1.5
"""A kept day's longest stretch with no event from any sensor is listed in the report (a recorder
outage, or nobody home; the day is kept) when it lasts this long and this many times the median
day's longest."""
_EPOCH = datetime(1970, 1, 1)
Overlaps = Literal["error", "latest"]


@dataclass(frozen=True, slots=True)
class GridOptions:
    """How a log is cut into days and steps, and which days are test days."""

    step_minutes: int = DEFAULT_STEP_MINUTES
    day_start_minute: int = DEFAULT_DAY_START
    day_end_minute: int = DEFAULT_DAY_END
    test_days: int | None = None  # None: the last test_fraction of the kept days
    test_fraction: float = DEFAULT_TEST_FRACTION
    overlaps: Overlaps = "error"

    def check(self) -> None:
        """Called where an import starts (not in the constructor, so options stay plain values)."""
        start, end, step = self.day_start_minute, self.day_end_minute, self.step_minutes
        if not 0 <= start < end <= DAY_MINUTES:
            raise ConfigError(f"the day must start before it ends, within 00:00..24:00 (got {_clock(start)} to "
                              f"{_clock(end)})")
        if step < 1 or (end - start) % step:
            raise ConfigError(f"a step of {step} minutes does not divide the day {_clock(start)}..{_clock(end)} "
                              f"({end - start} minutes); use e.g. 1, 2, 5 or 10")
        if self.test_days is not None and self.test_days < 0:
            raise ConfigError(f"test days must be 0 or more (got {self.test_days})")
        if not 0.0 <= self.test_fraction < 1.0:
            raise ConfigError(f"the test fraction must be in [0, 1) (got {self.test_fraction})")
        if self.overlaps not in ("error", "latest"):
            raise ConfigError(f"overlaps must be 'error' or 'latest' (got {self.overlaps!r})")

    @property
    def steps(self) -> int:
        return (self.day_end_minute - self.day_start_minute) // self.step_minutes + 1


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
    activations: dict[str, list[Activation]] = field(default_factory=dict)  # object sensors only
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

    def heard(self, start: datetime, end: datetime | None = None, *, line: int = 0, source: int = 0) -> None:
        """A sensor's record (on ``line`` of the ``source``-th file): an event at ``start``, or on
        from ``start`` to ``end`` (heard throughout: a stretch it is on is no silence)."""
        self.saw(start, line=line, source=source)
        if end is not None and end != start:
            self.saw(end, line=line, source=source)
        end = start if end is None else end
        lo, hi = (start - _EPOCH).total_seconds(), (end - _EPOCH).total_seconds()
        if hi - lo < FAR_GAP.total_seconds():  # a stretch on for longer lies far outside the log by itself
            self.moments.extend(np.arange(lo, hi, 3600.0).tolist() if hi - lo > 3600.0 else [lo])
        self.moments.append(hi)

    def saw(self, moment: datetime, *, line: int = 0, source: int = 0) -> None:
        """A record at ``moment`` (the log's span)."""
        if self.first is None or moment < self.first:
            self.first = moment
        if self.last is None or moment > self.last:
            self.last = moment
        self.stamps.append((moment - _EPOCH).total_seconds())
        self.stamp_lines.append(line)
        self.stamp_sources.append(source)


@dataclass(frozen=True, slots=True)
class ImportResult:
    """What an import wrote, for the command line to print."""

    dest: Path
    train_days: int
    test_days: int
    objects: tuple[str, ...]
    activities: tuple[str, ...]
    dropped_days: int
    report: Path
    notes: tuple[str, ...]


def _clock(minute: int) -> str:
    return f"{minute // 60:02d}:{minute % 60:02d}"


def _ceil_steps(delta: timedelta, step: timedelta) -> int:
    return -(-delta // step)


def check_overlaps(annotations: Sequence[Annotation], overlaps: Overlaps, *,
                   error_field: str = "start") -> list[Annotation]:
    """The annotations by start (ties: file order). Overlapping ones are an error unless
    ``overlaps="latest"``; an interval ending before it begins is always one."""
    for ann in annotations:
        if ann.end < ann.start:
            raise DataError(f"{show(ann.activity)} ends at {ann.end} before it begins at {ann.start}",
                            source=ann.source, line=ann.line, field="end")
    ordered = sorted(annotations, key=lambda a: (a.start, a.line))
    if overlaps == "error":
        longest: Annotation | None = None
        for ann in ordered:
            if longest is not None and ann.start < longest.end:
                raise DataError(f"{show(ann.activity)} begins at {ann.start} while {show(longest.activity)} (line "
                                f"{longest.line}) lasts until {longest.end}: annotations may not overlap (one person, "
                                "one activity; --overlaps latest lets the later one win while it lasts)",
                                source=ann.source, line=ann.line, field=error_field)
            if longest is None or ann.end > longest.end:
                longest = ann
    return ordered


def _day_dates(first: datetime, last: datetime) -> list[date]:
    count = (last.date() - first.date()).days + 1
    return [first.date() + timedelta(days=i) for i in range(count)]


def _touched_dates(start: datetime, end: datetime, offset: timedelta, window: timedelta) -> list[date]:
    """Dates D whose window ``[D + offset, D + offset + window)`` may meet ``[start, end]``."""
    low = (start - offset - window).date()
    high = (end - offset).date()
    return [low + timedelta(days=i) for i in range((high - low).days + 1)]


@dataclass
class _Grid:
    """The kept days' rows while they are filled in."""

    options: GridOptions
    bases: dict[date, datetime]  # kept date -> its first step's start
    activities: dict[date, list[str]]
    used: dict[str, dict[date, set[int]]]
    shares: dict[date, list[dict[str, float]]] = field(default_factory=dict)  # seconds of each step each label covers

    @property
    def step(self) -> timedelta:
        return timedelta(minutes=self.options.step_minutes)

    @property
    def window(self) -> timedelta:
        return self.step * self.options.steps

    @property
    def offset(self) -> timedelta:
        return timedelta(minutes=self.options.day_start_minute)


def _meets(ann: Annotation, base: datetime, window: timedelta) -> bool:
    """Whether an annotation meets the day window ``[base, base + window)`` (one of no length:
    whether its instant lies in it)."""
    if ann.start == ann.end:
        return base <= ann.start < base + window
    return ann.start < base + window and ann.end > base


def _choose_days(sensor_log: SensorLog, ordered: Sequence[Annotation], options: GridOptions
                 ) -> tuple[dict[date, datetime], list[dict[str, str]]]:
    """The kept days (date -> first step's start) and the dropped ones with why."""
    assert sensor_log.first is not None and sensor_log.last is not None
    offset = timedelta(minutes=options.day_start_minute)
    last_row = timedelta(minutes=options.day_end_minute)
    window = timedelta(minutes=options.step_minutes * options.steps)
    annotated: set[date] = set()  # days an annotation meets
    begun: set[date] = set()  # days on whose date an annotation begins, or that one covers to the last row
    for ann in ordered:
        for day in _touched_dates(ann.start, ann.end, offset, window):
            base = datetime.combine(day, time()) + offset
            if _meets(ann, base, window):
                annotated.add(day)
                if ann.start.date() == day or ann.end >= base + window:  # a day away is a day
                    begun.add(day)
    kept: dict[date, datetime] = {}
    dropped: list[dict[str, str]] = []
    for day in _day_dates(sensor_log.first, sensor_log.last):
        midnight = datetime.combine(day, time())
        if sensor_log.first > midnight + offset:
            why = (f"partial: the log starts at {sensor_log.first:%Y-%m-%d %H:%M:%S}, after this day's first row "
                   f"({_clock(options.day_start_minute)})")
        elif sensor_log.last < midnight + last_row:
            why = (f"partial: the log ends at {sensor_log.last:%Y-%m-%d %H:%M:%S}, before this day's last row "
                   f"({_clock(options.day_end_minute)})")
        elif day not in annotated:
            why = "no annotation"
        elif day not in begun:
            why = ("no annotation begins on it: it only carries one over from the day before, which ends before "
                   "its last row (annotating stopped, or the log has a gap)")
        else:
            kept[day] = midnight + offset
            continue
        dropped.append({"date": day.isoformat(), "why": why})
    return kept, dropped


@dataclass
class _LabelStats:
    annotations: int = 0
    origins: set[str] = field(default_factory=set)
    on_no_row: int = 0  # annotations inside kept days that cover no step's start


def _place_annotations(grid: _Grid, ordered: Sequence[Annotation]) -> dict[str, _LabelStats]:
    """Each kept row's activity: the annotation covering its start; later starts overwrite
    earlier ones, which is the ``latest`` rule (without overlaps, nothing is overwritten)."""
    per_label: dict[str, _LabelStats] = {}
    steps = grid.options.steps
    for ann in ordered:
        stats = per_label.setdefault(ann.activity, _LabelStats())
        stats.annotations += 1
        stats.origins.add(ann.origin)
        touched = placed = False
        for day in _touched_dates(ann.start, ann.end, grid.offset, grid.window):
            base = grid.bases.get(day)
            if base is None or not _meets(ann, base, grid.window):
                continue
            touched = True
            first = max(0, _ceil_steps(ann.start - base, grid.step))
            stop = min(steps, _ceil_steps(ann.end - base, grid.step))
            row = grid.activities[day]
            for k in range(first, stop):
                row[k] = ann.activity
                placed = True
            shares = grid.shares.setdefault(day, [{} for _ in range(steps)])
            for k in range(max(0, (ann.start - base) // grid.step), stop):
                lo, hi = max(ann.start, base + k * grid.step), min(ann.end, base + (k + 1) * grid.step)
                if hi > lo:
                    shares[k][ann.activity] = shares[k].get(ann.activity, 0.0) + (hi - lo).total_seconds()
        if touched and not placed:
            stats.on_no_row += 1
    return per_label


def _place_uses(grid: _Grid, objects: Sequence[ObjectSpec], activations: dict[str, list[Activation]]) -> None:
    """Mark the steps in which a sensor of each object fired or was on."""
    steps = grid.options.steps
    for spec in objects:
        marks = grid.used.setdefault(spec.object, {})
        for key in spec.sensors:
            for act in activations.get(key, ()):
                for day in _touched_dates(act.start, act.end, grid.offset, grid.window):
                    base = grid.bases.get(day)
                    if base is None or act.start >= base + grid.window or act.end < base:
                        continue
                    first = max(0, (act.start - base) // grid.step)
                    last = min(steps - 1, (act.end - base) // grid.step)
                    marks.setdefault(day, set()).update(range(first, last + 1))


def _test_count(kept: int, options: GridOptions) -> int:
    if options.test_days is not None:
        if kept and options.test_days >= kept:
            raise ConfigError(f"{options.test_days} test days would leave no training day ({kept} days kept)")
        return options.test_days
    share = int(kept * options.test_fraction)
    return share if kept < 2 or options.test_fraction == 0 else max(1, share)


def _prepare_dest(dest: Path) -> Path:
    """A fresh temporary folder beside ``dest``; ``dest`` itself must be new or empty, so that
    days of an earlier import never mix with these."""
    dest = Path(dest)
    if dest.exists() and (not dest.is_dir() or any(dest.iterdir())):
        raise DataError("already exists and is not an empty folder; import into a new folder", source=str(dest))
    try:
        dest.parent.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise DataError(f"cannot make the folder it goes in: {err.strerror or err}", source=str(dest)) from None
    for left in dest.parent.glob(f".{dest.name}.importing-*"):  # an import killed before it could clean up
        pid = left.name.rsplit("-", 1)[1]
        if not pid.isdigit() or int(pid) == os.getpid() or not _running(int(pid)):
            shutil.rmtree(left, ignore_errors=True)
    tmp = dest.parent / f".{dest.name}.importing-{os.getpid()}"
    try:
        tmp.mkdir()
    except OSError as err:
        raise DataError(f"cannot write beside it: {err.strerror or err}", source=str(dest)) from None
    return tmp


def _running(pid: int) -> bool:
    """Whether a process ``pid`` runs (an import under way keeps its folder)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    return True


def write_import(*, sensor_log: SensorLog, selection: ObjectSelection, options: GridOptions, dest: Path,
                 settings: dict[str, Any] | None = None) -> ImportResult:
    """Put ``sensor_log`` on the grid and write the household folder ``dest`` with its report.
    ``settings`` are the format's own options, recorded in the report."""
    options.check()
    if sensor_log.first is None or sensor_log.last is None:
        raise DataError("no records", source=sensor_log.sources[0])
    keep_to_the_log(sensor_log)
    try:
        return _write_import(sensor_log, selection, options, dest, settings)
    except OverflowError:  # the log runs up to the calendar's last days (9999): its days cannot be cut
        raise DataError(f"the log's times run to {sensor_log.last}: too near the calendar's end to cut into days",
                        source=", ".join(sensor_log.sources)) from None


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
    lo, hi = (_EPOCH + timedelta(seconds=float(times[parts[main]].min())),
              _EPOCH + timedelta(seconds=float(times[parts[main]].max())))
    where = sensor_log.stamp_sources, sensor_log.stamp_lines
    first = min((int(i) for p in stray for i in p), key=lambda i: (where[0][i], where[1][i]))
    line, source = where[1][first] or None, sensor_log.sources[where[0][first]]
    when = _EPOCH + timedelta(seconds=float(times[first]))
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
    sensor_log.first, sensor_log.last = lo, hi
    moments = np.frombuffer(sensor_log.moments, dtype=np.float64)
    keep = moments[(moments >= (lo - _EPOCH).total_seconds()) & (moments <= (hi - _EPOCH).total_seconds())]
    sensor_log.moments = array("d", keep.tolist())
    sensor_log.left_out = [{"source": sensor_log.sources[where[0][i]], "line": where[1][i],
                            "time": str(_EPOCH + timedelta(seconds=float(times[i])))}
                           for p in stray for i in p.tolist()]
    sensor_log.notes.append(f"{len(sensor_log.left_out)} records far outside the rest of the log ({lo} .. {hi}) left "
                            "out (--skip-bad-lines), with the annotations and sensor stretches reaching them: see "
                            "far_outside in the report")


def _write_import(sensor_log: SensorLog, selection: ObjectSelection, options: GridOptions, dest: Path,
                  settings: dict[str, Any] | None) -> ImportResult:
    objects = selection.objects()
    home = build_map(objects)
    ordered = check_overlaps(sensor_log.annotations, options.overlaps, error_field=sensor_log.annotation_field)
    kept, dropped = _choose_days(sensor_log, ordered, options)
    log.info("%s: %d days with annotations kept, %d dropped", sensor_log.format, len(kept), len(dropped))
    if not kept:
        reasons = Counter(d["why"].split(":")[0] for d in dropped)
        counts = ", ".join(f"{n} {why}" for why, n in reasons.items())
        raise DataError(f"no day to import: none of the {len(dropped)} days is both annotated and covered by the log "
                        f"from its first row ({_clock(options.day_start_minute)}) to its last "
                        f"({_clock(options.day_end_minute)}): {counts}", source=", ".join(sensor_log.sources))
    silent, limit_h = _silent_stretches(sensor_log, kept, options)
    if silent:
        n = len(silent)
        sensor_log.notes.append(f"{n} kept {'day has' if n == 1 else 'days have'} a stretch of {limit_h:.1f} hours or "
                                "more with no event from any sensor, far longer than the home's usual (a recorder "
                                "outage, or nobody home): see silent_stretches in the report")
    grid = _Grid(options, kept, {day: [IDLE] * options.steps for day in kept}, {})
    per_label = _place_annotations(grid, ordered)
    _place_uses(grid, objects, sensor_log.activations)
    n_test = _test_count(len(kept), options)
    dates = sorted(kept)
    splits = {"train": dates[:len(dates) - n_test], "test": dates[len(dates) - n_test:]}
    columns = tuple(spec.object for spec in objects)
    tmp = _prepare_dest(dest)
    try:
        write_nodes(tmp / "nodes.csv", home.nodes)
        for split, days in splits.items():
            (tmp / split).mkdir()
            for day in days:
                write_day(tmp / split / f"{day.isoformat()}.csv", _day(grid, day, columns, home, split), columns)
        report = _report(sensor_log, selection, objects, home, options, settings or {}, grid, per_label, splits,
                         dropped) | {"silent_stretches": silent, "far_outside": sensor_log.left_out}
        (tmp / REPORT_FILE).write_text(json.dumps(report, indent=2, ensure_ascii=False) + "\n", encoding="utf-8")
        if Path(dest).exists():
            Path(dest).rmdir()
        tmp.rename(dest)
    except OSError as err:  # a full disk, a folder made read-only: named as the folder asked for, not its draft
        shutil.rmtree(tmp, ignore_errors=True)
        raise DataError(f"cannot write the household folder: {err.strerror or err}", source=str(dest)) from None
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    log.info("%s: wrote %d train and %d test days to %s", sensor_log.format, len(splits["train"]), len(splits["test"]),
             dest)
    labels = tuple(sorted({a for row in grid.activities.values() for a in row}))
    return ImportResult(Path(dest), len(splits["train"]), len(splits["test"]), columns, labels, len(dropped),
                        Path(dest) / REPORT_FILE, tuple(sensor_log.notes))


def _silent_stretches(sensor_log: SensorLog, kept: dict[date, datetime], options: GridOptions
                      ) -> tuple[list[dict[str, str]], float]:
    """Each kept day's longest stretch of its rows with no event from any sensor, where it is far
    longer than the home's usual one (:data:`SILENCE_FACTOR` times the median day's longest, and
    at least :data:`SILENCE_NOTED`); and that limit in hours."""
    times = np.sort(np.frombuffer(sensor_log.moments, dtype=np.float64))
    window = options.step_minutes * options.steps * 60.0
    longest: dict[date, tuple[float, float, float]] = {}  # day -> (seconds, from, to)
    for day, base in kept.items():
        lo = (base - _EPOCH).total_seconds()
        inside = times[np.searchsorted(times, lo, side="right"):np.searchsorted(times, lo + window)]
        edges = np.concatenate(([lo], inside, [lo + window]))
        k = int(np.argmax(np.diff(edges)))
        longest[day] = (float(edges[k + 1] - edges[k]), float(edges[k]), float(edges[k + 1]))
    busy = [g for g, _, _ in longest.values() if g < window]  # days a sensor was heard on at all
    usual = float(np.median(busy)) if busy else 0.0
    limit = max(SILENCE_NOTED.total_seconds(), SILENCE_FACTOR * usual)
    silent = [{"date": day.isoformat(), "from": _clock_time(lo), "to": _clock_time(hi)}
              for day, (gap, lo, hi) in sorted(longest.items()) if gap >= limit]
    return silent, limit / 3600


def _clock_time(seconds: float) -> str:
    """A time of :attr:`SensorLog.moments` as the report writes times."""
    return f"{_EPOCH + timedelta(seconds=seconds):%Y-%m-%d %H:%M:%S}"


def _day(grid: _Grid, day: date, columns: tuple[str, ...], home: HomeMap, split: str) -> Day:
    options = grid.options
    minutes = tuple(options.day_start_minute + k * options.step_minutes for k in range(options.steps))
    marks = [grid.used.get(obj, {}).get(day, set()) for obj in columns]
    at_home = tuple(home.home_of[obj] for obj in columns)
    in_use = tuple(home.in_use_of[obj] for obj in columns)
    locations = tuple(tuple(in_use[i] if k in marks[i] else at_home[i] for i in range(len(columns)))
                      for k in range(options.steps))
    return Day(f"{split}/{day.isoformat()}", minutes, tuple(grid.activities[day]), locations,
               covering=_covering(grid, day))


def _covering(grid: _Grid, day: date) -> tuple[str, ...]:
    """Each row's activity covering most of its step (see the module doc)."""
    seconds = grid.step.total_seconds()
    out = []
    for k, start_label in enumerate(grid.activities[day]):
        shares = dict(grid.shares[day][k]) if day in grid.shares else {}
        shares[IDLE] = shares.get(IDLE, 0.0) + max(0.0, seconds - sum(shares.values()))
        out.append(max(shares, key=lambda a: (shares[a], a == start_label, a)))
    return tuple(out)


def _report(sensor_log: SensorLog, selection: ObjectSelection, objects: Sequence[ObjectSpec], home: HomeMap,
            options: GridOptions, settings: dict[str, Any], grid: _Grid, per_label: dict[str, _LabelStats],
            splits: dict[str, list[date]], dropped: list[dict[str, str]]) -> dict[str, Any]:
    rows = Counter(a for row in grid.activities.values() for a in row)
    activities = []
    for label in sorted(set(per_label) | set(rows)):
        stats = per_label.get(label, _LabelStats())
        activities.append({"activity": label, "from": sorted(stats.origins) or ["unannotated time"],
                           "annotations": stats.annotations, "rows": rows.get(label, 0),
                           "annotations_on_no_row": stats.on_no_row})
    object_rows = []
    for spec in objects:
        used = sum(len(steps) for steps in grid.used.get(spec.object, {}).values())
        object_rows.append({"object": spec.object, "sensors": list(spec.sensors),
                            "events": sum(sensor_log.events[k] for k in spec.sensors), "rows_in_use": used,
                            "home": home.home_of[spec.object], "in_use": home.in_use_of[spec.object], "why": spec.why})
    left_out = [{"sensor": key, "events": sensor_log.events[key], "why": choice.why}
                for key, choice in selection.choices.items() if choice.object is None]
    return {
        "format": sensor_log.format,
        "sources": list(sensor_log.sources),
        "grid": {"step_minutes": options.step_minutes, "day_start": _clock(options.day_start_minute),
                 "day_end": _clock(options.day_end_minute), "rows_per_day": options.steps,
                 "activity_rule": "the annotation covering the step's start; idle where none does",
                 "use_rule": "a sensor of the object fires or is on at any time inside the step",
                 "overlaps": options.overlaps},
        "settings": settings,
        "log_span": [f"{sensor_log.first:%Y-%m-%d %H:%M:%S}", f"{sensor_log.last:%Y-%m-%d %H:%M:%S}"],
        "objects": object_rows,
        "sensors_left_out": left_out,
        "objects_rule": (f"the mapping {selection.mapping.source}" if selection.mapping is not None
                         else selection.default_help),
        "activities": activities,
        "days": {split: [d.isoformat() for d in days] for split, days in splits.items()},
        "dropped_days": dropped,
        "notes": list(sensor_log.notes),
    }
