"""Importer of the CASAS event format (WSU's smart-home testbeds: Aruba, Milan, Cairo, ...).

One event a line, fields separated by spaces or tabs::

    2010-11-04 00:03:50.209589 M004 ON Bed_to_Toilet begin
    2010-11-04 00:03:57.399391 M005 OFF
    2010-11-04 00:04:00.000000 T002 21.5
    2010-11-04 00:05:01.000000 M004 OFF Bed_to_Toilet end

``date time sensor value``, then optionally ``activity begin`` or ``activity end`` (on any
event line; an activity may be several words, as Cairo's ``Bed to toilet begin``: one space
between them). Values are ON/OFF, OPEN/CLOSE, ABSENT/PRESENT (item sensors) or numbers
(temperature, light level, analog sensors); anything else is an error. Events must be in time
order (given the log's time zone, the hour logged twice when the clocks go back is read in
order); an activity may not begin twice before it ends, end without beginning, or be left open
at the end of the file (with ``--skip-bad-lines``, a begin whose end never came is left out:
one followed by other annotations, or by a later date, before it begins again).
Activity names are NFC-normalised before a begin is paired with its end.

CASAS names a sensor's type by the letters of its id. Without a mapping, only item sensors
(``I...``, placed on things a person takes: a medicine box, a pot) become objects, named by
their id in lower case, in one room; motion (M, MA), door (D), temperature (T), light (L, LS),
analog (AD) and unknown sensors stay out. An object sensor is *on* from ON/OPEN/ABSENT to the
next OFF/CLOSE/PRESENT (an ON while on means the OFF was lost: the earlier ON is one firing) and
fires at every event; a numeric sensor cannot be an object.

Every sensor is kept (the household's ``sensors.csv`` and ``events/``, :mod:`globe.data.sensors`),
its type by the same letters (:data:`SENSOR_TYPES`: M, MA motion; D door; I contact; T
temperature; L, LS light; AD appliance; P power; anything else other) and its room from the
``--objects`` mapping when it gives one, else none (a CASAS id says nothing of its room). Any
sensor's ON/OPEN/ABSENT .. OFF/CLOSE/PRESENT is an activation, by the rule objects follow (a motion
sensor is on from its ON to its OFF); numeric readings (temperatures, light levels) are no
activations: such a sensor is listed with its type and has no events.
"""

from __future__ import annotations

import logging
import re
import unicodedata
from collections import Counter
from datetime import datetime, timedelta, tzinfo
from pathlib import Path

from globe.data.csv_logs import _label
from globe.data.importers.grid import ImportResult, write_import
from globe.data.importers.objects import Choice, ObjectSelection, Sensor, read_mapping
from globe.data.importers.options import GridOptions
from globe.data.importers.sensor_log import Activation, Annotation, SensorLog
from globe.data.importers.text import (
    RESIDENT,
    RESIDENT_ID,
    clocks_went_back,
    out_of_order,
    parse_date_time,
    read_lines,
    show,
    time_zone,
)
from globe.errors import ConfigError, DataError

log = logging.getLogger(__name__)

FIELDS = ("date", "time", "sensor", "value", "activity", "begin/end")
ACTIVE = frozenset({"ON", "OPEN", "ABSENT"})  # an item sensor reads ABSENT while its thing is taken
INACTIVE = frozenset({"OFF", "CLOSE", "CLOSED", "PRESENT"})
KINDS = {"M": "motion", "MA": "motion", "D": "door", "T": "temperature", "L": "light switch",
         "LS": "light level", "I": "item", "AD": "analog"}
SENSOR_TYPES = {"M": "motion", "MA": "motion", "D": "door", "I": "contact", "T": "temperature", "L": "light",
                "LS": "light", "AD": "appliance", "P": "power"}
"""A kept sensor's type (:mod:`globe.data.sensors`) by the letters its id begins with; others: 'other'."""
SENSOR_RULE = ("type by the id's letters: M, MA motion; D door; I contact; T temperature; L, LS light; AD appliance; "
               "P power; else other. Room: the --objects mapping's, else none. Activations: ON/OPEN/ABSENT to the next "
               "OFF/CLOSE/PRESENT (a firing at each lone event); numeric readings are none")
