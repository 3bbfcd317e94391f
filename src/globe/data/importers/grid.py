"""Put a smart home's timestamped record on GLOBE's step grid and write it as a household folder.

Every importer reads its format into one :class:`~globe.data.importers.sensor_log.SensorLog`
(annotated activity intervals, and when each object sensor fired or was on) and hands it here, so
that the rules below hold for every format and are written once (the options are
:class:`~globe.data.importers.options.GridOptions`):

- A day of date D has one row at each minute ``day_start + k * step`` up to ``day_end``
  (06:00, 06:10, ..., 24:00 by default, as HOMER+); the row at minute m stands for the step
  ``[m, m + step)``. Event times never add rows.
- A row's activity is the annotation covering the step's *start* (the current convention of the
  CSV logs); a step no annotation covers is ``idle``. Its ``covering`` cell is the activity that
  covers most of the step (``idle`` for time no annotation covers; ties: the row's activity, then
  the name), so a use can be credited to it (``sequences.alignment = "most"``). Annotations may
  not overlap, unless ``overlaps="latest"``: then the one that began last wins while it lasts
  (ties: the later line).
- An object's *uses* (:mod:`globe.data.importers.uses`) are its sensors' activations
  (:class:`~globe.data.importers.sensor_log.Activation`), those that overlap or touch merged into
  one (the sensor, or another of the object's, never went off between: one use). With
  ``use="while-on"`` (the default) the object is in use in every step a use reaches (a sensor
  of it fires, or is on, at any time inside the step); with ``use="start"`` only in the
  step the use begins in, and home again from the next step on. Either way a use is one move
  *into* the ``in_use`` place, which is all the evaluation counts (returns home are no uses);
  ``while-on`` also shows how long the object is busy, which the fetch rule reads (it never
  fetches an object in use). Uses beginning in consecutive steps read as one stay there: the
  grid has no step between to go home in. An object's cell is its room's ``in_use`` place in the
  steps it is in use, its home place in the others.
- A sensor left on: an activation far longer than its object's usual is cut to a firing (it
  marks the step it began in only, as with ``use="start"``) and listed in the report
  (``left_on``). The limit, per object from all of its activations in the log (after the
  records far outside it are left out), is ``max_use_minutes`` when given, else the rule of
  :mod:`globe.data.importers.uses` (a multiple of the 99th percentile or the median of the
  object's activations; never under two steps or an hour: an oven on for a stew is a use).
- A day with no annotation at all is left out, and so is a day on whose date no annotation
  begins and whose annotations end before its last row (one carried over from the day before is
  all it has: annotating stopped, or the recorder was down; a day one annotation covers whole,
  a day away, is kept), and a day the log does not cover from its first step to its last (the
  log's first and last days, usually). All are listed in the report.
- A day with no annotation at all on which a sensor was heard (a record inside its rows' span) is
  an *unlabelled* day: with ``unlabelled="keep"`` (``--unlabelled keep``, the default) it is
  written to ``unlabelled/<date>.csv`` (its rows and object cells, no activity column:
  :mod:`globe.data.sensors`) with its ``events/<date>.csv``, listed in the report
  (``unlabelled_days``), never a training or test day; with ``drop`` it is left out as above.
  Recognition learns from such days and labels them (``globe recognise --label``).
- A kept day whose longest stretch without an event from any sensor is far longer than the
  home's usual (1.5 times the median longest of the days a sensor was heard on, and 6 hours at
  least: :mod:`globe.data.importers.report`) is listed in the report (``silent_stretches``): a
  recorder outage, or nobody home.
- A line that breaks its format's rules is an error naming its file, line and field, or, with
  ``skip_bad_lines`` (``--skip-bad-lines``), left out and listed in the report (``bad_lines``):
  every reader hands such errors to :meth:`~globe.data.importers.sensor_log.SensorLog.bad`.
- A record far outside the rest of the log (a corrupt timestamp: a year 9999 or 0001, an end
  dated years late; see :data:`~globe.data.importers.sensor_log.FAR_GAP`) is an error naming its
  line, or, with ``--skip-bad-lines``, left out with the annotations and sensor stretches reaching
  it and listed in the report (``far_outside``).
- Days after ``until`` are left out (listed, why: ``after --until``). The kept days from
  ``test_from`` on are test days; without it, the last ``test_days`` kept days (default: the last
  20 %, at least one when two or more days are kept); the rest are training days.

The folder is written through :mod:`globe.data.csv_logs` (the writer of the shipped files) into a
temporary sibling and renamed into place, with ``import.json``
(:mod:`globe.data.importers.report`): which sensor became which object column, which annotation
which activity, which days were dropped and why. Every sensor the log kept, objects or not, is
written beside the days too: ``sensors.csv`` and one ``events/<day>.csv`` per kept day, named as
its day file (:mod:`globe.data.importers.events`, :mod:`globe.data.sensors`), counted by type in
the report's ``sensors`` section.
"""

