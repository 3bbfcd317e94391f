"""Which sensors become objects a robot can fetch, and the map (``nodes.csv``) they live in.

A smart home's sensors are mostly not things: motion sensors, doors, thermometers. Only a sensor
on something a person takes or opens (a cupboard, the fridge, the kettle) becomes an object
column, and only when the user maps it (``--objects FILE``) or the format's documented default
rule picks it by sensor type; every sensor's fate is written to the import report. An object sits
at its home place (its room, or a piece of furniture in it) and moves to its room's ``in_use``
place in the steps it is in use (while its sensor is on, or in the step a use begins: see
:mod:`globe.data.importers.grid`), so the object models see a movement there and back.

The mapping file is CSV with the columns ``sensor`` and ``object`` and, optionally, ``room`` and
``furniture``. Several sensors may map to one object (both fridge doors); one sensor may not map
to two.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

from globe.data.csv_logs import RESERVED_COLUMNS, csv_table
from globe.data.importers.text import read_text, show, slug, table_cells
from globe.data.records import IN_USE_CLASS, Node
from globe.errors import DataError

HOME_CLASS = "home"  # the top of the map (category Home), as in HOMER+
DEFAULT_ROOM = "room"  # the room of objects whose log and mapping name none
MAPPING_COLUMNS = ("sensor", "object")
MAPPING_OPTIONAL = ("room", "furniture")
_NAME = re.compile(r"[\w.-]+")


@dataclass(frozen=True, slots=True)
class Sensor:
    """One sensor as a log describes it."""

    key: str  # as written in the log: 'I006', '7', 'Cupboard Magnetic Kitchen', 'binary_sensor.fridge'
    name: str  # what it is called (the default object name comes from it)
    kind: str  # its type where the log or sensor list says ('item', 'motion', 'Magnetic'), else ''
    room: str  # its place where known, else ''


@dataclass(frozen=True, slots=True)
class Choice:
    """What became of one sensor: an object column (``object``) or none, and why."""

    object: str | None
    room: str
    furniture: str
    why: str


@dataclass(frozen=True, slots=True)
class ObjectSpec:
    """One object column: its class, its home place and the sensors that mark its use."""

    object: str
    room: str
    furniture: str  # '' = directly in the room
    sensors: tuple[str, ...]
    why: str


@dataclass(frozen=True, slots=True)
class MappingRow:
    object: str
    room: str
    furniture: str
    line: int


@dataclass(frozen=True, slots=True)
class ObjectMapping:
    """The user's ``--objects`` file: sensor key -> object, in file order."""

    source: str
    rows: dict[str, MappingRow]


DefaultRule = Callable[[Sensor], tuple[bool, str]]  # (is an object, why), for the report


def _name(value: str, *, what: str, source: str, line: int, field: str) -> str:
    if not _NAME.fullmatch(value):
        raise DataError(f"{what} {show(value)} must be letters, digits, '_', '-' or '.' (it becomes a node class)",
                        source=source, line=line, field=field)
    return value


def read_mapping(path: Path) -> ObjectMapping:
    """The ``--objects`` file, checked: known columns, valid names, each sensor once, one room per
    object."""
    source = str(path)
    rows, header = csv_table(read_text(Path(path)), source, MAPPING_COLUMNS)
    unknown = [h for h in header if h not in MAPPING_COLUMNS + MAPPING_OPTIONAL]
    if unknown:
        raise DataError("unknown column (a mapping has sensor, object, and optionally room, furniture)",
                        source=source, line=1, field=unknown[0])
    mapping: dict[str, MappingRow] = {}
    homes: dict[str, tuple[str, str, int]] = {}
    for line, cell in table_cells(rows, header, source):
        sensor = cell["sensor"]
        if not sensor:
            raise DataError("empty sensor", source=source, line=line, field="sensor")
        if sensor in mapping:
            raise DataError(f"sensor {show(sensor)} is mapped twice (also line {mapping[sensor].line})", source=source,
                            line=line, field="sensor")
        obj = _name(cell["object"], what="object", source=source, line=line, field="object")
        if obj in RESERVED_COLUMNS:
            raise DataError(f"an object may not be called {show(obj)} (a day file's column of its own)", source=source,
                            line=line, field="object")
        room = cell.get("room", "")
        furniture = cell.get("furniture", "")
        if room:
            _name(room, what="room", source=source, line=line, field="room")
        if furniture:
            _name(furniture, what="furniture", source=source, line=line, field="furniture")
        if obj in homes and homes[obj][:2] != (room, furniture):
            raise DataError(f"object {show(obj)} is placed differently at line {homes[obj][2]} (one object, one home "
                            "place)", source=source, line=line, field="room")
        homes.setdefault(obj, (room, furniture, line))
        mapping[sensor] = MappingRow(obj, room, furniture, line)
    return ObjectMapping(source, mapping)


