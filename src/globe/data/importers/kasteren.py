"""Importer of interval logs in the van Kasteren / Ordóñez format.

Two files, one interval a line, fields separated by spaces or tabs: sensor intervals (when each
sensor was on) and activity intervals (what the person did)::

    # van Kasteren (kasterenSenseData.txt, kasterenActData.txt): numeric ids
    25-Feb-2008 09:33:41    25-Feb-2008 09:33:42    7    1
    25-Feb-2008 09:33:41    25-Feb-2008 09:43:10    13
    # Ordóñez (OrdonezA_Sensors.txt, OrdonezA_ADLs.txt): sensors as 'Location Type Place'
    2011-11-28 02:27:59    2011-11-28 10:18:11    Bed    Pressure    Bedroom
    2011-11-28 02:27:59    2011-11-28 10:18:11    Sleeping

Times are ``YYYY-MM-DD HH:MM:SS`` or ``DD-Mon-YYYY HH:MM:SS``. Lines before the first record
that do not begin with a digit are a header (Ordóñez has two); after it, every line is a record.
A van Kasteren sensor line is ``start end id [1]``; its names come from a sensor list (CSV
``sensor,name`` and, optionally, ``type`` and ``room``), and every id must be in it when one is
given. Activity ids become labels through an activity list (CSV ``id,activity``) when given.

Without a mapping, a sensor of type Magnetic, Contact, Reed or Electric (a contact on a cupboard
or the fridge, a switched appliance) is an object, named after its location or name, in its place
(room), unless its name says it is a door; PIR (motion), Pressure, Flush and sensors of unknown
type stay out.
"""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path

from globe.data.csv_logs import _label, csv_table
from globe.data.importers.grid import Activation, Annotation, GridOptions, ImportResult, SensorLog, write_import
from globe.data.importers.objects import ObjectSelection, Sensor, read_mapping
from globe.data.importers.text import (
    parse_date_time,
    parse_day_month_year,
    read_lines,
    read_text,
    show,
    table_cells,
)
from globe.errors import DataError

log = logging.getLogger(__name__)

OBJECT_TYPES = frozenset({"magnetic", "contact", "reed", "electric"})
DEFAULT_RULE = ("sensors of type Magnetic, Contact, Reed or Electric are objects unless their name says 'door'; "
                "other types (PIR, Pressure, Flush, ...) and sensors of unknown type are not")
_RECORD = re.compile(r"\s*(\S+)\s+(\S+)\s+(\S+)\s+(\S+)(?:\s+(.*?))?\s*")
_ISO_DAY = re.compile(r"\d{4}-\d{2}-\d{2}")


@dataclass(frozen=True, slots=True)
class Interval:
    """One record: ``[start, end]`` and what follows the two times."""

    line: int
    start: datetime
    end: datetime
    rest: tuple[str, ...]


def _time(date: str, clock: str, source: str, line: int, field: str) -> datetime:
    if _ISO_DAY.fullmatch(date):
        return parse_date_time(date, clock, source=source, line=line, date_field=field, time_field=field)
    return parse_day_month_year(date, clock, source=source, line=line, field=field)


def read_intervals(path: Path) -> tuple[list[Interval], int]:
    """The records of an interval file and how many header lines came before them."""
    source = str(path)
    records: list[Interval] = []
    header = 0
    for line, text in read_lines(path):
        if not records and not text.lstrip()[:1].isdigit():
            header += 1
            continue
        match = _RECORD.fullmatch(text)
        if match is None:
            raise DataError("not a record (expected 'start date, start time, end date, end time, ...')", source=source,
                            line=line, field="start")
        start = _time(match.group(1), match.group(2), source, line, "start")
        end = _time(match.group(3), match.group(4), source, line, "end")
        if end < start:
            raise DataError(f"ends at {end}, before it starts at {start}", source=source, line=line, field="end")
        rest = tuple((match.group(5) or "").split())
        if not rest:
            raise DataError("nothing after the two times", source=source, line=line, field="sensor")
        records.append(Interval(line, start, end, rest))
    if not records:
        raise DataError(f"no records (only {header} header line{'s' if header > 1 else ''})", source=source, line=1)
    return records, header


def read_sensor_list(path: Path) -> dict[str, Sensor]:
    """A van Kasteren sensor list: CSV ``sensor,name[,type][,room]``, one sensor a row."""
    source = str(path)
    rows, header = csv_table(read_text(Path(path)), source, ("sensor", "name"))
    unknown = [h for h in header if h not in ("sensor", "name", "type", "room")]
    if unknown:
        raise DataError("unknown column (a sensor list has sensor, name, and optionally type, room)", source=source,
                        line=1, field=unknown[0])
    sensors: dict[str, Sensor] = {}
    for line, cell in table_cells(rows, header, source):
        key = _label(cell["sensor"], source, line, "sensor", "sensor id")
        if key in sensors:
            raise DataError(f"sensor {show(key)} is listed twice", source=source, line=line, field="sensor")
        name = _label(cell["name"], source, line, "name", "sensor name")
        sensors[key] = Sensor(key, name, cell.get("type", ""), cell.get("room", ""))
    return sensors


