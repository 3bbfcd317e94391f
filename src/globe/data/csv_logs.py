"""Read, validate and write the CSV observation-log format (HOMER+'s and a user's own).

A household folder holds ``nodes.csv`` and ``train/NNN.csv``, ``test/NNN.csv`` day files. A day
file has the columns ``minute``, ``activity``, then one column per movable node (named by its
class) whose value is the ``class#id`` of the node it is on or in. The rules are strict and
listed in the README ("Data format"); every violation is a :class:`DataError` naming file, line
and column. Nothing is guessed: the only transformation, resampling irregular minutes to the
household's step, happens when the configuration asks for it.
"""

from __future__ import annotations

import csv
import io
import re
import stat
import unicodedata
from collections import Counter
from itertools import chain, compress
from operator import sub
from pathlib import Path
from typing import TYPE_CHECKING, Iterable, Literal, Sequence

from globe.data.locate import household_dir
from globe.data.records import Day, Household, Node, Split
from globe.errors import DataError

if TYPE_CHECKING:
    from globe.data.sensors import SensorData

NODE_COLUMNS = ("node", "class", "category", "movable", "start_location")
FIXED_COLUMNS = ("minute", "activity")
COVERING = "covering"
RESERVED_COLUMNS = ("minute", "activity", COVERING)  # no object column may take these names
"""An optional column after ``activity``: the activity covering most of the row's step (the
importers write it; a movement can be credited to it, ``sequences.alignment = "most"``)."""
DAY_MINUTES = 1440  # minutes are 0..1440 (1440 = midnight at the end of the day)
ROOM_CATEGORIES = frozenset({"rooms", "room"})
HOME_CATEGORIES = frozenset({"home"})
Resample = Literal["none", "locf"]

_MINUTE = re.compile(r"[0-9]+")
_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f]")
_BIDI = re.compile("[\u061c\u200e\u200f\u202a-\u202e\u2066-\u2069]")  # text-direction marks, embeddings, isolates
_INVISIBLE = re.compile("[\u200b\u2060\ufeff]")  # zero-width space, word joiner, byte-order mark (zero-width no-break)
_SURROGATE = re.compile("[\ud800-\udfff]")  # only in text that did not come from valid UTF-8 (e.g. JSON's "\\ud800")
_BLANKS = " \t"


def _clean(cell: str) -> str:
    """Cells lose surrounding spaces and tabs, nothing else."""
    return cell.strip(_BLANKS)


def _short(text: str, limit: int = 64) -> str:
    return repr(text if len(text) <= limit else text[:limit] + "...")


# -- reading text -------------------------------------------------------------------------------


MAX_FILE_BYTES = 2 << 30  # a year of a busy home's events is some hundred megabytes


def _read_bytes(path: Path, kind: str = "CSV file") -> bytes:
    """The file's bytes; a folder, a missing or an unreadable file, something that is no file (a
    pipe would wait for ever, ``/dev/zero`` fill the memory) or one over :data:`MAX_FILE_BYTES` is
    a :class:`DataError`."""
    path = Path(path)
    if path.is_dir():
        raise DataError(f"is a folder, not a {kind}", source=str(path))
    try:
        info = path.stat()
        if not stat.S_ISREG(info.st_mode):
            raise DataError(f"is not a regular file (a pipe, a device or a socket), not a {kind}", source=str(path))
        if info.st_size > MAX_FILE_BYTES:
            raise DataError(f"is {info.st_size >> 20} MiB, larger than the {MAX_FILE_BYTES >> 30} GiB a {kind} may be "
                            "(split it)", source=str(path))
        return path.read_bytes()
    except FileNotFoundError as err:
        raise DataError("file not found", source=str(path)) from err
    except OSError as err:
        raise DataError(f"cannot read file: {err.strerror or err}", source=str(path)) from err


