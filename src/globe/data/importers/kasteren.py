"""Importer of interval logs in the van Kasteren / Ordóñez format.

Two files, one interval a line, fields separated by spaces or tabs: sensor intervals (when each
sensor was on) and activity intervals (what the person did)::

    # van Kasteren (kasterenSenseData.txt, kasterenActData.txt): numeric ids
    25-Feb-2008 09:33:41    25-Feb-2008 09:33:42    7    1
    25-Feb-2008 09:33:41    25-Feb-2008 09:43:10    13
    # Ordóñez (OrdonezA_Sensors.txt, OrdonezA_ADLs.txt): sensors as 'Location Type Place'
    2011-11-28 02:27:59    2011-11-28 10:18:11    Bed    Pressure    Bedroom
    2011-11-28 02:27:59    2011-11-28 10:18:11    Sleeping

Times are ``YYYY-MM-DD HH:MM:SS`` or ``DD-Mon-YYYY HH:MM:SS``. Before the first record, a line
``id name`` (also ``id: name``, ``id,name``, ``[id] 'name'``; quotes around the name dropped)
belongs to the file's own list of ids, as the files are distributed; any other line that does not
begin with a digit is a header (Ordóñez has two). A record's dates hold a '-', so it is never
read as a list line. After the first record every line is a record, except a last line
``Length: N`` (any case), the distributed files' footer: when N differs from the number of
records, the report says so (a note, not an error).

A van Kasteren sensor line is ``start end id [1]``; its names come from the file's own list and
from a sensor list (CSV ``sensor,name`` and, optionally, ``type`` and ``room``), which replaces
the file's entry for each id it names; when either is given every id must be in one of them.
Activity ids become labels the same way (the file's own list, and an activity list, CSV
``id,activity``, that wins for the ids it names). Numbered activities that nothing names are
refused, naming the line (``--activity-list``, or ``--allow-numeric-labels`` to keep the numbers).
A line that breaks a rule is an error naming file, line and field, or with ``--skip-bad-lines``
left out and listed in the report.

Without a mapping, a sensor of type Magnetic, Contact, Reed or Electric (a contact on a cupboard
or the fridge, a switched appliance) is an object, named after its location or name, in its place
(room), unless its name says it is a door; PIR (motion), Pressure, Flush and sensors of unknown
type stay out.

Every sensor is kept (the household's ``sensors.csv`` and ``events/``, :mod:`globe.data.sensors`)
with each of its intervals as an activation. Its type (:func:`sensor_type`): the listed type
(Ordóñez's *Type*, a sensor list's ``type``) in the household's words, PIR motion, Magnetic,
Contact and Reed contact (door when the name says door), Pressure pressure, Flush and Float flush,
Electric appliance, another word kept as it is; without one, by the name: door, PIR or motion,
pressure or mat, flush, a cupboard or an appliance with a door (fridge, microwave, ...: contact),
a toaster or kettle (appliance); else other. Its room (:func:`sensor_room`): the ``--objects``
mapping's, else the listed one (Ordóñez's *Place*, a sensor list's ``room``), else the last room
word of its name (``Hall-Toilet door``: the door into the toilet), else kitchen for kitchen
things (cupboards, fridge, microwave, ...) and toilet for a flush; else none.
"""

from __future__ import annotations

import logging
import re
from collections import Counter
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path

from globe.data.csv_logs import _label, csv_table
from globe.data.importers.grid import ImportResult, write_import
from globe.data.importers.objects import ObjectSelection, Sensor, read_mapping
from globe.data.importers.options import GridOptions
from globe.data.importers.sensor_log import Activation, Annotation, SensorLog
from globe.data.importers.text import (
    parse_date_time,
    parse_day_month_year,
    read_lines,
    read_text,
    show,
    slug,
    table_cells,
)
from globe.errors import DataError

log = logging.getLogger(__name__)

LISTED_TYPES = {"pir": "motion", "motion": "motion", "magnetic": "contact", "contact": "contact", "reed": "contact",
                "pressure": "pressure", "flush": "flush", "float": "flush", "electric": "appliance",
                "power": "power"}
"""A listed sensor type in the household's words (:mod:`globe.data.sensors`); other words are kept."""
NAME_TYPES = (("door", "door"), ("pir", "motion"), ("motion", "motion"), ("pressure", "pressure"), ("mat", "pressure"),
              ("flush", "flush"), ("cupboard", "contact"), ("cabinet", "contact"), ("drawer", "contact"),
              ("fridge", "contact"), ("freezer", "contact"), ("microwave", "contact"), ("dishwasher", "contact"),
              ("washingmachine", "contact"), ("oven", "contact"), ("toaster", "appliance"),
              ("kettle", "appliance"))
