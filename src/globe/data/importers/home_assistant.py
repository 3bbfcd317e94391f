"""Importer of a Home Assistant recorder history export (the History panel's "Download data").

A CSV with the columns ``entity_id,state,last_changed``, one state change a row, grouped by
entity and in time order within each::

    entity_id,state,last_changed
    input_select.activity,sleeping,2024-03-01T05:00:00.000Z
    input_select.activity,breakfast,2024-03-01T06:31:12.410Z
    binary_sensor.fridge_door,off,2024-03-01T05:00:00.000Z
    binary_sensor.fridge_door,on,2024-03-01T06:40:03.120Z

The activity is the state of one entity the user names (``activity_entity``, e.g. an
``input_select`` the household sets, or a template sensor): each state holds from its row until
the entity's next row, the last one until the end of the export; ``unknown`` and ``unavailable``
are no activity (``idle`` on the grid). Objects are only the entities the user maps
(``--objects``): an export says nothing about what an entity is on, so without a mapping there are
no object columns. A mapped entity is in use while ``on`` or ``open`` and fires whenever its state
changes; ``off`` and ``closed`` are not in use, ``unavailable`` and ``unknown`` are not either and
are counted in the report; any other state is an error. Other entities are left out. A row that
breaks a rule (a bad entity id or timestamp, a row before its entity's previous one) is an error
naming its line and column, or with ``--skip-bad-lines`` left out and listed in the report.
When the export holds a climate, humidifier or water heater entity, the panel adds a column per
attribute it writes (``current_temperature``, ``hvac_action``, ...) and leaves them out of every
other row: a row may stop short of the header, as long as it holds the columns read.

Timestamps with a UTC offset (HA writes UTC) are put on the home's clock with ``timezone`` (an
IANA name such as ``Europe/Amsterdam``), which is then required: the day starts at 06:00 where
the person lives. When the clocks go back, an hour happens twice on the home's clock; a row in
its second pass is held at its entity's previous local time (and counted in the report), so that
intervals never end before they begin. Timestamps without an offset are the home's clock already.

Every on/off entity is kept as a sensor (the household's ``sensors.csv`` and ``events/``,
:mod:`globe.data.sensors`): each ``binary_sensor``, ``switch`` and ``light``, and each mapped
entity; numeric sensors, trackers and the activity entity are not. An activation is a stretch
from ``on`` or ``open`` to the entity's next other state. Its type is the export's
``device_class`` column where it has one, else inferred from the entity's name
(:data:`NAME_TYPES`: motion, occupancy, presence, door, window, opening, moisture, ...), else by
its domain (a switch is an appliance, a light a light, a binary sensor other); its room is the
mapping's (the user's word wins, as for objects), else the export's ``area`` column, else none.
"""

from __future__ import annotations

import logging
import re
from datetime import datetime
from pathlib import Path
from typing import Callable

from globe.data.csv_logs import _clean, _label, _ragged, csv_table
from globe.data.importers.grid import ImportResult, write_import
from globe.data.importers.objects import ObjectSelection, Sensor, read_mapping
from globe.data.importers.options import GridOptions
from globe.data.importers.sensor_log import Activation, Annotation, SensorLog
from globe.data.importers.text import parse_iso_8601, read_text, show, slug, time_zone
from globe.errors import DataError

log = logging.getLogger(__name__)

COLUMNS = ("entity_id", "state", "last_changed")
ON_STATES = frozenset({"on", "open"})
OFF_STATES = frozenset({"off", "closed"})
NO_DATA = frozenset({"unknown", "unavailable"})
DEFAULT_RULE = "no objects without a mapping: a Home Assistant export does not say what an entity is on"
SENSOR_DOMAINS = frozenset({"binary_sensor", "switch", "light"})
"""Entities kept as sensors (besides the mapped ones): those that are on or off."""
OPTIONAL_COLUMNS = ("device_class", "area")
NAME_TYPES = (("motion", "motion"), ("occupancy", "motion"), ("presence", "motion"), ("pir", "motion"),
              ("door", "door"), ("window", "window"), ("opening", "contact"), ("contact", "contact"),
              ("moisture", "moisture"), ("leak", "moisture"), ("pressure", "pressure"), ("bed", "pressure"),
              ("flush", "flush"), ("smoke", "smoke"), ("vibration", "vibration"), ("power", "power"),
              ("plug", "power"))