def _decode(data: bytes, source: str) -> str:
    """UTF-8 text, with or without a byte-order mark (Excel writes one)."""
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        line = data.count(b"\n", 0, err.start) + 1
        raise DataError(f"not UTF-8 text (byte {err.start}: {err.reason}); save the file as UTF-8",
                        source=source, line=line) from err


def _read_text(path: Path) -> str:
    """The file as text: UTF-8, with or without a byte-order mark."""
    return _decode(_read_bytes(path), str(path))


def _csv_rows(text: str, source: str) -> list[tuple[int, list[str]]]:
    """``(line, cells)`` per record; blank lines are skipped. ``line`` is where the record starts."""
    reader = csv.reader(io.StringIO(text, newline=""), strict=True)
    rows: list[tuple[int, list[str]]] = []
    start = 1
    while True:
        try:
            row = next(reader)
        except StopIteration:
            break
        except csv.Error as err:
            raise DataError(f"not valid CSV: {err}", source=source, line=reader.line_num or 1) from None
        if row and not (len(row) == 1 and not _clean(row[0])):  # a blank line, spaces and tabs only included
            rows.append((start, row))
        start = reader.line_num + 1
    if not rows or not any(_clean(c) for c in rows[0][1]):
        raise DataError("empty file (expected a header line)", source=source, line=1)
    return rows


def _check_header(path: Path | str, header: list[str], required: Iterable[str]) -> None:
    for i, name in enumerate(header):
        if "\x00" in name:
            raise DataError(f"header cell {i + 1} ({_short(name, 24)}) contains a NUL byte: a binary file, or text "
                            "saved as UTF-16? (save it as UTF-8)", source=str(path), line=1)
        if _CONTROL.search(name):
            raise DataError(f"header cell {i + 1} ({_short(name, 24)}) contains a control character", source=str(path),
                            line=1)
    seen: set[str] = set()
    for name in header:  # a duplicate first: it is often the column that seems to be missing, misnamed
        if name in seen:
            raise DataError("duplicate column", source=str(path), line=1, field=name)
        seen.add(name)
    for name in required:
        if name not in header:
            shown = ", ".join(_short(h, 24) for h in header[:6]) + (", ..." if len(header) > 6 else "")
            raise DataError(f"missing column (header has {shown})", source=str(path), line=1, field=name)


def csv_table(text: str, source: str, required: Iterable[str]) -> tuple[list[tuple[int, list[str]]], list[str]]:
    """The (line, cells) of a CSV text and its cleaned header, which must have the ``required`` columns."""
    rows = _csv_rows(text, source)
    header = [_clean(h) for h in rows[0][1]]
    _check_header(source, header, required)
    return rows, header


def _ragged(path: Path | str, lineno: int, row: list[str], header: list[str]) -> DataError:
    """A row with too few fields names the first column it lacks."""
    field = header[len(row)] if len(row) < len(header) else None
    return DataError(f"ragged row: {len(row)} fields, header has {len(header)}", source=str(path), line=lineno,
                     field=field)


def _label(value: str, source: str | None, line: int | None, field: str, what: str = "label") -> str:
    if not value:
        raise DataError(f"empty {what}", source=source, line=line, field=field)
    if _CONTROL.search(value):
        raise DataError(f"{what} {_short(value)} contains a control character", source=source, line=line, field=field)
    if _SURROGATE.search(value):
        raise DataError(f"{what} {_short(value)} contains a lone surrogate (not valid Unicode text)", source=source,
                        line=line, field=field)
    if _BIDI.search(value):
        raise DataError(f"{what} {_short(value)} contains a bidirectional formatting character (it would display "
                        "reordered)", source=source, line=line, field=field)
    if _INVISIBLE.search(value):
        raise DataError(f"{what} {_short(value)} contains an invisible character (a zero-width space, word joiner or "
                        "byte-order mark: it would look like another label)", source=source, line=line, field=field)
    return value