from __future__ import annotations

import logging
import os
import shutil
from collections import Counter
from dataclasses import dataclass, field
from datetime import date, datetime, time, timedelta
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from globe.data.csv_logs import write_day, write_nodes
from globe.data.importers.events import sensor_data
from globe.data.importers.objects import HomeMap, ObjectSelection, build_map
from globe.data.importers.options import GridOptions, Overlaps, clock
from globe.data.importers.report import REPORT_FILE, LabelStats, build_report, silent_stretches, write_report
from globe.data.importers.sensor_log import EPOCH, Annotation, SensorLog, keep_to_the_log
from globe.data.importers.text import RESIDENT, show
from globe.data.importers.uses import ObjectUses, find_uses
from globe.data.records import Day
from globe.data.sensors import write_sensor_data, write_unlabelled_day
from globe.errors import ConfigError, DataError

log = logging.getLogger(__name__)

IDLE = "idle"


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
    bad_lines: int = 0  # lines left out (--skip-bad-lines), listed in the report
    left_on: int = 0  # uses cut to a firing (a sensor left on), listed in the report
    first_bad_line: str = ""  # the first of them, for the command line
    unlabelled_days: int = 0  # days with sensor records and no annotation, written to unlabelled/


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
                whose = {m.group(1).upper() for a in (ann, longest) if (m := RESIDENT.fullmatch(a.activity))}
                hint = f"; a log of {len(whose)} residents: --resident {min(whose)} (CASAS) takes one person's" \
                    if len(whose) > 1 else ""
                raise DataError(f"{show(ann.activity)} begins at {ann.start} while {show(longest.activity)} (line "
                                f"{longest.line}) lasts until {longest.end}: annotations may not overlap (one person, "
                                f"one activity; --overlaps latest lets the later one win while it lasts{hint})",
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
                 ) -> tuple[dict[date, datetime], dict[date, datetime], list[dict[str, str]]]:
    """The kept days (date -> first step's start), the unlabelled ones kept (the same) and the
    dropped ones with why."""
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
    unlabelled: dict[date, datetime] = {}
    dropped: list[dict[str, str]] = []
    heard = np.sort(np.frombuffer(sensor_log.moments, dtype=np.float64))
    for day in _day_dates(sensor_log.first, sensor_log.last):
        midnight = datetime.combine(day, time())
        if options.until is not None and day > options.until:
            why = f"after --until {options.until}"
        elif sensor_log.first > midnight + offset:
            why = (f"partial: the log starts at {sensor_log.first:%Y-%m-%d %H:%M:%S}, after this day's first row "
                   f"({clock(options.day_start_minute)})")
        elif sensor_log.last < midnight + last_row:
            why = (f"partial: the log ends at {sensor_log.last:%Y-%m-%d %H:%M:%S}, before this day's last row "
                   f"({clock(options.day_end_minute)})")
        elif day not in annotated:
            lo = (midnight + offset - EPOCH).total_seconds()
            span = np.searchsorted(heard, [lo, lo + window.total_seconds()])
            if options.unlabelled == "keep" and span[0] < span[1]:  # a sensor was heard: the recorder was up
                unlabelled[day] = midnight + offset
                continue
            why = "no annotation"  # and, unless --unlabelled drop, no sensor record
        elif day not in begun:
            why = ("no annotation begins on it: it only carries one over from the day before, which ends before "
                   "its last row (annotating stopped, or the log has a gap)")
        else:
            kept[day] = midnight + offset
            continue
        dropped.append({"date": day.isoformat(), "why": why})
    return kept, unlabelled, dropped


def _place_annotations(grid: _Grid, ordered: Sequence[Annotation]) -> dict[str, LabelStats]:
    """Each kept row's activity: the annotation covering its start; later starts overwrite
    earlier ones, which is the ``latest`` rule (without overlaps, nothing is overwritten)."""
    per_label: dict[str, LabelStats] = {}
    steps = grid.options.steps
    for ann in ordered:
        stats = per_label.setdefault(ann.activity, LabelStats())
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