"""A sensor's type by a word of its name when nothing lists it, first match first."""
ROOM_WORDS = {"hall": "hall", "toilet": "toilet", "bathroom": "bathroom", "bedroom": "bedroom", "kitchen": "kitchen",
              "living": "living_room", "livingroom": "living_room", "lounge": "living_room", "entrance": "entrance",
              "garage": "garage", "office": "office", "study": "office"}
"""Rooms a sensor's name may say (the last one said wins: ``Hall-Toilet door`` opens the toilet)."""
KITCHEN_THINGS = frozenset({"cupboard", "cabinet", "fridge", "freezer", "microwave", "dishwasher", "oven", "stove",
                            "toaster", "kettle", "cups", "plates", "pans", "groceries", "cooktop"})
SENSOR_RULE = ("type: the listed type (PIR motion; Magnetic, Contact, Reed contact, or door when the name says door; "
               "Pressure pressure; Flush, Float flush; Electric appliance; another word kept), else by the name "
               "(door, PIR/motion, pressure/mat, flush, cupboards and appliances with a door contact, toaster/kettle "
               "appliance), else other. Room: the --objects mapping's, else the listed room, else the last room word "
               "of the name, else kitchen for kitchen things and toilet for a flush, else none")
OBJECT_TYPES = frozenset({"magnetic", "contact", "reed", "electric"})
DEFAULT_RULE = ("sensors of type Magnetic, Contact, Reed or Electric are objects unless their name says 'door'; "
                "other types (PIR, Pressure, Flush, ...) and sensors of unknown type are not")
_RECORD = re.compile(r"\s*(\S+)\s+(\S+)\s+(\S+)\s+(\S+)(?:\s+(.*?))?\s*")
_ISO_DAY = re.compile(r"\d{4}-\d{2}-\d{2}")
_LIST_ENTRY = re.compile(r"\s*\[?\s*(\d+)\s*\]?(?:\s*[:,=]\s*|\s+)(\S.*?)\s*")  # never a record: its dates hold '-'
_FOOTER = re.compile(r"\s*length\s*:\s*(\d+)?\s*", re.IGNORECASE)
_NUMBER = re.compile(r"\d+")


@dataclass(frozen=True, slots=True)
class Interval:
    """One record: ``[start, end]`` and what follows the two times."""

    line: int
    start: datetime
    end: datetime
    rest: tuple[str, ...]


@dataclass
class IntervalFile:
    """What an interval file holds: its records, and around them a header, the file's own list of
    ids (id -> (name, line)) and a ``Length: N`` footer."""

    source: str
    records: list[Interval] = field(default_factory=list)
    header: int = 0  # header lines before the first record (the list's lines not counted)
    names: dict[str, tuple[str, int]] = field(default_factory=dict)
    record_lines: int = 0  # lines read as records, those left out (--skip-bad-lines) included
    footer: int | None = None  # the footer's N


def _time(date: str, clock: str, source: str, line: int, field: str) -> datetime:
    if _ISO_DAY.fullmatch(date):
        return parse_date_time(date, clock, source=source, line=line, date_field=field, time_field=field)
    return parse_day_month_year(date, clock, source=source, line=line, field=field)


def _record(text: str, source: str, line: int) -> Interval:
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
    return Interval(line, start, end, rest)


def _list_entry(found: IntervalFile, key: str, name: str, line: int) -> None:
    """One ``id name`` line of the file's own list (quotes around the name dropped)."""
    if len(name) > 1 and name[0] == name[-1] and name[0] in "'\"":
        name = name[1:-1].strip()
    name = _label(name, found.source, line, "name", "name")
    if key in found.names:
        raise DataError(f"id {show(key)} is listed twice (also line {found.names[key][1]})", source=found.source,
                        line=line, field="id")
    found.names[key] = (name, line)


def read_intervals(path: Path, sensor_log: SensorLog) -> IntervalFile:
    """The records of an interval file; before the first, header lines (not beginning with a
    digit) and the file's own list of ids (``id name``, ``id: name``, ``id,name``, ``[id] 'name'``);
    a last line ``Length: N`` is a footer. A bad line goes to :meth:`SensorLog.bad`."""
    found = IntervalFile(str(path))
    lines = read_lines(path)
    footer = _FOOTER.fullmatch(lines[-1][1]) if lines else None
    if footer is not None:
        found.footer = int(footer.group(1)) if footer.group(1) else None
        lines = lines[:-1]
    for line, text in lines:
        try:
            if not found.record_lines:
                entry = _LIST_ENTRY.fullmatch(text)
                if entry is not None:
                    _list_entry(found, entry.group(1), entry.group(2), line)
                    continue
                if not text.lstrip()[:1].isdigit():
                    found.header += 1
                    continue
            found.record_lines += 1
            found.records.append(_record(text, found.source, line))
        except DataError as err:
            sensor_log.bad(err)
    if not found.records:
        where = f"only {found.header} header line{'s' if found.header > 1 else ''}"
        if found.names:
            where += f" and a list of {len(found.names)} ids"
        if found.record_lines:
            where = f"all {found.record_lines} left out as bad lines"
        raise DataError(f"no records ({where})", source=found.source, line=1)
    if found.footer is not None and found.footer != found.record_lines:
        sensor_log.notes.append(f"{found.source}: its footer says Length: {found.footer}, but it holds "
                                f"{found.record_lines} records (checked, not enforced)")
    return found


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