def activity_label(raw: str, source: str | None = None, line: int | None = None, field: str = "activity") -> str:
    """The one rule for activity labels, wherever they come from (day files, uploaded days, the
    service's observations): spaces and tabs around it dropped; non-empty; no control,
    bidirectional-formatting or lone-surrogate character; NFC-normalised, so that one word typed
    two ways (``café`` composed or decomposed) is one activity."""
    return unicodedata.normalize("NFC", _label(_clean(raw), source, line, field, "activity"))


# -- nodes.csv ------------------------------------------------------------------------------------


def _is_room(n: Node) -> bool:
    return n.category.lower() in ROOM_CATEGORIES


def _is_top(n: Node) -> bool:
    return n.start_location == n.node


def check_map(nodes: Sequence[Node], source: str | None = None, lines: Sequence[int] | None = None) -> None:
    """The rules of a map, however it arrived (``nodes.csv`` or the service): unique labels,
    known start locations, an acyclic containment graph whose chains all pass through a room,
    unique classes of movable nodes. ``lines[i]`` is node ``i``'s line for the message."""
    def where(i: int) -> dict:
        return {"source": source, "line": lines[i] if lines is not None else None}

    index: dict[str, int] = {}
    for i, n in enumerate(nodes):
        if n.node in index:
            first = lines[index[n.node]] if lines else index[n.node]
            raise DataError(f"duplicate node {n.node!r} (first at line {first})", **where(i), field="node")
        index[n.node] = i
    for i, n in enumerate(nodes):
        if n.start_location not in index:
            raise DataError(f"unknown location {_short(n.start_location)}", **where(i), field="start_location")
    classes: dict[str, int] = {}
    for i, n in enumerate(nodes):
        if n.movable:
            if n.cls in RESERVED_COLUMNS:
                raise DataError(f"a movable node may not be of class {n.cls!r} (a day file's column of its own)",
                                **where(i), field="class")
            if n.cls in classes:
                also = nodes[classes[n.cls]].node
                raise DataError(f"class {n.cls!r} of movable nodes must be unique (also {also!r})", **where(i),
                                field="class")
            classes[n.cls] = i
    # in_room[label]: the chain label -> start_location -> ... (label included) passes a room.
    in_room: dict[str, bool] = {}
    for n in nodes:
        path: list[str] = []
        on_path: set[str] = set()
        cur = n.node
        while cur not in in_room:
            node = nodes[index[cur]]
            if _is_top(node):
                if node.movable or not (_is_room(node) or node.category.lower() in HOME_CATEGORIES):
                    raise DataError(f"{cur!r} is inside itself (only the home or a room may be the top of the map)",
                                    **where(index[cur]), field="start_location")
                in_room[cur] = _is_room(node)
                break
            if cur in on_path:
                cycle = path[path.index(cur):] + [cur]
                raise DataError("containment cycle: " + " is in ".join(cycle), **where(index[cur]),
                                field="start_location")
            on_path.add(cur)
            path.append(cur)
            cur = node.start_location
        result = in_room[cur]
        for label in reversed(path):
            result = result or _is_room(nodes[index[label]])
            in_room[label] = result
    for i, n in enumerate(nodes):
        if not _is_room(n) and not _is_top(n) and not in_room[n.start_location]:
            raise DataError(f"{n.node!r} is not in a room (its start_location chain reaches the top without a node "
                            "of category Rooms)", **where(i), field="start_location")