"""A sensor's type by a word of its entity name (``binary_sensor.hallway_motion``: motion), first
match first, where the export has no ``device_class``."""
DOMAIN_TYPES = {"switch": "appliance", "light": "light"}
DEVICE_CLASSES = {"occupancy": "motion", "presence": "motion", "garage_door": "door", "opening": "contact",
                  "plug": "power"}
"""Home Assistant device classes in the household's words; other classes are kept as they are."""
SENSOR_RULE = ("every binary_sensor, switch and light, and every mapped entity; type: the device_class column "
               "(occupancy, presence motion; garage_door door; opening contact; plug power; others as they are), else "
               "a word of the entity's name (motion, occupancy, presence, door, window, opening, moisture, leak, bed, "
               "flush, ...), else switch appliance, light light, other. Room: the mapping's, else the area column, "
               "else none. Activations: on/open to the next other state")
_ENTITY = re.compile(r"[a-z0-9_]+\.[a-z0-9_]+")


def default_rule(sensor: Sensor) -> tuple[bool, str]:
    return False, "not mapped (map binary sensors on cupboards, the fridge or appliances with --objects)"


def sensor_type(entity: str, device_class: str = "") -> str:
    """The type ``sensors.csv`` gives an entity (see the module doc)."""
    if device_class:
        word = re.sub(r"[^a-z0-9_]+", "_", device_class.lower()).strip("_")
        if re.fullmatch(r"[a-z][a-z0-9_]*", word):
            return DEVICE_CLASSES.get(word, word)
    domain, name = entity.split(".", 1)
    words = name.split("_")
    for needle, kind in NAME_TYPES:
        if needle in words:
            return kind
    return DOMAIN_TYPES.get(domain, "other")


