"""Every sensor of a home, kept beside its days: what activity recognition reads.

A household folder may carry, besides its map and day files, the raw record of the home's ambient
sensors (motion, doors, contacts, pressure mats, flushes, appliances), so that a home nobody
labels can have its activities recognised (:mod:`globe.recognition`):

- ``sensors.csv``: one row per sensor, ``sensor,type,room,object``: the log's own name for it, its
  kind in one lowercase word (:data:`SENSOR_TYPES` are the usual ones; any other word is kept), the
  room it is in (empty: unknown) and the object column it feeds (empty: none).
- ``events/<day>.csv``: one row per activation during the day whose file has the same name
  (``train/2010-11-04.csv`` -> ``events/2010-11-04.csv``), ``sensor,start,end``: seconds after
  the day's midnight, a firing with ``end == start``. An activation is cut to the span the day's
  rows cover (its first row's minute to its last row's minute plus one step), so a row past
  midnight is read from seconds past 86400.

- ``unlabelled/<day>.csv``: the days the sensors recorded and nobody annotated (``globe data
  import`` keeps them, ``--unlabelled keep``): a day file without its activity column (``minute``
  and the object columns), so that nothing expecting labels reads one by accident; their
  activations are in ``events/`` as any day's. :func:`read_unlabelled_days` reads them (their
  activities empty) for the recogniser to learn from and label (``globe recognise --label``).

Days without an events file are days the sensors were not recorded; a folder without
``sensors.csv`` has no sensors at all. Both files are checked when read (file, line and field):
:func:`load_sensor_data` also checks that each events file has its day file, and
:func:`check_sensor_data` (``globe data validate``) that its activations lie in its day's span and
that the objects named are the household's object columns.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Collection, Iterable, Mapping, Sequence

import numpy as np

from globe.data.csv_logs import (
    _child,
    _csv_line,
    _label,
    _ragged,
    _read_text,
    _write_atomic,
    check_step,
    csv_table,
    day_files,
    format_day,
    household_step,
    map_rules,
    parse_day_text,
)
from globe.data.locate import household_dir
from globe.data.records import Day, Household
from globe.errors import DataError

SENSORS_FILE, EVENTS_FOLDER, UNLABELLED_FOLDER = "sensors.csv", "events", "unlabelled"
SENSOR_TYPES = ("motion", "door", "contact", "pressure", "flush", "appliance", "power", "light", "temperature",
                "other")
"""The kinds of sensor the importers name (CASAS M/D/T..., van Kasteren's reed switches, pressure
mats and float sensors, Home Assistant's device classes)."""
_TYPE = re.compile(r"[a-z][a-z0-9_]*")
_SECONDS_LIMIT = 3 * 86400  # a day's events lie within its own span: never past its third midnight


@dataclass(frozen=True, slots=True)
class Sensor:
    """One sensor of the home: its name in the log, kind, room and the object it feeds (if any)."""

    name: str
    type: str = "other"
    room: str = ""
    object: str = ""


@dataclass(frozen=True, slots=True, eq=False)
class SensorDay:
    """One day's activations: parallel arrays, sorted by start; ``sensor`` indexes the home's
    :attr:`SensorData.sensors`; ``start``/``end`` are seconds after the day's midnight."""

    name: str
    sensor: np.ndarray
    start: np.ndarray
    end: np.ndarray

    def __len__(self) -> int:
        return len(self.sensor)

    @classmethod
    def of(cls, name: str, rows: Iterable[tuple[int, float, float]]) -> "SensorDay":
        """From (sensor index, start, end) rows in any order."""
        ordered = sorted(rows, key=lambda r: (r[1], r[2], r[0]))
        return cls(name, np.array([r[0] for r in ordered], dtype=np.int64),
                   np.array([r[1] for r in ordered], dtype=np.float64),
                   np.array([r[2] for r in ordered], dtype=np.float64))


@dataclass(frozen=True, slots=True)
class SensorData:
    """A home's sensors and the activations of each day that has them, by day-file stem."""

    sensors: tuple[Sensor, ...]
    days: Mapping[str, SensorDay]

    def of(self, day_name: str) -> SensorDay | None:
        """The activations of the day named ``day_name`` (``train/2010-11-04`` or its stem), if recorded."""
        return self.days.get(day_stem(day_name))

    def recorded(self, days: Sequence[Day]) -> list[Day]:
        """Those of ``days`` whose activations were recorded (the only ones a recogniser can read)."""
        return [d for d in days if self.of(d.name) is not None]

    def index(self, name: str) -> int:
        for i, sensor in enumerate(self.sensors):
            if sensor.name == name:
                return i
        raise KeyError(name)


def day_stem(day_name: str) -> str:
    """``train/2010-11-04`` or ``2010-11-04.csv`` -> ``2010-11-04``: how events files are named."""
    return day_name.rsplit("/", 1)[-1].removesuffix(".csv")


def parse_sensors_text(text: str, source: str, objects: Collection[str] | None = None) -> tuple[Sensor, ...]:
    """The rows of ``sensors.csv``; with ``objects`` (the household's object columns), an object
    named that is not one of them is an error."""
    rows, header = csv_table(text, source, ("sensor", "type"))
    col = {name: i for i, name in enumerate(header)}
    out: list[Sensor] = []
    seen: dict[str, int] = {}
    for line, row in rows[1:]:
        if len(row) != len(header):
            raise _ragged(source, line, row, header)

        def cell(field: str, row: list[str] = row) -> str:
            i = col.get(field)
            return row[i].strip() if i is not None and i < len(row) else ""
        name, kind = _label(cell("sensor"), source, line, "sensor", "sensor name"), cell("type").lower() or "other"
        if name in seen:
            raise DataError(f"sensor {name!r} is listed twice (first on line {seen[name]})", source=source, line=line,
                            field="sensor")
        if not _TYPE.fullmatch(kind):
            raise DataError(f"sensor type {kind!r}: expected one lowercase word such as {', '.join(SENSOR_TYPES[:5])}",
                            source=source, line=line, field="type")
        room, obj = cell("room"), cell("object")
        if room:
            _label(room, source, line, "room", "room")
        if obj:
            _label(obj, source, line, "object", "object")
            if objects is not None and obj not in objects:
                raise DataError(f"object {obj!r} is not an object column of the household (see nodes.csv)",
                                source=source, line=line, field="object")
        seen[name] = line
        out.append(Sensor(name, kind, room, obj))
    return tuple(out)


def parse_events_text(text: str, sensors: Sequence[Sensor], name: str, source: str,
                      span: tuple[float, float] | None = None) -> SensorDay:
    """One ``events/<day>.csv``; with ``span`` (seconds after midnight: the day's first row and
    its last row's end), an activation outside it is an error."""
    rows, header = csv_table(text, source, ("sensor", "start", "end"))
    index = {s.name: i for i, s in enumerate(sensors)}
    col = {name: i for i, name in enumerate(header)}
    out: list[tuple[int, float, float]] = []
    for line, row in rows[1:]:
        if len(row) != len(header):
            raise _ragged(source, line, row, header)
        cells = {f: row[col[f]].strip() if col[f] < len(row) else "" for f in ("sensor", "start", "end")}
        code = index.get(cells.get("sensor", ""))
        if code is None:
            raise DataError(f"sensor {cells.get('sensor', '')!r} is not in {SENSORS_FILE}", source=source, line=line,
                            field="sensor")
        times = []
        for field in ("start", "end"):
            try:
                value = float(cells.get(field, ""))
            except ValueError:
                raise DataError(f"{cells.get(field, '')!r} is not a number of seconds", source=source, line=line,
                                field=field) from None
            if not 0.0 <= value <= _SECONDS_LIMIT:
                raise DataError(f"{value:g} seconds after the day's midnight: outside the day", source=source,
                                line=line, field=field)
            times.append(value)
        if times[1] < times[0]:
            raise DataError(f"ends ({times[1]:g}) before it starts ({times[0]:g})", source=source, line=line,
                            field="end")
        if span is not None:
            for field, value in zip(("start", "end"), times):
                if not span[0] <= value <= span[1]:
                    raise DataError(f"{value:g} seconds after midnight is outside the day's span {span[0]:g}.."
                                    f"{span[1]:g} (its first row to its last row's end)", source=source, line=line,
                                    field=field)
        out.append((code, times[0], times[1]))
    return SensorDay.of(name, out)


Spans = Mapping[str, tuple[float, float] | None]
"""Day-file stems -> the day's span in seconds after midnight (None: not checked)."""


def read_sensor_data(root: Path, *, days: Spans | None = None,
                     objects: Collection[str] | None = None) -> SensorData | None:
    """The sensors of the household folder ``root`` and their activations, or None without a
    ``sensors.csv`` (names matched ignoring case, as ``nodes.csv``). Every ``*.csv`` of
    ``events/`` is read; with ``days`` (the household's day stems and spans), an events file of no
    day, or an activation outside its day's span, is an error; with ``objects``, an object of
    ``sensors.csv`` that is not one of them."""
    root = Path(root)
    listing = _child(root, SENSORS_FILE, want_dir=False)
    folder = _child(root, EVENTS_FOLDER, want_dir=True)
    if listing is None:
        if folder is not None:
            raise DataError(f"an events folder without {SENSORS_FILE} (the sensors its files name)", source=str(folder))
        return None
    sensors = parse_sensors_text(_read_text(listing), str(listing), objects)
    found: dict[str, SensorDay] = {}
    for path in day_files(folder) if folder is not None else []:
        stem = path.stem
        if days is not None and stem not in days:
            raise DataError(f"no day file train/{stem}.csv or test/{stem}.csv (nor {UNLABELLED_FOLDER}/{stem}.csv) "
                            "for these events (an events file belongs to the day of its name)", source=str(path))
        found[stem] = parse_events_text(_read_text(path), sensors, stem, str(path),
                                        days.get(stem) if days is not None else None)
    return SensorData(sensors, found)


def load_sensor_data(root: Path, name: str) -> SensorData | None:
    """The sensors of household ``name`` under ``root`` (the folder :func:`load_household`
    reads), or None when it has none: each events file must have its day file. The spans are
    checked by :func:`check_sensor_data`, which needs the loaded days."""
    folder = household_dir(Path(root), name)
    stems: dict[str, tuple[float, float] | None] = {}
    for split in ("train", "test", UNLABELLED_FOLDER):
        sub = _child(folder, split, want_dir=True)
        stems.update({path.stem: None for path in (day_files(sub) if sub is not None else [])})
    return read_sensor_data(folder, days=stems)


def day_span(minutes: Sequence[int], step_minutes: int) -> tuple[float, float]:
    """The seconds after midnight a day's rows cover: its first row to its last row plus one step."""
    return minutes[0] * 60.0, (minutes[-1] + step_minutes) * 60.0


def check_sensor_data(household: Household, step_minutes: int | None = None,
                      unlabelled: Sequence[Day] | None = None) -> SensorData | None:
    """The loaded ``household``'s sensors, every rule checked (``globe data validate``): the
    files' own, each events file's day, its activations within that day's span (``step_minutes``:
    the household's step, else the most common gap between its rows) and the objects named. The
    unlabelled days are ``unlabelled`` when the caller has read them, else read (and checked) here."""
    step = step_minutes or household_step(household.train + household.test) or 0
    if unlabelled is None:
        unlabelled = read_unlabelled_days(household, step or None)
    days = household.train + household.test + tuple(unlabelled)
    spans = {day_stem(d.name): day_span(d.minutes, step) for d in days if d.minutes}
    return read_sensor_data(Path(household.source), days=spans, objects=household.objects)


def format_sensors(sensors: Iterable[Sensor]) -> str:
    lines = [_csv_line(("sensor", "type", "room", "object"))]
    lines += [_csv_line((s.name, s.type, s.room, s.object)) for s in sensors]
    return "\n".join(lines) + "\n"


def format_events(day: SensorDay, sensors: Sequence[Sensor]) -> str:
    """A day's events as written (each sensor's name quoted once, as ``csv.writer`` would; the
    seconds never need quoting)."""
    names = [_csv_line((s.name,)) for s in sensors]
    lines = [_csv_line(("sensor", "start", "end"))]
    for code, start, end in zip(day.sensor.tolist(), day.start.tolist(), day.end.tolist()):
        lines.append(f"{names[code]},{_seconds(start)},{_seconds(end)}")
    return "\n".join(lines) + "\n"


def _seconds(value: float) -> str:
    """Seconds as written: whole ones bare, else to the millisecond (``25.5``, never ``25.``)."""
    text = f"{value:.3f}".rstrip("0").rstrip(".")
    return "0" if text == "-0" else text


def write_sensor_data(root: Path, data: SensorData) -> None:
    """Write ``sensors.csv`` and one ``events/<stem>.csv`` per day into the folder ``root``."""
    _write_atomic(root / SENSORS_FILE, format_sensors(data.sensors))
    folder = root / EVENTS_FOLDER
    folder.mkdir(parents=True, exist_ok=True)
    for stem, day in sorted(data.days.items()):
        _write_atomic(folder / f"{stem}.csv", format_events(day, data.sensors))


def read_unlabelled_days(household: Household, step_minutes: int | None = None) -> tuple[Day, ...]:
    """The loaded ``household``'s unlabelled days (``unlabelled/<day>.csv``, named
    ``unlabelled/<stem>``), checked as day files are (its objects and places, the step:
    ``step_minutes``, else the household's), their activities empty; none without the folder. A
    date that is also a labelled day is an error: one day, one file."""
    folder = Path(household.source)
    sub = _child(folder, UNLABELLED_FOLDER, want_dir=True) if folder.is_dir() else None
    if sub is None:
        return ()
    locations, owners = map_rules(household.nodes)
    labelled = {day_stem(d.name) for d in household.train + household.test}
    step = step_minutes or household_step(household.train + household.test)
    out = []
    for path in day_files(sub):
        if path.stem in labelled:
            raise DataError(f"{path.stem} is also a labelled day (train/ or test/): one day, one file",
                            source=str(path))
        day, lines = parse_day_text(_read_text(path), household.objects, locations,
                                    f"{UNLABELLED_FOLDER}/{path.stem}", str(path), owners, labelled=False)
        out.append(check_step(day, lines, step) if step else day)
    return tuple(out)


def write_unlabelled_day(root: Path, day: Day, objects: tuple[str, ...]) -> None:
    """Write ``day`` as ``unlabelled/<stem>.csv`` of the household folder ``root``, without its
    activities (see the module doc)."""
    _write_atomic(Path(root) / UNLABELLED_FOLDER / f"{day_stem(day.name)}.csv",
                  format_day(day, objects, labelled=False))