def parse_nodes_text(text: str, source: str) -> tuple[Node, ...]:
    """The nodes of a ``nodes.csv`` text, checked by :func:`check_map`."""
    rows, header = csv_table(text, source, NODE_COLUMNS)
    col = {name: header.index(name) for name in NODE_COLUMNS}
    nodes: list[Node] = []
    lines: list[int] = []
    for lineno, row in rows[1:]:
        if len(row) != len(header):
            raise _ragged(source, lineno, row, header)
        cell = {name: _clean(row[col[name]]) for name in NODE_COLUMNS}
        if cell["movable"] not in ("0", "1"):
            raise DataError(f"{_short(cell['movable'])} is not 0 or 1", source=source, line=lineno, field="movable")
        label = _label(cell["node"], source, lineno, "node", "node label")
        cls = _label(cell["class"], source, lineno, "class", "class")
        prefix, sep, ident = label.rpartition("#")
        if not sep or not prefix or not ident:
            raise DataError(f"{_short(label)} is not of the form class#id", source=source, line=lineno, field="node")
        if prefix != cls:
            raise DataError(f"label {_short(label)} does not start with its class {_short(cls)} (labels are class#id)",
                            source=source, line=lineno, field="node")
        if _CONTROL.search(cell["category"]):
            raise DataError("category contains a control character", source=source, line=lineno, field="category")
        location = _label(cell["start_location"], source, lineno, "start_location", "location")
        nodes.append(Node(label, cls, cell["category"], cell["movable"] == "1", location))
        lines.append(lineno)
    if not nodes:
        raise DataError("no nodes after the header", source=source, line=2)
    check_map(nodes, source, lines)
    return tuple(nodes)


def read_nodes(path: Path) -> tuple[Node, ...]:
    """Read ``nodes.csv``: every node of the home and where each starts the day."""
    return parse_nodes_text(_read_text(path), str(path))


# -- day files ------------------------------------------------------------------------------------


def _parse_minute(raw: str, source: str, line: int) -> int:
    if not _MINUTE.fullmatch(raw):
        raise DataError(f"{_short(raw, 32)} is not a whole number of minutes in 0..{DAY_MINUTES} (ASCII digits only)",
                        source=source, line=line, field="minute")
    digits = raw.lstrip("0") or "0"  # leading zeros are fine, however many
    if len(digits) > len(str(DAY_MINUTES)) or int(digits) > DAY_MINUTES:
        raise DataError(f"{_short(raw, 32)} is not a whole number of minutes in 0..{DAY_MINUTES} (ASCII digits only)",
                        source=source, line=line, field="minute")
    return int(digits)


def parse_day_text(text: str, objects: tuple[str, ...], locations: frozenset[str], name: str, source: str,
                   owners: dict[str, str] | None = None, *, labelled: bool = True) -> tuple[Day, tuple[int, ...]]:
    """One day from its text, and the line of each row. ``owners`` maps each object column to its
    node label (an object cannot be inside itself or inside an object that is inside it). An
    unlabelled day (``labelled=False``: a day nobody annotated, :mod:`globe.data.sensors`) has no
    activity column; its activities are empty, so that nothing mistakes them for labels."""
    fixed = FIXED_COLUMNS if labelled else ("minute",)
    rows, header = csv_table(text, source, fixed + objects)
    optional = () if COVERING in objects or not labelled else (COVERING,)
    extra = [h for h in header if h not in fixed and h not in objects and h not in optional]
    if extra:
        why = ("an unlabelled day has no activity column (a labelled day goes in train/ or test/)"
               if not labelled and extra[0] in RESERVED_COLUMNS else "not a movable node of this home (see nodes.csv)")
        raise DataError(why, source=source, line=1, field=extra[0])
    i_min, i_act = header.index("minute"), header.index("activity") if labelled else -1
    i_cov = header.index(COVERING) if optional and COVERING in header else None
    covering: list[str] = []
    obj_idx = [header.index(o) for o in objects]
    shared = {loc: loc for loc in locations}  # one string object per label, shared by every step
    owners = owners or {}
    column_of = {label: k for k, label in enumerate(owners.get(o, "") for o in objects) if label}
    minutes: list[int] = []
    activities: list[str] = []
    states: list[tuple[str, ...]] = []
    lines: list[int] = []
    # Rows repeat their location cells until something moves: each distinct run of cells is
    # looked up once (the object columns are usually contiguous, so the key is one slice).
    first = obj_idx[0] if obj_idx else 0
    contiguous = obj_idx == list(range(first, first + len(obj_idx)))
    known: dict[tuple[str, ...], tuple[str, ...]] = {}
    for lineno, row in rows[1:]:
        if len(row) != len(header):
            raise _ragged(source, lineno, row, header)
        minute = _parse_minute(_clean(row[i_min]), source, lineno)
        if minutes and minute <= minutes[-1]:
            raise DataError(f"{minute} is not after {minutes[-1]} (minutes must increase)", source=source,
                            line=lineno, field="minute")
        activity = activity_label(row[i_act], source, lineno) if labelled else ""
        if i_cov is not None:
            covering.append(activity_label(row[i_cov], source, lineno, COVERING))
        cells = tuple(row[first: first + len(obj_idx)]) if contiguous else tuple(row[i] for i in obj_idx)
        state = known.get(cells)
        if state is None:
            found = [shared.get(cell.strip(_BLANKS)) for cell in cells]
            if None in found:
                k = found.index(None)
                raise DataError(f"unknown location {_short(_clean(cells[k]))} (not in nodes.csv)",
                                source=source, line=lineno, field=objects[k])
            state = known[cells] = tuple(loc for loc in found if loc is not None)
        if column_of and (not states or state != states[-1]) and not column_of.keys().isdisjoint(state):
            _check_nesting(state, objects, owners, column_of, source, lineno)
        minutes.append(minute)
        activities.append(activity)
        states.append(state)
        lines.append(lineno)
    if not minutes:
        raise DataError("no observation rows after the header", source=source, line=2)
    return (Day(name, tuple(minutes), tuple(activities), tuple(states), source,
                None if i_cov is None else tuple(covering)), tuple(lines))


