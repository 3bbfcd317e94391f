"""A household sent over HTTP: its map (the rows of ``nodes.csv``) and optional day logs (the text
of day files), validated by exactly the rules of the files on disk (the data layer's own parsers,
:func:`globe.data.csv_logs.parse_nodes_text` and :func:`~globe.data.csv_logs.parse_day_text`),
with errors naming ``nodes[i].field`` or ``days[i].column`` and the line. Nothing here touches
the server's disk: clients never name a path.
"""

from __future__ import annotations

import csv
import datetime as dt
import io
import operator
import sys
from itertools import chain, repeat
from typing import Any, Iterable, Mapping, Sequence

from globe.data.csv_logs import (
    NODE_COLUMNS,
    _check_nesting,
    _clean,
    _parse_minute,
    activity_label,
    check_map,
    check_step,
    household_step,
    map_rules,
    parse_day_text,
    parse_nodes_text,
)
from globe.data.records import Day, Household, Node
from globe.data.sensors import SensorData, SensorDay, day_span, day_stem, parse_events_text, parse_sensors_text
from globe.errors import DataError, LimitError

NODES = "nodes"


def parse_nodes(rows: Sequence[Mapping[str, Any]], *, max_label: int = 128) -> tuple[Node, ...]:
    """Nodes from ``[{"node", "class", "category", "movable", "start_location"}, ...]``."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(NODE_COLUMNS)
    for i, row in enumerate(rows):
        where = f"nodes[{i}]"
        cells = []
        for col in NODE_COLUMNS:
            if col not in row:
                raise DataError(f"{where}: missing {col!r}", field=f"{where}.{col}")
            v = row[col]
            if col == "movable":
                if v not in (True, False, 0, 1, "0", "1"):
                    raise DataError(f"{where}: movable {v!r} is not true/false or 0/1", field=f"{where}.movable")
                v = "1" if v in (True, 1, "1") else "0"
            elif not isinstance(v, str):
                raise DataError(f"{where}: {col!r} must be a string", field=f"{where}.{col}")
            elif len(v) > max_label:
                raise LimitError(f"{where}: {col!r} is longer than {max_label} characters", field=f"{where}.{col}")
            cells.append(v)
        writer.writerow(cells)
    try:
        nodes = parse_nodes_text(out.getvalue(), NODES)
    except DataError as err:
        raise _renamed(err) from None
    return tuple(Node(sys.intern(n.node), sys.intern(n.cls), n.category, n.movable, sys.intern(n.start_location))
                 for n in nodes)


def check_nodes(nodes: Sequence[Node]) -> None:
    """The map rules for nodes read some other way (the same :func:`check_map`)."""
    check_map(nodes, NODES)


def _renamed(err: DataError) -> DataError:
    """``nodes`` line n is ``nodes[n - 2]`` of the request (line 1 is the header we wrote)."""
    if err.source == NODES and err.line and err.line >= 2:
        where = f"nodes[{err.line - 2}]"
        return type(err)(f"{where}: {err.message}", field=f"{where}.{err.field}" if err.field else where)
    return type(err)(err.message, field=NODES)


def parse_day(text: str, objects: tuple[str, ...], locations: frozenset[str], name: str,
              owners: dict[str, str] | None = None) -> tuple[Day, tuple[int, ...]]:
    """One day file's text (and each row's line), validated exactly like a file on disk (see
    :class:`DayParser`, which parses many days of one household faster)."""
    return DayParser(objects, locations, owners).parse(text, name)


def day_fields(text: str) -> tuple[tuple[str, ...], tuple[str, ...], list[int], list[str]] | None:
    """The cells the fast path reads from a day text: each line's minute and activity (lines
    after the header), and the lines where the rest (its locations) differs from the line
    before's, with that rest; None for a blank line (a final newline aside) or a line after the
    header with fewer than three cells (the data layer reports them). Objects rarely move, so
    the rest of a line is compared in place with the last one that changed, and only a changed
    rest becomes a string: a day's ~1 KB lines are never all copied, which kept freed memory
    scattered between each household's models."""
    n = len(text) - text.endswith("\n")
    pos = text.find("\n", 0, n) + 1
    if pos <= 1:  # one line, or a blank header
        return None
    find, starts_with = text.find, text.startswith
    minutes: list[str] = []
    activities: list[str] = []
    starts: list[int] = []
    tails: list[str] = []
    tail = ""
    while pos <= n:
        end = find("\n", pos, n)
        end = n if end < 0 else end
        first = find(",", pos, end)
        second = find(",", first + 1, end) if first >= 0 else -1
        if second < 0:  # a blank line, or fewer than three cells
            return None
        minutes.append(text[pos:first])
        activities.append(text[first + 1: second])
        if not tails or end - second - 1 != len(tail) or not starts_with(tail, second + 1, end):
            tail = text[second + 1: end]
            starts.append(len(minutes) - 1)
            tails.append(tail)
        pos = end + 1
    return tuple(minutes), tuple(activities), starts, tails


