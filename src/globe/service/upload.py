"""A household sent over HTTP: its map (the rows of ``nodes.csv``) and optional day logs (the text
of day files), validated by exactly the rules of the files on disk (the data layer's own parsers,
:func:`globe.data.csv_logs.parse_nodes_text` and :func:`~globe.data.csv_logs.parse_day_text`),
with errors naming ``nodes[i].field`` or ``days[i].column`` and the line. Nothing here touches
the server's disk: clients never name a path.
"""

from __future__ import annotations

import csv
import io
import sys
from typing import Any, Iterable, Mapping, Sequence

from globe.data.csv_logs import (
    NODE_COLUMNS,
    _check_nesting,
    _clean,
    _label,
    _parse_minute,
    check_map,
    check_step,
    household_step,
    parse_day_text,
    parse_nodes_text,
)
from globe.data.records import Day, Household, Node
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
    if not any(n.movable for n in nodes):  # a home the robot could fetch nothing in
        raise DataError("no movable node (every node has movable false)", field=NODES)
    return tuple(Node(sys.intern(n.node), sys.intern(n.cls), n.category, n.movable, sys.intern(n.start_location)) for n in nodes)


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
    """One day file's text (and each row's line), validated exactly like a file on disk.

    Day files as GLOBE writes them (header ``minute,activity,<objects in map order>``, no quotes,
    no carriage returns, no blank lines) take a fast path that applies the same rules with the
    data layer's own helpers, but checks each distinct row of locations once (objects rarely
    move, so most rows repeat the previous one); any other text, and any row the fast path
    would reject, goes through :func:`parse_day_text` itself, so the result and the message are
    the data layer's."""
    header = text[: text.find("\n")] if "\n" in text else text
    plain = (header.split(",") == ["minute", "activity", *objects] and '"' not in text and "\r" not in text
             and "\n\n" not in text and not text.startswith("\ufeff"))
    if plain:
        day = _fast_day(text, objects, locations, name, owners or {})
        if day is not None:
            return day
    return parse_day_text(text, objects, locations, name, name, owners)


def _fast_day(text: str, objects: tuple[str, ...], locations: frozenset[str], name: str,
              owners: dict[str, str]) -> tuple[Day, tuple[int, ...]] | None:
    """The fast path of :func:`parse_day`; None as soon as a row needs the full reader."""
    shared = {loc: loc for loc in locations}
    column_of = {label: k for k, label in enumerate(owners.get(o, "") for o in objects) if label}
    seen: dict[str, tuple[str, ...]] = {}
    width = len(objects) + 2
    minutes: list[int] = []
    activities: list[str] = []
    states: list[tuple[str, ...]] = []
    lines = text.split("\n")
    if lines and not lines[-1]:
        lines.pop()
    try:
        for lineno, line in enumerate(lines[1:], start=2):
            i1 = line.find(",")
            i2 = line.find(",", i1 + 1)
            if i1 < 0 or i2 < 0:
                return None
            tail = line[i2 + 1:]
            state = seen.get(tail)
            if state is None:
                cells = tail.split(",")
                if len(cells) != width - 2:
                    return None
                found = [shared.get(_clean(c)) for c in cells]
                if None in found:
                    return None
                state = tuple(found)  # type: ignore[arg-type]
                if column_of and not column_of.keys().isdisjoint(state):
                    _check_nesting(state, objects, owners, column_of, name, lineno)
                seen[tail] = state
            minute = _parse_minute(_clean(line[:i1]), name, lineno)
            if minutes and minute <= minutes[-1]:
                return None
            activity = _label(_clean(line[i1 + 1:i2]), name, lineno, "activity", "activity")
            minutes.append(minute)
            activities.append(sys.intern(activity))
            states.append(state)
    except DataError:
        return None  # the full reader reports it, with its own message
    if not minutes:
        return None
    return Day(name, tuple(minutes), tuple(activities), tuple(states), name), tuple(range(2, 2 + len(minutes)))


def household_from(name: str, nodes: tuple[Node, ...], day_texts: Iterable[str], *, max_label: int = 128,
                   step_minutes: int | None = None) -> Household:
    """A validated household (its days as ``train``) from a map and day texts; every day must
    keep the household's step (``step_minutes``, else the most common gap), as on disk."""
    objects = tuple(n.cls for n in nodes if n.movable)
    owners = {n.cls: n.node for n in nodes if n.movable}
    locations = frozenset(n.node for n in nodes)
    parsed = [parse_day(text, objects, locations, f"days[{i}]", owners) for i, text in enumerate(day_texts)]
    step = step_minutes or household_step(d for d, _ in parsed)
    days = tuple(check_step(d, lines, step) if step else d for d, lines in parsed)
    for i, d in enumerate(days):
        for lineno, activity in zip(parsed[i][1], d.activities):
            if len(activity) > max_label:
                raise LimitError(f"activity longer than {max_label} characters", source=f"days[{i}]", line=lineno, field="activity")
    days = tuple(Day(d.name, d.minutes, tuple(sys.intern(a) for a in d.activities), d.locations, d.source) for d in days)
    return Household(name, nodes, objects, days, (), "upload")