def _check_nesting(state: Sequence[str], objects: tuple[str, ...], owners: dict[str, str], column_of: dict[str, int],
                   source: str, line: int) -> None:
    """No object inside itself, directly or through other objects, at any step; a cycle is named
    whole (``containment cycle: 'a#1' is in 'b#2' is in 'a#1'``), in the column of its first node."""
    for k in compress(range(len(state)), map(column_of.__contains__, state)):  # objects inside objects
        path = [owners[objects[k]]]
        cur = state[k]
        while cur in column_of:
            if cur in path:
                cycle = path[path.index(cur):] + [cur]
                message = (f"{cur!r} is inside itself" if len(cycle) == 2
                           else "containment cycle: " + " is in ".join(map(repr, cycle)))
                raise DataError(message, source=source, line=line, field=objects[column_of[cycle[0]]])
            path.append(cur)
            cur = state[column_of[cur]]


def read_day(path: Path, objects: tuple[str, ...], locations: frozenset[str], name: str | None = None) -> Day:
    """Read and validate one day file against the home's object columns and locations."""
    path = Path(path)
    day, _ = parse_day_text(_read_text(path), objects, locations, name or path.stem, str(path))
    return day


# -- the household's step -----------------------------------------------------------------------------


def household_step(days: Iterable[Day]) -> int | None:
    """The most common gap between consecutive rows over all days (ties: the smallest); None
    when no day has two rows."""
    gaps = Counter(chain.from_iterable(map(sub, d.minutes[1:], d.minutes) for d in days))
    if not gaps:
        return None
    top = max(gaps.values())
    return min(g for g, c in gaps.items() if c == top)