def _words(name: str) -> list[str]:
    """A sensor's name in lower-case words (``ToiletFlush`` -> toilet, flush; ``Hall-Toilet door``
    -> hall, toilet, door)."""
    return [w.lower() for w in re.findall(r"[A-Z]?[a-z]+|[A-Z]+(?![a-z])|\d+", name)]


def sensor_type(sensor: Sensor) -> str:
    """The type ``sensors.csv`` gives a sensor (see the module doc)."""
    words = _words(sensor.name)
    kind = slug(sensor.kind)
    if kind:
        listed = LISTED_TYPES.get(kind, kind if re.fullmatch(r"[a-z][a-z0-9_]*", kind) else "other")
        return "door" if listed == "contact" and any("door" in w for w in words) else listed
    for needle, kind in NAME_TYPES:
        if any(w == needle or (len(needle) > 3 and needle in w) for w in words):
            return kind
    return "other"


def sensor_room(sensor: Sensor, mapped: str = "") -> str:
    """The room ``sensors.csv`` gives a sensor (see the module doc); ``mapped``: the mapping's."""
    if mapped or sensor.room:
        return mapped or slug(sensor.room)
    words = _words(sensor.name)
    rooms = [ROOM_WORDS[w] for w in words if w in ROOM_WORDS]
    if rooms:
        return rooms[-1]
    if any(w in KITCHEN_THINGS for w in words):
        return "kitchen"
    return "toilet" if "flush" in words else ""


def _sensor_of(record: Interval, named: dict[str, Sensor] | None, source: str, lists: str) -> Sensor:
    """The sensor of a record: 'Location Type Place' (Ordóñez) or 'id [1]' (van Kasteren), named
    by ``named`` (from ``lists``) when given."""
    if len(record.rest) == 3:
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
        raise DataError(f"unknown sensor {show(key)} (not in {lists})", source=source, line=record.line,
                        field="sensor")
    return sensor


def _own_list(found: IntervalFile, what: str) -> str:
    """The note that a file named its ids itself."""
    lines = [line for _, line in found.names.values()]
    return (f"{found.source}: its own list names {len(found.names)} {what} (lines {min(lines)}-{max(lines)}); "
            "a list given as an option names the ids it lists instead")


def _lists(found: IntervalFile, option: Path | None, what: str) -> str:
    """Where the names of a file's ids come from, for messages."""
    where = ([f"the list at the head of {found.source}"] if found.names else []) + \
        ([f"{what} {option}"] if option is not None else [])
    return " or ".join(where)