class DayParser:
    """Parses the day texts of one household (and each row's line), validated exactly like files
    on disk.

    Day files as GLOBE writes them (header ``minute,activity,<objects in map order>``, no quotes,
    no carriage returns, no blank lines) take a fast path that applies the same rules with the
    data layer's own helpers, but checks each distinct row of locations, minute and activity
    cell once for all the household's days (objects rarely move, every day starts where the
    last one ended, and the minutes repeat daily); any other text, and any row the fast path
    would reject, goes through :func:`parse_day_text` itself, so the result and the message are
    the data layer's."""

    def __init__(self, objects: tuple[str, ...], locations: frozenset[str],
                 owners: dict[str, str] | None = None) -> None:
        self.objects, self.locations, self.owners = objects, locations, owners or {}
        self._shared = {loc: loc for loc in locations}  # one string per label, whatever text it came from
        self._column_of = {label: k for k, label in enumerate(self.owners.get(o, "") for o in objects) if label}
        self._header = ["minute", "activity", *objects]
        self._rows: dict[str, tuple[str, ...]] = {}  # cells of a valid row of locations -> the row
        self._minutes: dict[str, int] = {}
        self._activities: dict[str, str] = {}

    def parse(self, text: str, name: str) -> tuple[Day, tuple[int, ...]]:
        header = text[: text.find("\n")] if "\n" in text else text
        plain = (header.split(",") == self._header and '"' not in text and "\r" not in text
                 and not text.startswith("\ufeff"))  # blank lines: see _fast_day
        if plain:
            day = self._fast_day(text, name)
            if day is not None:
                return day
        return parse_day_text(text, self.objects, self.locations, name, name, self.owners)

    def _fast_day(self, text: str, name: str) -> tuple[Day, tuple[int, ...]] | None:
        """The fast path of :meth:`parse`; None as soon as a row needs the full reader (which
        reports it, with its own message and line). Rows are split and looked up in bulk; only
        the cells not seen in an earlier row or day are checked."""
        fields = day_fields(text)
        if fields is None:
            return None
        raw_minutes, raw_activities, starts, changed = fields
        rows, minute_of, activity_of = self._rows, self._minutes, self._activities
        n = len(raw_minutes)
        try:
            for tail in set(changed).difference(rows):
                row = self._row(tail, name)
                if row is None:
                    return None
                rows[tail] = row
            for raw in set(raw_minutes).difference(minute_of):
                minute_of[raw] = _parse_minute(_clean(raw), name, 0)
            for raw in set(raw_activities).difference(activity_of):
                activity_of[raw] = sys.intern(activity_label(raw, name, 0))
        except DataError:
            return None
        minutes = tuple(map(minute_of.__getitem__, raw_minutes))
        if not all(map(int.__lt__, minutes, minutes[1:])):
            return None
        spans = map(operator.sub, [*starts[1:], n], starts)
        locations = tuple(chain.from_iterable(map(repeat, map(rows.__getitem__, changed), spans)))
        day = Day(name, minutes, tuple(map(activity_of.__getitem__, raw_activities)), locations, name)
        return day, tuple(range(2, 2 + len(minutes)))

    def _row(self, tail: str, name: str) -> tuple[str, ...] | None:
        """The locations of one row's object cells, if they are valid (DataError if an object is
        inside itself)."""
        cells = tail.split(",")
        if len(cells) != len(self.objects):
            return None
        blanks = " " in tail or "\t" in tail  # cells lose surrounding blanks (_clean); most rows have none
        found = [self._shared.get(_clean(c)) for c in cells] if blanks else list(map(self._shared.get, cells))
        if None in found:
            return None
        row = tuple(found)
        if self._column_of and not self._column_of.keys().isdisjoint(row):
            _check_nesting(row, self.objects, self.owners, self._column_of, name, 0)  # type: ignore[arg-type]
        return row  # type: ignore[return-value]