def check_step(day: Day, lines: Sequence[int], step: int, resample: Resample = "none") -> Day:
    """Every row ``step`` minutes after the previous one. Otherwise, with ``resample="locf"``,
    the day is resampled to the grid ``first minute + k * step`` (up to the last row's minute),
    each grid point taking the last observation at or before it; without it, an error."""
    if all(map(step.__eq__, map(sub, day.minutes[1:], day.minutes))):  # the usual case, at C speed
        return day
    irregular = next(t for t in range(1, len(day)) if day.minutes[t] - day.minutes[t - 1] != step)
    if resample != "locf":
        previous, minute = day.minutes[irregular - 1], day.minutes[irregular]
        raise DataError(f"{minute} is {minute - previous} minutes after {previous}; this household's step is "
                        f"{step} minutes (fix the log, or set data.resample = \"locf\" to resample to the step)",
                        source=day.source, line=lines[irregular], field="minute")
    grid = range(day.minutes[0], day.minutes[-1] + 1, step)
    rows, t = [], 0  # the row each grid point takes
    for minute in grid:
        while t + 1 < len(day) and day.minutes[t + 1] <= minute:
            t += 1
        rows.append(t)
    return Day(day.name, tuple(grid), tuple(day.activities[t] for t in rows), tuple(day.locations[t] for t in rows),
               day.source, None if day.covering is None else tuple(day.covering[t] for t in rows))


# -- a household folder ----------------------------------------------------------------------------


def _child(folder: Path, name: str, want_dir: bool) -> Path | None:
    """``folder/name`` matched case-insensitively; two matches are an error, not a choice."""
    try:
        found = [p for p in folder.iterdir() if p.name.lower() == name.lower()]
    except OSError as err:
        raise DataError(f"cannot list folder: {err.strerror or err}", source=str(folder)) from err
    if len(found) > 1:
        raise DataError(f"both {found[0].name} and {found[1].name} exist; keep one", source=str(folder))
    if not found:
        return None
    if found[0].is_dir() != want_dir:
        raise DataError("is a file, expected a folder" if want_dir else "is a folder, expected a file",
                        source=str(found[0]))
    return found[0]


def _natural(stem: str) -> tuple:
    return tuple((0, int(p), "") if p.isdigit() and p.isascii() else (1, 0, p) for p in re.split(r"(\d+)", stem))


def day_files(folder: Path) -> list[Path]:
    """The day files of ``train/`` or ``test/``: every ``*.csv`` (any case), ordered by name with
    numbers compared as numbers. Hidden files are ignored; any other entry is an error."""
    by_key: dict[str, Path] = {}
    for p in folder.iterdir():
        if p.name.startswith("."):
            continue
        if not p.name.lower().endswith(".csv") or p.name.lower() == ".csv":
            raise DataError("not a day file (day files end in .csv; remove or rename it)", source=str(p))
        if p.is_dir():
            raise DataError("is a folder, not a day file", source=str(p))
        key = p.name.lower()
        if key in by_key:
            raise DataError(f"{by_key[key].name} and {p.name} are the same day (names differ only in case)",
                            source=str(folder))
        by_key[key] = p
    return sorted(by_key.values(), key=lambda p: (_natural(p.stem.lower()), p.name))


def read_household_map(root: Path, name: str) -> tuple[Path, tuple[Node, ...]]:
    """The folder of household ``name`` and its checked ``nodes.csv`` (no day is read)."""
    folder = household_dir(Path(root), name)
    nodes_file = _child(folder, "nodes.csv", want_dir=False)
    if nodes_file is None:
        raise DataError("file not found", source=str(folder / "nodes.csv"))
    return folder, read_nodes(nodes_file)


def map_rules(nodes: Sequence[Node]) -> tuple[frozenset[str], dict[str, str]]:
    """What a home's map says of its day files' cells (:func:`parse_day_text`): every place a cell
    may name, and each object column's node label (an object is never inside itself or inside an
    object inside it)."""
    return frozenset(n.node for n in nodes), {n.cls: n.node for n in nodes if n.movable}