def read_home_assistant(path: Path, selection: ObjectSelection, *, activity_entity: str,
                        timezone: str | None = None, skip_bad_lines: bool = False) -> SensorLog:
    """The activity entity's states as annotations and the mapped entities' on-intervals. A row
    that breaks a rule is an error, or with ``skip_bad_lines`` left out (see :meth:`SensorLog.bad`)."""
    source = str(path)
    rows, header = csv_table(read_text(Path(path)), source, COLUMNS)
    column = {name: header.index(name) for name in COLUMNS}
    sensor_log = SensorLog("home-assistant", (source,), skip_bad_lines=skip_bad_lines, sensor_rule=SENSOR_RULE)
    optional = {name: header.index(name) for name in OPTIONAL_COLUMNS if name in header}
    extra = [h for h in header if h not in COLUMNS and h not in OPTIONAL_COLUMNS]
    if extra:
        sensor_log.notes.append(f"columns not used: {', '.join(extra)}")
    zone = time_zone(timezone) if timezone is not None else None
    local: Callable[[datetime], datetime] = (lambda t: t) if zone is None else (
        lambda t: t.astimezone(zone).replace(tzinfo=None) if t.tzinfo is not None else t)
    aware: list[bool] = []  # whether the first good row's timestamp carries an offset
    last_row: dict[str, tuple[datetime, int]] = {}
    states: list[tuple[datetime, str, int]] = []  # the activity entity's rows
    on_since: dict[str, datetime] = {}
    sensor_since: dict[str, datetime] = {}  # every kept sensor -> when it went on
    no_data: dict[str, int] = {}
    last_local: dict[str, datetime] = {}
    repeated = 0  # rows in the hour a clock change repeats, held at the entity's previous local time
    for line, row in rows[1:]:
        try:  # every check first: a row left out changes nothing
            entity, state, moment, choice = _row(row, header, column, line, source, aware, last_row, selection,
                                                 activity_entity)
        except DataError as err:
            sensor_log.bad(err)
            continue
        if not aware:
            aware.append(moment.tzinfo is not None)
            if aware[0] and zone is None:
                raise DataError("timestamps carry a UTC offset: give the home's time zone (--timezone, e.g. "
                                "Europe/Amsterdam) so that its days start at its own 06:00", source=source, line=line,
                                field="last_changed")
        last_row[entity] = (moment, line)
        moment = local(moment)
        if entity in last_local and moment < last_local[entity]:
            moment = last_local[entity]
            repeated += 1
        last_local[entity] = moment
        sensor_log.events[entity] += 1
        if entity == activity_entity:  # the activity, not a sensor: its rows are no sign of the recorder
            sensor_log.saw(moment, line=line)
            states.append((moment, state, line))
            continue
        sensor_log.heard(moment, line=line)
        if choice is not None or entity.split(".", 1)[0] in SENSOR_DOMAINS:
            if entity not in sensor_log.sensors:
                cell = {name: _clean(row[i]) for name, i in optional.items() if i < len(row)}
                sensor_log.sensor(entity, sensor_type(entity, cell.get("device_class", "")),
                                  selection.mapped_room(entity) or slug(cell.get("area", "")))
            if state.lower() in ON_STATES:
                sensor_since.setdefault(entity, moment)
            elif entity in sensor_since:
                sensor_log.sensor_on(entity, sensor_since.pop(entity), moment)
        if choice is None:
            continue
        key = state.lower()
        if key in NO_DATA:
            no_data[entity] = no_data.get(entity, 0) + 1
        if key in ON_STATES:
            on_since.setdefault(entity, moment)
        elif entity in on_since:
            sensor_log.activations.setdefault(entity, []).append(Activation(on_since.pop(entity), moment))
    if not states:
        shown = ", ".join(sorted(e for e in sensor_log.events if e.startswith(("input_select.", "sensor.")))[:5])
        raise DataError(f"the activity entity {show(activity_entity)} is not in the export"
                        + (f" (entities such as {shown})" if shown else ""), source=source)
    _finish(sensor_log, states, on_since, no_data, activity_entity, source)
    assert sensor_log.last is not None
    still_on = []
    for entity, start in sensor_since.items():  # objects among them are noted by _finish
        sensor_log.sensor_on(entity, start, sensor_log.last)
        if selection.choices[entity].object is None:
            still_on.append(f"{entity} (since {start})")
    if still_on:
        sensor_log.notes.append("sensors of no object still on at the end of the export, counted as on until it ends "
                                f"(events/): {', '.join(still_on)}")
    if repeated:
        sensor_log.notes.append(f"rows in an hour that a clock change repeats: {repeated}; each is held at its "
                                "entity's previous local time, so that the home's clock never runs backwards")
    return sensor_log