def _place_uses(grid: _Grid, uses: dict[str, ObjectUses]) -> None:
    """Mark the steps each object is in use in: those its uses reach (``while-on``), or those
    they begin in (``start``)."""
    steps = grid.options.steps
    for obj, found in uses.items():
        marks = grid.used.setdefault(obj, {})
        for start, end in found.spans:
            end = start if grid.options.use == "start" else end
            for day in _touched_dates(start, end, grid.offset, grid.window):
                base = grid.bases.get(day)
                if base is None or start >= base + grid.window or end < base:
                    continue
                first = max(0, (start - base) // grid.step)
                last = min(steps - 1, (end - base) // grid.step)
                marks.setdefault(day, set()).update(range(first, last + 1))


def _split(dates: list[date], options: GridOptions) -> dict[str, list[date]]:
    """The kept days (in order) as training and test days."""
    if options.test_from is not None:
        at = sum(d < options.test_from for d in dates)
        span = f"the kept days run {dates[0]} .. {dates[-1]}"
        if at == 0:
            raise ConfigError(f"--test-from {options.test_from} leaves no training day ({span})")
        if at == len(dates):
            raise ConfigError(f"--test-from {options.test_from} leaves no test day ({span})")
        return {"train": dates[:at], "test": dates[at:]}
    n_test = _test_count(len(dates), options)
    return {"train": dates[:len(dates) - n_test], "test": dates[len(dates) - n_test:]}


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
    if sensor_log.bad_lines:
        log.warning("%s: %d lines left out (--skip-bad-lines), the first: %s", sensor_log.format,
                    len(sensor_log.bad_lines), sensor_log.bad_lines[0])
    try:
        return _write_import(sensor_log, selection, options, dest, settings)
    except OverflowError:  # the log runs up to the calendar's last days (9999): its days cannot be cut
        raise DataError(f"the log's times run to {sensor_log.last}: too near the calendar's end to cut into days",
                        source=", ".join(sensor_log.sources)) from None


def _write_import(sensor_log: SensorLog, selection: ObjectSelection, options: GridOptions, dest: Path,
                  settings: dict[str, Any] | None) -> ImportResult:
    objects = selection.objects()
    home = build_map(objects)
    ordered = check_overlaps(sensor_log.annotations, options.overlaps, error_field=sensor_log.annotation_field)
    kept, unlabelled, dropped = _choose_days(sensor_log, ordered, options)
    log.info("%s: %d days with annotations kept, %d unlabelled kept, %d dropped", sensor_log.format, len(kept),
             len(unlabelled), len(dropped))
    if not kept:
        reasons = Counter(d["why"].split(":")[0] for d in dropped)
        counts = ", ".join([f"{n} {why}" for why, n in reasons.items()]
                           + ([f"{len(unlabelled)} with sensor records and no annotation (GLOBE learns activity names "
                               "from a few labelled days: annotate one or more)"] if unlabelled else []))
        raise DataError(f"no day to import: none of the {len(dropped) + len(unlabelled)} days is both annotated and "
                        f"covered by the log from its first row ({clock(options.day_start_minute)}) to its last "
                        f"({clock(options.day_end_minute)}): {counts}", source=", ".join(sensor_log.sources))
    silent, limit_h = silent_stretches(sensor_log, kept, options)
    if silent:
        n = len(silent)
        sensor_log.notes.append(f"{n} kept {'day has' if n == 1 else 'days have'} a stretch of {limit_h:.1f} hours or "
                                "more with no event from any sensor, far longer than the home's usual (a recorder "
                                "outage, or nobody home): see silent_stretches in the report")
    every = {**kept, **unlabelled}  # unlabelled days: their object cells and events, no activity
    grid = _Grid(options, every, {day: [IDLE] * options.steps for day in every}, {})
    per_label = _place_annotations(grid, ordered)
    uses = {spec.object: find_uses(spec, sensor_log.activations, options) for spec in objects}
    _place_uses(grid, uses)
    left_on = [row for found in uses.values() for row in found.left_on]
    sensors, sensors_report = sensor_data(sensor_log, selection, uses, every, options)
    activities = {day: grid.activities[day] for day in kept}
    used = {obj: {day: steps for day, steps in marks.items() if day in kept} for obj, marks in grid.used.items()}
    splits = _split(sorted(kept), options)
    columns = tuple(spec.object for spec in objects)
    tmp = _prepare_dest(dest)
    try:
        write_nodes(tmp / "nodes.csv", home.nodes)
        for split, days in splits.items():
            (tmp / split).mkdir()
            for day in days:
                write_day(tmp / split / f"{day.isoformat()}.csv", _day(grid, day, columns, home, split), columns)
        for day in sorted(unlabelled):
            write_unlabelled_day(tmp, _day(grid, day, columns, home, "unlabelled"), columns)
        if sensors is not None:
            write_sensor_data(tmp, sensors)
        report = build_report(sensor_log, selection, objects, home, options, settings or {}, activities,
                              used, per_label, splits, dropped, uses, silent, left_on)
        report["sensors"] = sensors_report
        report["grid"]["unlabelled"] = options.unlabelled
        report["unlabelled_days"] = [day.isoformat() for day in sorted(unlabelled)]
        write_report(tmp, report)
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
    labels = tuple(sorted({a for row in activities.values() for a in row}))
    bad = sensor_log.bad_lines
    return ImportResult(Path(dest), len(splits["train"]), len(splits["test"]), columns, labels, len(dropped),
                        Path(dest) / REPORT_FILE, tuple(sensor_log.notes), bad_lines=len(bad), left_on=len(left_on),
                        first_bad_line=str(bad[0]) if bad else "", unlabelled_days=len(unlabelled))


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