def read_kasteren(sensors_file: Path, activities_file: Path, selection: ObjectSelection, *,
                  sensor_list: Path | None = None, activity_list: Path | None = None, skip_bad_lines: bool = False,
                  allow_numeric_labels: bool = False) -> SensorLog:
    """Both files of an interval log, checked line by line, as one :class:`SensorLog`. The ids of
    each file are named by its own list, and by ``sensor_list`` / ``activity_list`` where they
    name them (the option wins: it is the user's word). Numbered activities that nothing names are
    refused unless ``allow_numeric_labels``: activities called '1', '10', '13' would import
    without a word and make every table unreadable."""
    sources = (str(sensors_file), str(activities_file))
    sensor_log = SensorLog("kasteren", sources, skip_bad_lines=skip_bad_lines, sensor_rule=SENSOR_RULE)
    sense = read_intervals(sensors_file, sensor_log)
    named: dict[str, Sensor] | None = None
    if sense.names or sensor_list is not None:
        named = {key: Sensor(key, name, "", "") for key, (name, _) in sense.names.items()}
        named.update(read_sensor_list(sensor_list) if sensor_list is not None else {})
    _notes(sensor_log, sense, "sensors")
    forms = Counter(len(r.rest) == 3 for r in sense.records)  # the form most records take (ties: the first's)
    shape = forms[True] > forms[False] or (forms[True] == forms[False] and len(sense.records[0].rest) == 3)
    if shape and named is not None:
        raise DataError("this log names its sensors itself ('Location Type Place'): "
                        + ("leave out --sensor-list" if sensor_list is not None else "its list of ids does not apply"),
                        source=sources[0], line=sense.records[0].line, field="sensor")
    lists = _lists(sense, sensor_list, "the sensor list")
    for record in sense.records:
        try:
            if (len(record.rest) == 3) != shape:
                raise DataError("sensors named differently from the other records (one log, one form: 'id [1]' or "
                                "'Location Type Place')", source=sources[0], line=record.line, field="sensor")
            sensor = _sensor_of(record, named, sources[0], lists)
        except DataError as err:
            sensor_log.bad(err)
            continue
        sensor_log.heard(record.start, record.end, line=record.line)
        sensor_log.events[sensor.key] += 1
        is_object = selection.choose(sensor, source=sources[0], line=record.line).object is not None
        if sensor.key not in sensor_log.sensors:
            sensor_log.sensor(sensor.key, sensor_type(sensor), sensor_room(sensor, selection.mapped_room(sensor.key)))
        sensor_log.sensor_on(sensor.key, record.start, record.end)
        if is_object:
            sensor_log.activations.setdefault(sensor.key, []).append(Activation(record.start, record.end))
    log.info("%s: %d sensor intervals", sources[0], len(sense.records))
    acts = read_intervals(activities_file, sensor_log)
    labels: dict[str, str] | None = None
    if acts.names or activity_list is not None:
        labels = {key: name for key, (name, _) in acts.names.items()}
        labels.update(read_activity_list(activity_list) if activity_list is not None else {})
    _notes(sensor_log, acts, "activities")
    lists = _lists(acts, activity_list, "the activity list")
    for record in acts.records:
        text = " ".join(record.rest)
        if labels is None and not allow_numeric_labels and _NUMBER.fullmatch(text):
            raise DataError(f"activity {show(text)} is a number, and neither the file's own list nor "
                            "--activity-list names it: give the names with --activity-list (CSV id,activity), or "
                            "pass --allow-numeric-labels to keep the numbers as activities", source=sources[1],
                            line=record.line, field="activity")
        try:
            if labels is not None and text not in labels:
                raise DataError(f"unknown activity id {show(text)} (not in {lists})", source=sources[1],
                                line=record.line, field="activity")
            activity = labels[text] if labels is not None else _label(text, sources[1], record.line, "activity",
                                                                        "activity")
        except DataError as err:
            sensor_log.bad(err)
            continue
        sensor_log.saw(record.start, line=record.line, source=1)
        sensor_log.saw(record.end, line=record.line, source=1)
        sensor_log.annotations.append(Annotation(activity, record.start, record.end, sources[1], record.line, text))
    log.info("%s: %d activity intervals", sources[1], len(acts.records))
    return sensor_log


def _notes(sensor_log: SensorLog, found: IntervalFile, what: str) -> None:
    if found.header:
        lines = found.header
        sensor_log.notes.append(f"{found.source}: skipped {lines} header line{'s' if lines > 1 else ''} before the "
                                "first record")
    if found.names:
        sensor_log.notes.append(_own_list(found, what))


def import_kasteren(*, sensors_file: Path, activities_file: Path, dest: Path, options: GridOptions | None = None,
                    objects: Path | None = None, sensor_list: Path | None = None,
                    activity_list: Path | None = None, skip_bad_lines: bool = False,
                    allow_numeric_labels: bool = False) -> ImportResult:
    """Import a van Kasteren or Ordóñez log into the household folder ``dest``. ``objects`` is a
    mapping file (sensor keys as the report lists them: the id, or 'Location Type Place').
    ``skip_bad_lines`` leaves out lines that break a rule (listed in the report) instead of
    stopping; ``allow_numeric_labels`` keeps activity ids nothing names as the activities."""
    options = options if options is not None else GridOptions()
    options.check()
    mapping = read_mapping(objects) if objects is not None else None
    selection = ObjectSelection(mapping=mapping, default=default_rule, default_help=DEFAULT_RULE)
    sensor_log = read_kasteren(sensors_file, activities_file, selection, sensor_list=sensor_list,
                               activity_list=activity_list, skip_bad_lines=skip_bad_lines,
                               allow_numeric_labels=allow_numeric_labels)
    settings = {"sensor_list": str(sensor_list) if sensor_list else None,
                "activity_list": str(activity_list) if activity_list else None,
                "skip_bad_lines": skip_bad_lines, "allow_numeric_labels": allow_numeric_labels}
    return write_import(sensor_log=sensor_log, selection=selection, options=options, dest=dest, settings=settings)
