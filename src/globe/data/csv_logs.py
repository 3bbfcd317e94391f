"""Read, validate and write the CSV observation-log format (HOMER+'s and a user's own).

A household folder holds ``nodes.csv`` and ``train/NNN.csv``, ``test/NNN.csv`` day files. A day
file has the columns ``minute``, ``activity``, then one column per movable node (named by its
class) whose value is the ``class#id`` of the node it is on or in. Every problem is reported
with file, line and column; nothing is guessed.
"""

from __future__ import annotations

import csv
import io
from pathlib import Path
from typing import Iterable

from globe.data.locate import household_dir
from globe.data.records import Day, Household, Node, Split
from globe.errors import DataError

NODE_COLUMNS = ("node", "class", "category", "movable", "start_location")
FIXED_COLUMNS = ("minute", "activity")


def _read_rows(path: Path) -> list[list[str]]:
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError as err:
        raise DataError("file not found", source=str(path)) from err
    except UnicodeDecodeError as err:
        raise DataError(f"not UTF-8 text ({err.reason})", source=str(path)) from err
    rows = [row for row in csv.reader(io.StringIO(text))]
    if not rows or not any(cell.strip() for cell in rows[0]):
        raise DataError("empty file (expected a header line)", source=str(path), line=1)
    return rows


def _check_header(path: Path, header: list[str], required: Iterable[str]) -> None:
    for name in required:
        if name not in header:
            raise DataError(
                f"missing column (header has {', '.join(header[:6])}{', ...' if len(header) > 6 else ''})",
                source=str(path), line=1, field=name,
            )
    seen: set[str] = set()
    for name in header:
        if name in seen:
            raise DataError("duplicate column", source=str(path), line=1, field=name)
        seen.add(name)


def _ragged(path: Path, lineno: int, row: list[str], header: list[str]) -> DataError:
    """A row with too few fields names the first column it lacks."""
    field = header[len(row)] if len(row) < len(header) else None
    return DataError(f"ragged row: {len(row)} fields, header has {len(header)}", source=str(path), line=lineno, field=field)


def read_nodes(path: Path) -> tuple[Node, ...]:
    """Read ``nodes.csv``: every node of the home and where each starts the day."""
    rows = _read_rows(path)
    header = rows[0]
    _check_header(path, header, NODE_COLUMNS)
    col = {name: header.index(name) for name in NODE_COLUMNS}
    nodes: list[Node] = []
    for lineno, row in enumerate(rows[1:], start=2):
        if not row:
            continue
        if len(row) != len(header):
            raise _ragged(path, lineno, row, header)
        movable = row[col["movable"]].strip()
        if movable not in ("0", "1"):
            raise DataError(f"{movable!r} is not 0 or 1", source=str(path), line=lineno, field="movable")
        label = row[col["node"]].strip()
        if "#" not in label:
            raise DataError(f"{label!r} is not of the form class#id", source=str(path), line=lineno, field="node")
        nodes.append(Node(label, row[col["class"]].strip(), row[col["category"]].strip(),
                          movable == "1", row[col["start_location"]].strip()))
    labels = {n.node for n in nodes}
    for lineno, n in enumerate(nodes, start=2):
        if n.start_location not in labels:
            raise DataError(f"unknown location {n.start_location!r}", source=str(path), line=lineno, field="start_location")
    if not any(n.movable for n in nodes):
        raise DataError("no movable node (column 'movable' is 0 everywhere)", source=str(path))
    return tuple(nodes)


def read_day(path: Path, objects: tuple[str, ...], locations: frozenset[str], name: str | None = None) -> Day:
    """Read and validate one day file against the home's object columns and locations."""
    rows = _read_rows(path)
    header = rows[0]
    _check_header(path, header, FIXED_COLUMNS + objects)
    extra = [h for h in header if h not in FIXED_COLUMNS and h not in objects]
    if extra:
        raise DataError("not a movable node of this home (see nodes.csv)", source=str(path), line=1, field=extra[0])
    i_min, i_act = header.index("minute"), header.index("activity")
    obj_idx = [header.index(o) for o in objects]
    minutes: list[int] = []
    activities: list[str] = []
    states: list[tuple[str, ...]] = []
    for lineno, row in enumerate(rows[1:], start=2):
        if not row:
            continue
        if len(row) != len(header):
            raise _ragged(path, lineno, row, header)
        raw_minute = row[i_min].strip()
        try:
            minute = int(raw_minute)
        except ValueError:
            raise DataError(f"{raw_minute!r} is not a whole number of minutes", source=str(path), line=lineno, field="minute") from None
        if minutes and minute <= minutes[-1]:
            raise DataError(f"{minute} is not after {minutes[-1]} (minutes must increase)", source=str(path), line=lineno, field="minute")
        activity = row[i_act].strip()
        if not activity:
            raise DataError("empty activity", source=str(path), line=lineno, field="activity")
        state = tuple(row[i].strip() for i in obj_idx)
        for obj, loc in zip(objects, state):
            if loc not in locations:
                raise DataError(f"unknown location {loc!r} (not in nodes.csv)", source=str(path), line=lineno, field=obj)
        minutes.append(minute)
        activities.append(activity)
        states.append(state)
    if not minutes:
        raise DataError("no observation rows after the header", source=str(path), line=2)
    return Day(name or path.stem, tuple(minutes), tuple(activities), tuple(states), str(path))


def load_household(root: Path, name: str) -> Household:
    """Load ``root/Household<name>`` (or ``root/<name>``): nodes and every train/test day."""
    folder = household_dir(Path(root), name)
    nodes = read_nodes(folder / "nodes.csv")
    objects = tuple(n.cls for n in nodes if n.movable)
    if len(set(objects)) != len(objects):
        raise DataError("class names of movable nodes must be unique", source=str(folder / "nodes.csv"), field="class")
    locations = frozenset(n.node for n in nodes)
    splits: dict[Split, tuple[Day, ...]] = {}
    for split in ("train", "test"):
        files = sorted((folder / split).glob("*.csv")) if (folder / split).is_dir() else []
        splits[split] = tuple(read_day(f, objects, locations, f"{split}/{f.stem}") for f in files)
    if not splits["train"]:
        raise DataError("no training days (expected train/*.csv)", source=str(folder))
    return Household(name, nodes, objects, splits["train"], splits["test"], str(folder))


def format_day(day: Day, objects: tuple[str, ...]) -> str:
    """Serialise a day exactly as the shipped files are written (LF line ends, no quoting)."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(FIXED_COLUMNS + objects)
    for minute, activity, state in zip(day.minutes, day.activities, day.locations):
        writer.writerow((minute, activity, *state))
    return out.getvalue()


def write_day(path: Path, day: Day, objects: tuple[str, ...]) -> None:
    """Write a day file atomically (a crash never leaves half a file)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(format_day(day, objects), encoding="utf-8")
    tmp.replace(path)


def write_nodes(path: Path, nodes: Iterable[Node]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(NODE_COLUMNS)
    for n in nodes:
        writer.writerow((n.node, n.cls, n.category, int(n.movable), n.start_location))
    path.write_text(out.getvalue(), encoding="utf-8")