DEFAULT_RULE = ("CASAS item sensors (I...) are objects, named by their id in lower case; motion (M, MA), door (D), "
                "temperature (T), light (L, LS), analog (AD) and unknown sensors are not")
PROGRESS_EVERY = 500_000
_NUMBER = re.compile(r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?")
_SENSOR = re.compile(r"[\w.-]+")
_LETTERS = re.compile(r"[A-Za-z]+")


def sensor_kind(key: str) -> str:
    """A CASAS sensor's type from the letters its id begins with ('' when unknown)."""
    match = _LETTERS.match(key)
    return KINDS.get(match.group(0).upper(), "") if match else ""


def sensor_type(key: str) -> str:
    """A CASAS sensor's type as ``sensors.csv`` writes it (see :data:`SENSOR_TYPES`)."""
    match = _LETTERS.match(key)
    return SENSOR_TYPES.get(match.group(0).upper(), "other") if match else "other"


def default_rule(sensor: Sensor) -> tuple[bool, str]:
    """Item sensors are objects; everything else is left out, with the reason for the report."""
    if sensor.kind == "item":
        return True, "CASAS item sensor (I...): on a thing a person takes"
    if sensor.kind:
        return False, f"CASAS {sensor.kind} sensor: not a thing a robot can fetch (map it with --objects to include it)"
    return False, "unknown CASAS sensor type (map it with --objects to include it)"


def read_casas(path: Path, selection: ObjectSelection, skip_bad_lines: bool = False,
               zone: tzinfo | None = None, resident: str | None = None) -> SensorLog:
    """Every event and annotation of a CASAS log, checked line by line. A line that breaks a rule
    is an error naming it; with ``skip_bad_lines`` it is left out instead (as is an activity that
    never ends), and the report lists what was left out: real logs carry a few corrupt lines.
    With the log's time ``zone``, the events of the hour logged twice when the clocks went back
    are kept in order: those of its second pass are held at the last time of the first. With
    ``resident`` (``R1``), annotations named for another resident of a multi-resident log
    (``R2_Sleep``) are left out, and the resident's own lose the prefix."""
    source = str(path)
    sensor_log = SensorLog("casas", (source,), annotation_field="activity", skip_bad_lines=skip_bad_lines)
    sensor_log.sensor_rule = SENSOR_RULE
    open_since: dict[str, datetime] = {}  # sensor -> when it went on
    begun: dict[str, tuple[datetime, int]] = {}  # activity -> (begin time, line)
    applied = 0  # annotation lines applied
    opened_at: dict[str, int] = {}  # activity -> ``applied`` after its last line
    previous: tuple[datetime, int] | None = None
    held = 0  # events of a repeated hour held in order
    lost_offs: Counter[str] = Counter()  # object sensor -> ONs that came while it was on
    lost_others: Counter[str] = Counter()  # the same for the other sensors
    residents: Counter[str] = Counter()  # annotations named for each resident (with --resident)
    lines = read_lines(path)
    disordered = _disordered(lines, source, zone) if skip_bad_lines else {}
    for count, (line, text) in enumerate(lines, start=1):
        named: str | None = None  # the resident this line's annotation names
        try:  # every check first: a line left out changes nothing
            moment, key, value, choice, marker = _event(text, source, line, previous, selection, zone)
            if line in disordered:
                raise disordered[line]
            begins = marker is not None and marker[1].lower() == "begin"
            if marker is not None and resident is not None:
                marker, named = _of_resident(marker, resident)
            if marker is not None:
                again = marker[1].lower() == "begin" and marker[0] in begun
                lost_end = skip_bad_lines and again and (opened_at[marker[0]] != applied
                                                         or begun[marker[0]][0].date() != moment.date())
                _check_annotation(begun, *marker, source, line, lost_ends=lost_end)
        except DataError as err:
            sensor_log.bad(err)
            continue
        if named is not None:
            residents[named] += begins
        if previous is not None and moment < previous[0]:  # the hour the clocks went back over, again
            held += 1
            moment = previous[0]
        previous = (moment, line)
        selection.choose(Sensor(key, key, sensor_kind(key), ""), source=source, line=line)
        if key not in sensor_log.sensors:
            sensor_log.sensor(key, sensor_type(key), selection.mapped_room(key))
        sensor_log.heard(moment, line=line)
        sensor_log.events[key] += 1
        binary = value in ACTIVE or value in INACTIVE
        if binary and _activation(sensor_log, open_since, key, moment, value in ACTIVE, choice.object is not None):
            (lost_offs if choice.object is not None else lost_others)[key] += 1
        if marker is not None:
            lost = _annotation(sensor_log, begun, *marker, moment, source, line)
            applied += 1
            opened_at[marker[0]] = applied
            if lost is not None:
                sensor_log.bad(lost)
        if count % PROGRESS_EVERY == 0:
            log.info("%s: %d of %d lines read", source, count, len(lines))
    for activity, (start, line) in list(begun.items()):
        hint = "" if skip_bad_lines else "; if the log was cut off while it lasted, --skip-bad-lines leaves it out"
        unended = DataError(f"{show(activity)} begins here (at {start}) but never ends (no end of it before the end "
                            f"of the file){hint}", source=source, line=line, field="activity")
        sensor_log.bad(unended)
    still_on = []  # sensors of no object still on at the end
    for key, start in open_since.items():
        assert sensor_log.last is not None
        sensor_log.sensor_on(key, start, sensor_log.last)
        if selection.choices[key].object is None:
            still_on.append(f"{key} (since {start})")
            continue
        sensor_log.activations.setdefault(key, []).append(Activation(start, sensor_log.last))
        sensor_log.notes.append(f"sensor {key} is still on at the end of the log (since {start}): counted as on until "
                                "the log ends")
    if still_on:
        sensor_log.notes.append(f"sensors of no object still on at the end of the log, counted as on until it ends "
                                f"(events/): {', '.join(still_on)}")
    if lost_offs:
        counts = ", ".join(f"{key} {n}x" for key, n in lost_offs.items())
        sensor_log.notes.append("an object sensor went on while on (its OFF, CLOSE or PRESENT was lost), so the "
                                f"earlier event counts as one firing: {counts}")
    if lost_others:
        counts = ", ".join(f"{key} {n}x" for key, n in lost_others.items())
        sensor_log.notes.append("a sensor of no object went on while on (its OFF, CLOSE or PRESENT was lost), so the "
                                f"earlier event counts as one firing in events/: {counts}")
    if resident is not None:
        if resident.upper() not in residents:
            named = ", ".join(sorted(residents)) or "none: not a multi-resident log"
            raise DataError(f"no annotation is named for resident {resident} (R1_Sleep names R1); the log names "
                            f"{named}", source=source)
        others = ", ".join(f"{who} {n}" for who, n in sorted(residents.items()) if who != resident.upper())
        if others:
            sensor_log.notes.append(f"annotations of other residents left out (--resident {resident}): {others}")
    if held:
        sensor_log.notes.append(f"{held} events logged in the hour repeated when the clocks went back are held at "
                                "the last time of its first pass")
    log.info("%s: %d events, %d sensors, %d annotations", source, len(lines), len(sensor_log.events),
             len(sensor_log.annotations))
    return sensor_log


def _disordered(lines: list[tuple[int, str]], source: str, zone: tzinfo | None) -> dict[int, DataError]:
    """The lines to leave out (``--skip-bad-lines``) so that the others are in time order, each
    with its error: the fewest, so that one timestamp corrupted to a later date costs its own line,
    not every line after it (see :func:`out_of_order`). The hour logged twice when the clocks go
    back is read as :func:`_event` reads it."""
    times: list[datetime | None] = []
    previous: datetime | None = None
    for line, text in lines:
        fields = text.split()
        moment: datetime | None = None
        if len(fields) == 4 or len(fields) >= 6:  # as _event reads them
            try:
                moment = parse_date_time(fields[0], fields[1], source=source, line=line)
            except DataError:
                moment = None  # a bad time: _event names it
        if moment is not None and previous is not None and moment < previous and zone is not None \
                and clocks_went_back(previous, moment, zone):
            moment = previous
        previous = moment if moment is not None else previous
        times.append(moment)
    dropped = out_of_order(times)
    errors: dict[int, DataError] = {}
    kept: tuple[datetime, int] | None = None
    gone = set(dropped)
    for i, ((line, _), moment) in enumerate(zip(lines, times)):
        if moment is None:
            continue
        if i not in gone:
            kept = (moment, line)
            continue
        after = f" (the event before it, line {kept[1]}, is at {kept[0]})" if kept is not None else ""
        errors[line] = DataError(f"{moment} is out of time order with the events around it{after}: the log is in order "
                                 "without this line (a corrupt timestamp?)", source=source, line=line, field="time")
    return errors


def _event(text: str, source: str, line: int, previous: tuple[datetime, int] | None, selection: ObjectSelection,
           zone: tzinfo | None = None) -> tuple[datetime, str, str, Choice, tuple[str, str] | None]:
    """One line checked: (time, sensor, value in upper case, what the sensor is, (activity,
    begin|end) or None). Changes nothing."""
    fields = text.split()
    if len(fields) < 4:
        raise DataError(f"missing field (a CASAS event is 'date time sensor value [activity begin|end]', "
                        f"found {len(fields)} fields)", source=source, line=line, field=FIELDS[len(fields)])
    if len(fields) == 5:
        raise DataError(f"{show(fields[4])} after the value must be followed by 'begin' or 'end'", source=source,
                        line=line, field="begin/end")
    if len(fields) > 6 and fields[-1].lower() not in ("begin", "end"):  # Cairo's 'Bed to toilet begin': 8 fields
        raise DataError(f"{len(fields)} fields; a CASAS event has 4, or more with 'activity begin|end' (an activity "
                        "may be several words)", source=source, line=line, field="begin/end")
    moment = parse_date_time(fields[0], fields[1], source=source, line=line)
    if previous is not None and moment < previous[0] and not (zone and clocks_went_back(previous[0], moment, zone)):
        fold_like = previous[0] - moment <= timedelta(hours=1) and moment.hour < 4  # clocks go back at night
        hint = ("; if the log is in local time and the clocks went back here (daylight saving time ended), give its "
                "time zone with --timezone" if zone is None and fold_like else "")
        raise DataError(f"{moment} is before the previous event's {previous[0]} (line {previous[1]}): events must "
                        f"be in time order{hint}", source=source, line=line, field="time")
    key, value = fields[2], fields[3].upper()
    if not _SENSOR.fullmatch(key):
        raise DataError(f"{show(key)} is not a sensor id (letters, digits, '_', '-', '.')", source=source,
                        line=line, field="sensor")
    binary = value in ACTIVE or value in INACTIVE
    if not binary and not _NUMBER.fullmatch(value):
        raise DataError(f"{show(fields[3])} is not ON, OFF, OPEN, CLOSE, ABSENT, PRESENT or a number (a corrupt "
                        "line? --skip-bad-lines leaves such lines out)", source=source, line=line, field="value")
    choice = selection.decide(Sensor(key, key, sensor_kind(key), ""), source=source, line=line)
    if choice.object is not None and not binary:
        raise DataError(f"{show(fields[3])} is a reading, not a use: sensor {key!r} (object {choice.object!r}) "
                        "must be ON/OFF, OPEN/CLOSE or ABSENT/PRESENT", source=source, line=line, field="value")
    marker = (unicodedata.normalize("NFC", " ".join(fields[4:-1])), fields[-1]) if len(fields) >= 6 else None
    return moment, key, value, choice, marker


def _of_resident(marker: tuple[str, str], resident: str) -> tuple[tuple[str, str] | None, str | None]:
    """A multi-resident log's annotation for ``resident``, and the resident it names (None: no
    one): ``R1_Sleep`` is ``Sleep`` for R1 and left out for anyone else; a label without such a
    prefix is everyone's."""
    match = RESIDENT.fullmatch(marker[0])
    if match is None:
        return marker, None
    who = match.group(1).upper()
    return ((match.group(2), marker[1]) if who == resident.upper() else None), who


def _activation(sensor_log: SensorLog, open_since: dict[str, datetime], key: str, moment: datetime,
                active: bool, is_object: bool) -> bool:
    """An on/off event of a sensor: it fires now, and is on from an ON until the next OFF. An ON
    while on means the OFF between was lost: the earlier ON then counts as one firing, not as a
    use lasting until now (a lost PRESENT would hold an item in use for hours). Every sensor's
    activations go to ``events/``; an object sensor's also make its object's uses. Returns
    whether an OFF was lost."""
    if active:
        earlier = open_since.setdefault(key, moment)
        if earlier == moment:
            return False
        _on(sensor_log, key, earlier, earlier, is_object)
        open_since[key] = moment
        return True
    start = open_since.pop(key, moment)
    _on(sensor_log, key, start, moment, is_object)
    return False


def _on(sensor_log: SensorLog, key: str, start: datetime, end: datetime, is_object: bool) -> None:
    sensor_log.sensor_on(key, start, end)
    if is_object:
        sensor_log.activations.setdefault(key, []).append(Activation(start, end))


def _check_annotation(begun: dict[str, tuple[datetime, int]], activity: str, marker: str, source: str,
                      line: int, lost_ends: bool = False) -> None:
    """That an annotation can be applied: a valid label, begun once (unless ``lost_ends``: a second
    begin after other annotations, or on a later date, means the first one's end was lost; one
    right after the first is a duplicated line), ended after it began."""
    _label(activity, source, line, "activity", "activity")
    if marker.lower() == "begin":
        if activity in begun and not lost_ends:
            raise DataError(f"{show(activity)} begins again before it ended (it began at line {begun[activity][1]}; if "
                            "its end line is lost or corrupt, --skip-bad-lines leaves that begin out)",
                            source=source, line=line, field="activity")
    elif marker.lower() == "end":
        if activity not in begun:
            raise DataError(f"{show(activity)} ends but never began (no begin of it is open)", source=source,
                            line=line, field="activity")
    else:
        raise DataError(f"{show(marker)} is not 'begin' or 'end'", source=source, line=line, field="begin/end")


def _annotation(sensor_log: SensorLog, begun: dict[str, tuple[datetime, int]], activity: str, marker: str,
                moment: datetime, source: str, line: int) -> DataError | None:
    """Apply an annotation :func:`_check_annotation` accepted; returns why an earlier begin of the
    same activity is left out (its end was lost: pairing it with this one's end would make one
    annotation of both and all between)."""
    if marker.lower() == "begin":
        earlier = begun.get(activity)
        begun[activity] = (moment, line)
        if earlier is not None:
            return DataError(f"{show(activity)} begins here (at {earlier[0]}) and again at line {line} before it "
                             "ends: its end was lost, so this begin is left out", source=source, line=earlier[1],
                             field="activity")
    else:
        start, first = begun.pop(activity)
        sensor_log.annotations.append(Annotation(activity, start, moment, source, first, activity))
    return None


def import_casas(*, log_file: Path, dest: Path, options: GridOptions | None = None, objects: Path | None = None,
                 skip_bad_lines: bool = False, timezone: str | None = None,
                 resident: str | None = None) -> ImportResult:
    """Import a CASAS log into the household folder ``dest`` (see :mod:`globe.data.importers.grid`
    for the grid's rules). ``objects`` is a mapping file; without it, item sensors are objects.
    ``skip_bad_lines`` leaves out lines that break a rule (listed in the report) instead of stopping.
    ``timezone``: the IANA zone of the log's local times, so that the hour logged twice when the
    clocks go back is read in order. ``resident``: in a multi-resident log, whose annotations
    (``R1``: those named ``R1_...``, and those named for no one) make the household's activities."""
    options = options if options is not None else GridOptions()
    options.check()
    mapping = read_mapping(objects) if objects is not None else None
    selection = ObjectSelection(mapping=mapping, default=default_rule, default_help=DEFAULT_RULE)
    zone = time_zone(timezone) if timezone is not None else None
    if resident is not None and not re.fullmatch(RESIDENT_ID, resident, re.IGNORECASE):
        raise ConfigError(f"--resident {resident!r}: name a resident as the log does, e.g. R1")
    sensor_log = read_casas(log_file, selection, skip_bad_lines, zone, resident)
    return write_import(sensor_log=sensor_log, selection=selection, options=options, dest=dest,
                        settings={"timezone": timezone, "resident": resident, "skip_bad_lines": skip_bad_lines})