class ObjectSelection:
    """Decides once per sensor whether it is an object: by the user's mapping when given (sensors
    it does not name are left out), else by the format's default rule."""

    def __init__(self, *, mapping: ObjectMapping | None, default: DefaultRule, default_help: str) -> None:
        self.mapping = mapping
        self.default = default
        self.default_help = default_help
        self.choices: dict[str, Choice] = {}
        self.first_seen: dict[str, tuple[str, int]] = {}

    def choose(self, sensor: Sensor, *, source: str, line: int) -> Choice:
        """The choice for a sensor first met at ``source:line`` (later calls return it unchanged)."""
        choice = self.decide(sensor, source=source, line=line)
        if sensor.key not in self.choices:
            self.choices[sensor.key] = choice
            self.first_seen[sensor.key] = (source, line)
        return choice

    def decide(self, sensor: Sensor, *, source: str, line: int) -> Choice:
        """What :meth:`choose` answers, without recording the sensor (its line is still being checked)."""
        known = self.choices.get(sensor.key)
        if known is not None:
            return known
        room_of_log = slug(sensor.room)
        if self.mapping is not None:
            row = self.mapping.rows.get(sensor.key)
            if row is None:
                choice = Choice(None, "", "", f"not in the mapping {self.mapping.source}")
            else:
                choice = Choice(row.object, row.room or room_of_log or DEFAULT_ROOM, row.furniture,
                                f"mapped at {self.mapping.source}:{row.line}")
        else:
            is_object, why = self.default(sensor)
            name = slug(sensor.name)
            if is_object and (not name or name in RESERVED_COLUMNS):
                why_not = "no usable name" if not name else f"the name {name!r}, a day file's column of its own,"
                raise DataError(f"sensor {show(sensor.key)} has {why_not} for an object; map it with --objects",
                                source=source, line=line)
            choice = Choice(name if is_object else None, room_of_log or DEFAULT_ROOM, "", why)
        return choice

    def mapped_room(self, key: str) -> str:
        """The room the user's mapping gives the sensor ``key`` ('' when it gives none): the room a
        kept sensor is listed in, before what the log says (the user's word wins, as for objects)."""
        row = self.mapping.rows.get(key) if self.mapping is not None else None
        return row.room if row is not None else ""

    def objects(self) -> tuple[ObjectSpec, ...]:
        """The object columns, once every sensor was seen: in mapping order, else by name. A
        mapped sensor the log never mentions is an error (a typo would leave an object unused)."""
        if self.mapping is not None:
            for key, row in self.mapping.rows.items():
                if key not in self.choices:
                    raise DataError(f"sensor {show(key)} is not in the log (remove the line, or check the sensor's "
                                    "name as the import report lists it)", source=self.mapping.source,
                                    line=row.line, field="sensor")
            order = {row.object: row.line for row in reversed(self.mapping.rows.values())}
        by_object: dict[str, list[str]] = {}
        for key, choice in self.choices.items():
            if choice.object is not None:
                by_object.setdefault(choice.object, []).append(key)
        if self.mapping is None:
            for obj, keys in by_object.items():
                if len(keys) > 1:
                    source, line = self.first_seen[keys[1]]
                    raise DataError(f"sensors {show(keys[0])} and {show(keys[1])} would both become object "
                                    f"{show(obj)}; name them in a mapping file (--objects)", source=source, line=line)
            order = {obj: 0 for obj in sorted(by_object)}
        specs = []
        for obj in sorted(by_object, key=lambda o: (order[o], o)):
            keys = by_object[obj]
            first = self.choices[keys[0]]
            other = next((k for k in keys if self.choices[k].room != first.room), None)
            if other is not None:
                source, line = self.first_seen[other]
                rooms = f"{first.room!r}, {self.choices[other].room!r}"
                raise DataError(f"sensors {show(keys[0])} and {show(other)} of object {show(obj)} are in different "
                                f"rooms ({rooms}); give the object's room in the mapping", source=source, line=line)
            whys = "; ".join(dict.fromkeys(self.choices[k].why for k in keys))
            specs.append(ObjectSpec(obj, first.room, first.furniture, tuple(keys), whys))
        return tuple(specs)


@dataclass(frozen=True, slots=True)
class HomeMap:
    """The nodes of an imported home and, per object, its home place and its in-use place."""

    nodes: tuple[Node, ...]
    home_of: dict[str, str]
    in_use_of: dict[str, str]


def build_map(objects: Sequence[ObjectSpec]) -> HomeMap:
    """``home#0`` on top (category Home), each room in it, each room's ``in_use`` place and
    furniture in the room, then the objects (category placable_objects, as HOMER+) at their home
    places. Ids count up from 1 in that order; with no objects the map is the home and one room."""
    nodes = [Node(f"{HOME_CLASS}#0", HOME_CLASS, "Home", False, f"{HOME_CLASS}#0")]
    rooms: dict[str, str] = {}
    in_use: dict[str, str] = {}
    furniture: dict[tuple[str, str], str] = {}

    def add(cls: str, category: str, movable: bool, parent: str) -> str:
        label = f"{cls}#{len(nodes)}"
        nodes.append(Node(label, cls, category, movable, parent))
        return label

    for spec in objects or (ObjectSpec("", DEFAULT_ROOM, "", (), ""),):
        if spec.room not in rooms:
            rooms[spec.room] = add(spec.room, "Rooms", False, nodes[0].node)
            in_use[spec.room] = add(IN_USE_CLASS, "InUse", False, rooms[spec.room])
        if spec.furniture and (spec.room, spec.furniture) not in furniture:
            furniture[spec.room, spec.furniture] = add(spec.furniture, "Furniture", False, rooms[spec.room])
    home_of: dict[str, str] = {}
    in_use_of: dict[str, str] = {}
    for spec in objects:
        place = furniture[spec.room, spec.furniture] if spec.furniture else rooms[spec.room]
        add(spec.object, "placable_objects", True, place)
        home_of[spec.object] = place
        in_use_of[spec.object] = in_use[spec.room]
    return HomeMap(tuple(nodes), home_of, in_use_of)