def read_activity_list(path: Path) -> dict[str, str]:
    """Activity ids to labels: CSV ``id,activity``."""
    source = str(path)
    rows, header = csv_table(read_text(Path(path)), source, ("id", "activity"))
    labels: dict[str, str] = {}
    for line, cell in table_cells(rows, header, source):
        key = _label(cell["id"], source, line, "id", "activity id")
        if key in labels:
            raise DataError(f"activity id {show(key)} is listed twice", source=source, line=line, field="id")
        labels[key] = _label(cell["activity"], source, line, "activity", "activity")
    return labels


def default_rule(sensor: Sensor) -> tuple[bool, str]:
    """Contact and electric sensors are objects, doors and the rest are not (see the module)."""
    kind = sensor.kind.lower()
    if not kind:
        return False, "no sensor type known (map it with --objects, or give the sensor list a type column)"
    if kind not in OBJECT_TYPES:
        return False, (f"sensor type {sensor.kind!r}: not a thing a robot can fetch (map it with --objects to "
                       "include it)")
    if "door" in sensor.name.lower():
        return False, "a door: not a thing a robot can fetch (map it with --objects to include it)"
    return True, f"sensor type {sensor.kind!r}: a contact on something opened, or a switched appliance"


def _sensor_of(record: Interval, named: dict[str, Sensor] | None, source: str) -> Sensor:
    """The sensor of a record: 'Location Type Place' (Ordóñez) or 'id [1]' (van Kasteren)."""
    if len(record.rest) == 3:
        if named is not None:
            raise DataError("this log names its sensors itself ('Location Type Place'): leave out --sensor-list",
                            source=source, line=record.line, field="sensor")
        location, kind, place = record.rest
        return Sensor(" ".join(record.rest), location, kind, place)
    if len(record.rest) > 3:
        raise DataError(f"{len(record.rest)} fields after the times; expected 'id [1]' or 'Location Type Place'",
                        source=source, line=record.line, field="sensor")
    if len(record.rest) == 2 and record.rest[1] != "1":
        raise DataError(f"{show(record.rest[1])} is not 1 (a record is an interval in which the sensor was on)",
                        source=source, line=record.line, field="value")
    key = record.rest[0]
    if named is None:
        return Sensor(key, key, "", "")
    sensor = named.get(key)
    if sensor is None:
        raise DataError(f"unknown sensor {show(key)} (not in the sensor list)", source=source, line=record.line,
                        field="sensor")
    return sensor


def _header_note(source: str, lines: int) -> str:
    return f"{source}: skipped {lines} header line{'s' if lines > 1 else ''} before the first record"


def read_kasteren(sensors_file: Path, activities_file: Path, selection: ObjectSelection, *,
                  sensor_list: Path | None = None, activity_list: Path | None = None) -> SensorLog:
    """Both files of an interval log, checked line by line, as one :class:`SensorLog`."""
    named = read_sensor_list(sensor_list) if sensor_list is not None else None
    labels = read_activity_list(activity_list) if activity_list is not None else None
    sources = (str(sensors_file), str(activities_file))
    sensor_log = SensorLog("kasteren", sources)
    records, header = read_intervals(sensors_file)
    if header:
        sensor_log.notes.append(_header_note(sources[0], header))
    shape = len(records[0].rest) == 3
    for record in records:
        if (len(record.rest) == 3) != shape:
            raise DataError("sensors named differently from the first record's (one log, one form: 'id [1]' or "
                            "'Location Type Place')", source=sources[0], line=record.line, field="sensor")
        sensor = _sensor_of(record, named, sources[0])
        sensor_log.heard(record.start, record.end, line=record.line)
        sensor_log.events[sensor.key] += 1
        if selection.choose(sensor, source=sources[0], line=record.line).object is not None:
            sensor_log.activations.setdefault(sensor.key, []).append(Activation(record.start, record.end))
    log.info("%s: %d sensor intervals", sources[0], len(records))
    records, header = read_intervals(activities_file)
    if header:
        sensor_log.notes.append(_header_note(sources[1], header))
    for record in records:
        text = " ".join(record.rest)
        if labels is not None:
            if text not in labels:
                raise DataError(f"unknown activity id {show(text)} (not in the activity list)", source=sources[1],
                                line=record.line, field="activity")
            activity = labels[text]
        else:
            activity = _label(text, sources[1], record.line, "activity", "activity")
        sensor_log.saw(record.start, line=record.line, source=1)
        sensor_log.saw(record.end, line=record.line, source=1)
        sensor_log.annotations.append(Annotation(activity, record.start, record.end, sources[1], record.line, text))
    log.info("%s: %d activity intervals", sources[1], len(records))
    return sensor_log


def import_kasteren(*, sensors_file: Path, activities_file: Path, dest: Path, options: GridOptions | None = None,
                    objects: Path | None = None, sensor_list: Path | None = None,
                    activity_list: Path | None = None) -> ImportResult:
    """Import a van Kasteren or Ordóñez log into the household folder ``dest``. ``objects`` is a
    mapping file (sensor keys as the report lists them: the id, or 'Location Type Place')."""
    options = options if options is not None else GridOptions()
    options.check()
    mapping = read_mapping(objects) if objects is not None else None
    selection = ObjectSelection(mapping=mapping, default=default_rule, default_help=DEFAULT_RULE)
    sensor_log = read_kasteren(sensors_file, activities_file, selection, sensor_list=sensor_list,
                               activity_list=activity_list)
    settings = {"sensor_list": str(sensor_list) if sensor_list else None,
                "activity_list": str(activity_list) if activity_list else None}
    return write_import(sensor_log=sensor_log, selection=selection, options=options, dest=dest, settings=settings)