def _row(row: list[str], header: list[str], column: dict[str, int], line: int, source: str, aware: list[bool],
         last_row: dict[str, tuple[datetime, int]], selection: ObjectSelection,
         activity_entity: str) -> tuple[str, str, datetime, str | None]:
    """One row checked: (entity, state, its time as written, the object it is or None). Changes
    nothing but the selection's record of the entity."""
    if len(row) > len(header) or len(row) <= max(column.values()):  # short: cells of attribute columns left out
        raise _ragged(source, line, row, header)
    entity = _clean(row[column["entity_id"]])
    state = _clean(row[column["state"]])
    if not _ENTITY.fullmatch(entity):
        raise DataError(f"{show(entity)} is not an entity id (domain.name, lower case)", source=source, line=line,
                        field="entity_id")
    moment = parse_iso_8601(_clean(row[column["last_changed"]]), source=source, line=line, field="last_changed")
    if aware and aware[0] != (moment.tzinfo is not None):
        raise DataError("a timestamp without a UTC offset among timestamps with one (or the other way round)",
                        source=source, line=line, field="last_changed")
    before = last_row.get(entity)
    if before is not None and moment < before[0]:
        raise DataError(f"{moment} is before this entity's previous row ({before[0]}, line {before[1]}): an "
                        "entity's rows must be in time order", source=source, line=line, field="last_changed")
    if entity == activity_entity:
        if state and state.lower() not in NO_DATA:
            _label(state, source, line, "state", "activity")
        return entity, state, moment, None
    sensor = Sensor(entity, entity.split(".", 1)[1], entity.split(".", 1)[0], "")
    if selection.decide(sensor, source=source, line=line).object is None:
        selection.choose(sensor, source=source, line=line)
        return entity, state, moment, None
    if state.lower() not in ON_STATES | OFF_STATES | NO_DATA:
        raise DataError(f"{show(state)} is not a state of a mapped binary sensor (on, off, open, closed, "
                        "unavailable, unknown)", source=source, line=line, field="state")
    return entity, state, moment, selection.choose(sensor, source=source, line=line).object


def _finish(sensor_log: SensorLog, states: list[tuple[datetime, str, int]], on_since: dict[str, datetime],
            no_data: dict[str, int], activity_entity: str, source: str) -> None:
    """States to annotations (each until the next; the last until the export ends; a repeated
    state extends the one before), and the notes."""
    assert sensor_log.last is not None
    kept: list[Annotation] = []
    for (start, state, line), (end, _, _) in zip(states, states[1:] + [(sensor_log.last, "", 0)]):
        if state.lower() in NO_DATA or not state:
            continue
        activity = _label(state, source, line, "state", "activity")
        if kept and kept[-1].activity == activity and kept[-1].end == start:
            previous = kept.pop()
            start, line = previous.start, previous.line
        kept.append(Annotation(activity, start, end, source, line, f"{activity_entity}: {state}"))
    sensor_log.annotations.extend(kept)
    sensor_log.notes.append(f"the last state of {activity_entity} holds until the export ends ({sensor_log.last})")
    for entity, start in on_since.items():
        sensor_log.activations.setdefault(entity, []).append(Activation(start, sensor_log.last))
        sensor_log.notes.append(f"{entity} is still on at the end of the export (since {start}): counted as on until "
                                "the export ends")
    for entity, count in no_data.items():
        times = "time" if count == 1 else "times"
        sensor_log.notes.append(f"{entity} was unavailable or unknown {count} {times} (counted as not in use)")


def import_home_assistant(*, history: Path, dest: Path, activity_entity: str, options: GridOptions | None = None,
                          objects: Path | None = None, timezone: str | None = None,
                          skip_bad_lines: bool = False) -> ImportResult:
    """Import a Home Assistant history CSV into the household folder ``dest``; the activity is
    ``activity_entity``'s state, the objects the entities ``objects`` maps. ``skip_bad_lines``
    leaves out rows that break a rule (listed in the report) instead of stopping."""
    options = options if options is not None else GridOptions()
    options.check()
    mapping = read_mapping(objects) if objects is not None else None
    if mapping is not None and activity_entity in mapping.rows:
        raise DataError(f"{show(activity_entity)} is the activity entity; it cannot also be an object",
                        source=mapping.source, line=mapping.rows[activity_entity].line, field="sensor")
    selection = ObjectSelection(mapping=mapping, default=default_rule, default_help=DEFAULT_RULE)
    sensor_log = read_home_assistant(history, selection, activity_entity=activity_entity, timezone=timezone,
                                     skip_bad_lines=skip_bad_lines)
    settings = {"activity_entity": activity_entity, "timezone": timezone, "skip_bad_lines": skip_bad_lines}
    return write_import(sensor_log=sensor_log, selection=selection, options=options, dest=dest, settings=settings)
