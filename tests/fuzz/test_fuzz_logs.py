"""Property tests: damaged day logs and ``nodes.csv`` files load as exactly what they say, or stop
with a :class:`DataError` naming the file (and line) — never another exception, never a silent
repair. Bounded by ``max_examples`` so the whole run takes seconds."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from globe.data.csv_logs import load_household
from globe.data.records import Household
from globe.errors import DataError
from tests.corpus.homes import NODES, OBJECTS, nodes_text, write_home
from tests.fuzz.mutations import cells_of, damaged, harmless, text_of

# CI: 150 fixed examples per property (reproducible). GLOBE_FUZZ_EXAMPLES=5000 explores further
# with fresh random examples each run.
EXPLORE = int(os.environ.get("GLOBE_FUZZ_EXAMPLES", "0"))
FUZZ = settings(max_examples=EXPLORE or 150, deadline=None, derandomize=not EXPLORE, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
LOCATIONS = [n[0] for n in NODES]
STEP = 10  # the step of the other days of the home


@st.composite
def valid_day(draw) -> str:
    """A day by the rules: ASCII minutes every 10 within one day, labels, known locations."""
    n = draw(st.integers(1, 12))
    start = draw(st.integers(0, 1440 - STEP * (n - 1)))
    printable = st.characters(codec="utf-8", exclude_categories=("Cc", "Cs", "Zs", "Zl", "Zp"))
    label = st.text(printable, min_size=1, max_size=8)
    rows = [["minute", "activity", *OBJECTS]]
    for t in range(n):
        rows.append([str(start + STEP * t), draw(st.sampled_from(["sleeping", "idle", "breakfast"]) | label),
                     draw(st.sampled_from(["counter#3", "table#4", "kitchen#2"])),
                     draw(st.sampled_from(LOCATIONS[:4]))])
    return text_of(rows)


@pytest.fixture(scope="module")
def home(tmp_path_factory) -> Path:
    return write_home(tmp_path_factory.mktemp("fuzz"), "HouseholdT", train=2, test=1)


def _load(home: Path) -> Household | DataError:
    try:
        return load_household(home.parent, "T")
    except DataError as err:
        return err


def _check_error(err: DataError, home: Path, data: bytes) -> None:
    assert err.source is not None and str(err.source).startswith(str(home)), err
    if err.line is not None:
        assert 1 <= err.line <= data.count(b"\n") + data.count(b"\r") + 2, err
    assert "\n" not in str(err) and "\r" not in str(err), repr(str(err))


def _rows(data: bytes) -> list[list[str]]:
    return [r for r in cells_of(data.decode("utf-8-sig")) if r]


def _assert_day_says(day, data: bytes) -> None:
    """The loaded day is the file's cells, by the documented rules, read with plain tools."""
    rows = _rows(data)
    header = [c.strip(" \t") for c in rows[0]]
    assert sorted(header) == sorted(("minute", "activity", *OBJECTS))
    assert len(rows) - 1 == len(day)
    for row, minute, activity, locations in zip(rows[1:], day.minutes, day.activities, day.locations):
        assert len(row) == len(header)
        cell = {h: c.strip(" \t") for h, c in zip(header, row)}
        assert cell["minute"].isascii() and cell["minute"].isdigit() and int(cell["minute"]) == minute <= 1440
        assert cell["activity"] == activity and activity.isprintable() or activity == cell["activity"]
        assert tuple(cell[o] for o in OBJECTS) == locations and set(locations) <= set(LOCATIONS)
    assert all(b - a == STEP for a, b in zip(day.minutes, day.minutes[1:]))


def _with_file(home: Path, rel: str, data: bytes):
    path = home / rel
    before = path.read_bytes()
    path.write_bytes(data)
    try:
        return _load(home)
    finally:
        path.write_bytes(before)


@FUZZ
@given(st.data())
def test_damaged_day_loads_as_written_or_names_the_place(home, data):
    original = data.draw(valid_day())
    mutated = data.draw(damaged(original))
    result = _with_file(home, "train/001.csv", mutated)
    if isinstance(result, DataError):
        _check_error(result, home, mutated)
    else:
        _assert_day_says(result.train[1], mutated)


@FUZZ
@given(st.data())
def test_valid_day_and_harmless_changes_load_unchanged(home, data):
    original = data.draw(valid_day())
    reference = _with_file(home, "train/001.csv", original.encode("utf-8"))
    assert isinstance(reference, Household), reference
    variant = _with_file(home, "train/001.csv", data.draw(harmless(original)))
    assert isinstance(variant, Household), variant
    assert variant.train[1].minutes == reference.train[1].minutes
    assert variant.train[1].activities == reference.train[1].activities
    assert variant.train[1].locations == reference.train[1].locations


def _assert_map_rules(h: Household) -> None:
    """An independent reading of the map rules: unique labels, acyclic containment ending at a
    home or room, every non-room node inside a room."""
    by = {n.node: n for n in h.nodes}
    assert len(by) == len(h.nodes)
    rooms = {n.node for n in h.nodes if n.category.lower() in ("rooms", "room")}
    for n in h.nodes:
        seen, cur, passed_room = [n.node], n.start_location, n.node in rooms
        while by[cur].start_location != cur:
            assert cur not in seen, seen
            seen.append(cur)
            passed_room = passed_room or cur in rooms
            cur = by[cur].start_location
        top = by[cur]
        assert not top.movable and (top.category.lower() in ("home", "rooms", "room"))
        assert passed_room or cur in rooms or n.node == cur


@FUZZ
@given(st.data())
def test_damaged_nodes_file_loads_as_written_or_names_the_place(home, data):
    mutated = data.draw(damaged(nodes_text()))
    result = _with_file(home, "nodes.csv", mutated)
    if isinstance(result, DataError):
        _check_error(result, home, mutated)
        return
    rows = _rows(mutated)
    header = [c.strip(" \t") for c in rows[0]]
    cells = [{h: c.strip(" \t") for h, c in zip(header, r)} for r in rows[1:]]
    assert [(n.node, n.cls, n.category, "1" if n.movable else "0", n.start_location) for n in result.nodes] == \
        [(c["node"], c["class"], c["category"], c["movable"], c["start_location"]) for c in cells]
    assert result.objects == tuple(n.cls for n in result.nodes if n.movable)
    _assert_map_rules(result)