def load_household(root: Path, name: str, *, step_minutes: int | None = None, resample: Resample = "none") -> Household:
    """Load household ``name`` under ``root`` (see :func:`household_dir`): nodes and every
    train/test day, each checked against the household's step (``step_minutes``, else the most
    common gap between rows)."""
    folder, nodes = read_household_map(root, name)
    objects = tuple(n.cls for n in nodes if n.movable)
    locations, owners = map_rules(nodes)
    parsed: dict[Split, list[tuple[Day, tuple[int, ...]]]] = {"train": [], "test": []}
    for split in ("train", "test"):
        sub = _child(folder, split, want_dir=True)
        for f in day_files(sub) if sub is not None else []:
            parsed[split].append(parse_day_text(_read_text(f), objects, locations, f"{split}/{f.stem}", str(f), owners))
    if not parsed["train"]:
        raise DataError("no training days (expected train/*.csv)", source=str(folder))
    step = step_minutes or household_step(d for days in parsed.values() for d, _ in days)
    splits: dict[Split, tuple[Day, ...]] = {
        split: tuple(check_step(d, lines, step, resample) if step else d for d, lines in days)
        for split, days in parsed.items()
    }
    return Household(name, nodes, objects, splits["train"], splits["test"], str(folder))


def load_sensor_data(root: Path, name: str) -> SensorData | None:
    """The sensors of household ``name`` under ``root`` and each day's activations
    (``sensors.csv``, ``events/``), or None when it has none: see :mod:`globe.data.sensors`."""
    from globe.data.sensors import load_sensor_data as load  # it reads through this module

    return load(root, name)


def format_day(day: Day, objects: tuple[str, ...], *, labelled: bool = True) -> str:
    """Serialise a day exactly as the shipped files are written (LF line ends, no quoting): what
    ``csv.writer`` writes row by row. A day repeats a few rows of places many times, so each
    distinct row (and activity) is formatted once and the lines are joined from those pieces (the
    writer formats each field on its own, so the pieces join to the same text). ``labelled=False``
    leaves the activity columns out (an unlabelled day, read back with ``parse_day_text``'s)."""
    rows: dict[tuple[str, ...], str] = {}
    names: dict[tuple[str, ...], str] = {}
    covered = day.covering is not None and labelled
    fixed = FIXED_COLUMNS if labelled else ("minute",)
    parts = [_csv_line(fixed + ((COVERING,) if covered else ()) + objects) + "\n"]
    labels: Iterable[tuple[str, ...]] = (
        zip(day.activities, day.covering) if day.covering is not None and covered
        else ((a,) for a in day.activities) if labelled else (() for _ in day.minutes))
    for minute, label, state in zip(day.minutes, labels, day.locations):
        text = rows.get(state)
        if text is None:  # formatted after a first field, so a lone empty cell is written as a row's middle cell is
            text = rows[state] = _csv_line(("0", *state))[1:]
        head = names.get(label)
        if head is None:
            head = names[label] = _csv_line(("0", *label))[1:]
        parts.append(f"{minute}{head}{text}\n")
    return "".join(parts)


def _csv_line(fields: Sequence[object]) -> str:
    """One row as ``csv.writer`` writes it, without its line end."""
    out = io.StringIO()
    csv.writer(out, lineterminator="\n").writerow(fields)
    return out.getvalue()[:-1]


def _write_atomic(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(text, encoding="utf-8")
    tmp.replace(path)


def write_day(path: Path, day: Day, objects: tuple[str, ...]) -> None:
    """Write a day file atomically (a crash never leaves half a file)."""
    _write_atomic(path, format_day(day, objects))


def format_nodes(nodes: Iterable[Node]) -> str:
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(NODE_COLUMNS)
    for n in nodes:
        writer.writerow((n.node, n.cls, n.category, int(n.movable), n.start_location))
    return out.getvalue()


def write_nodes(path: Path, nodes: Iterable[Node]) -> None:
    _write_atomic(path, format_nodes(nodes))


__all__: list[str] = [
    "NODE_COLUMNS", "FIXED_COLUMNS", "RESERVED_COLUMNS", "DAY_MINUTES", "csv_table", "activity_label", "check_map",
    "parse_nodes_text", "read_nodes", "parse_day_text", "read_day", "household_step", "check_step", "day_files",
    "read_household_map", "load_household", "load_sensor_data", "format_day", "write_day", "format_nodes",
    "write_nodes",
]