def household_from(name: str, nodes: tuple[Node, ...], day_texts: Iterable[str], *, max_label: int = 128,
                   step_minutes: int | None = None, dates: Sequence[dt.date | None] | None = None) -> Household:
    """A validated household (its days as ``train``) from a map and day texts; every day must
    keep the household's step (``step_minutes``, else the most common gap), as on disk. A day
    with a date (``dates``, one per text) is named by it, so that models can read its weekday."""
    objects = tuple(n.cls for n in nodes if n.movable)
    parser = DayParser(objects, *map_rules(nodes))
    parsed = [parser.parse(text, f"days[{i}]") for i, text in enumerate(day_texts)]
    step = step_minutes or household_step(d for d, _ in parsed)
    days = tuple(check_step(d, lines, step) if step else d for d, lines in parsed)
    for i, d in enumerate(days):
        if max(map(len, set(d.activities)), default=0) > max_label:  # which line: only when one is too long
            lineno = next(n for n, a in zip(parsed[i][1], d.activities) if len(a) > max_label)
            raise LimitError(f"activity longer than {max_label} characters", source=f"days[{i}]", line=lineno,
                             field="activity")
    if dates is not None and len(dates) != len(days):
        raise DataError(f"{len(dates)} dates for {len(days)} days; give one date per day, or none", field="dates")
    given = [None] * len(days) if dates is None else dates
    names = [d.name if when is None else when.isoformat() for d, when in zip(days, given)]
    days = tuple(Day(n, d.minutes, tuple(map(sys.intern, d.activities)), d.locations, d.source, d.covering)
                 for n, d in zip(names, days))
    return Household(name, nodes, objects, days, (), "upload")


def sensors_from(rows: Sequence[Mapping[str, Any]], events: Sequence[str | None] | None, household: Household,
                 step_minutes: int | None) -> SensorData:
    """A home's sensors sent over HTTP (the rows of ``sensors.csv``) and each training day's
    activations (the text of its ``events/<day>.csv``, in the order of the days; None: not
    recorded), by the rules of the files on disk (:mod:`globe.data.sensors`), errors naming
    ``sensors[i].field`` or ``events[i]`` and the line."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(("sensor", "type", "room", "object"))
    for row in rows:
        writer.writerow([row.get(k, "") for k in ("sensor", "type", "room", "object")])
    try:
        sensors = parse_sensors_text(out.getvalue(), "sensors", household.objects)
    except DataError as err:
        where = f"sensors[{err.line - 2}]" if err.line and err.line >= 2 else "sensors"
        raise type(err)(f"{where}: {err.message}", field=f"{where}.{err.field}" if err.field else where) from None
    texts = list(events or [])
    if len(texts) > len(household.train):
        raise DataError(f"{len(texts)} events texts for {len(household.train)} days; give one per day, in order "
                        "(null: not recorded)", field="events")
    step = step_minutes or household_step(household.train) or 0
    days: dict[str, SensorDay] = {}
    for i, (text, day) in enumerate(zip(texts, household.train)):
        if text is None or not day.minutes:
            continue
        where = f"events[{i}]"
        try:
            days[day_stem(day.name)] = parse_events_text(text, sensors, day_stem(day.name), where,
                                                         day_span(day.minutes, step))
        except DataError as err:
            detail = f"{where}:{err.line}: {err.message}" if err.line else f"{where}: {err.message}"
            raise type(err)(detail, field=f"{where}.{err.field}" if err.field else where) from None
    return SensorData(sensors, days)
