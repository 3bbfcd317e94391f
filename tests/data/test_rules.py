"""The loader's explicit rules, one at a time: step, resampling, the map, folders, file order."""

from __future__ import annotations

import pytest

from globe.data.csv_logs import check_map, check_step, day_files, household_step, load_household, parse_day_text
from globe.data.locate import household_dir, household_names
from globe.data.records import Day, Node
from globe.errors import DataError
from tests.corpus.homes import NODES, write_home


def _day(minutes, activities=None):
    acts = tuple(activities or [f"a{i}" for i in range(len(minutes))])
    return Day("train/x", tuple(minutes), acts, tuple((f"l{i}",) for i in range(len(minutes))), "x.csv")


def test_step_is_the_most_common_gap_ties_to_the_smallest():
    assert household_step([_day([0, 10, 20, 40]), _day([5, 15])]) == 10
    assert household_step([_day([0, 5, 15])]) == 5
    assert household_step([_day([7])]) is None


def test_irregular_rows_are_refused_unless_resampled():
    day = _day([360, 370, 385, 400, 410])
    with pytest.raises(DataError, match=r"x\.csv:4: column 'minute': 385 is 15 minutes after 370") as err:
        check_step(day, (2, 3, 4, 5, 6), 10)
    assert err.value.line == 4
    grid = check_step(day, (2, 3, 4, 5, 6), 10, "locf")
    assert grid.minutes == (360, 370, 380, 390, 400, 410)
    # each grid point takes the last row at or before it: 380 <- 370, 390 <- 385, 400 <- 400
    assert grid.activities == ("a0", "a1", "a1", "a2", "a3", "a4")
    assert grid.locations[3] == ("l2",)
    assert check_step(_day([0, 10, 20]), (2, 3, 4), 10, "locf") == _day([0, 10, 20])


def test_resample_via_load_household(tmp_path):
    home = write_home(tmp_path, "HouseholdT")
    text = (home / "train" / "001.csv").read_text().splitlines(keepends=True)
    (home / "train" / "001.csv").write_text("".join(text[:4] + text[6:]))  # drop 390 and 400
    with pytest.raises(DataError, match=r"001\.csv:5: column 'minute': 410 is 30 minutes after 380"):
        load_household(tmp_path, "T")
    h = load_household(tmp_path, "T", resample="locf")
    assert h.train[1].minutes == tuple(range(360, 470, 10)) and len(h.train[1]) == len(h.train[0])
    with pytest.raises(DataError, match=r"is 10 minutes after .*step is 5 minutes"):
        load_household(tmp_path, "T", step_minutes=5)


def _nodes(rows):
    return [Node(*r[:3], bool(r[3]), r[4]) for r in rows]


def test_check_map_is_reusable_without_files():
    check_map(_nodes(NODES))
    bad = _nodes(NODES[:4] + [("cup#5", "cup", "placable_objects", 1, "plate#6"),
                              ("plate#6", "plate", "placable_objects", 1, "cup#5")])
    with pytest.raises(DataError, match=r"containment cycle: cup#5 is in plate#6 is in cup#5") as err:
        check_map(bad, "nodes", [10, 11, 12, 13, 14, 15])
    assert err.value.line == 14 and err.value.field == "start_location"
    with pytest.raises(DataError, match=r"class 'cup' of movable nodes must be unique"):
        check_map(_nodes(NODES + [("cup#9", "cup", "placable_objects", 1, "table#4")]))
    with pytest.raises(DataError, match=r"may not be of class 'minute'"):
        check_map(_nodes(NODES + [("minute#9", "minute", "placable_objects", 1, "table#4")]))


def test_a_map_without_movable_nodes_is_valid():
    check_map(_nodes([n[:3] + (0,) + n[4:] for n in NODES]))


def test_day_files_are_ordered_by_number_and_matched_ignoring_case(tmp_path):
    for name in ("10.csv", "9.CSV", "2.csv", ".hidden", "100.Csv"):
        (tmp_path / name).write_text("x")
    assert [p.name for p in day_files(tmp_path)] == ["2.csv", "9.CSV", "10.csv", "100.Csv"]


def test_household_folder_is_the_name_given(tmp_path):
    write_home(tmp_path, "HouseholdA")
    write_home(tmp_path, "Kitchen")
    assert household_dir(tmp_path, "A").name == "HouseholdA"
    assert household_dir(tmp_path, "HouseholdA").name == "HouseholdA"
    assert household_dir(tmp_path, "Kitchen").name == "Kitchen"
    for bad in ("", ".", "..", "a/b", " A"):
        with pytest.raises(DataError, match="is not a folder name"):
            household_dir(tmp_path, bad)
    with pytest.raises(DataError, match=r"household 'a' not found .*available: A, Kitchen"):
        household_dir(tmp_path, "a")


def test_lines_count_quoted_newlines_and_labels_refuse_them():
    text = 'minute,activity,cup\n360,idle,"counter\n#3"\n370,idle,attic#1\n'
    with pytest.raises(DataError, match=r"d\.csv:2: column 'cup': unknown location 'counter\\n#3'"):
        parse_day_text(text, ("cup",), frozenset({"counter#3"}), "d", "d.csv")
    text = 'minute,activity,cup\n360,"idle",counter#3\n370,"two\nlines",counter#3\n380,idle,attic#1\n'
    with pytest.raises(DataError,
                       match=r"d\.csv:3: column 'activity': activity 'two\\nlines' contains a control character"):
        parse_day_text(text, ("cup",), frozenset({"counter#3"}), "d", "d.csv")


def test_shipped_map_passes_the_map_rules(households):
    for h in households.values():
        check_map(h.nodes)
        assert household_step(h.train + h.test) == 10


def test_the_households_of_a_data_folder_are_its_folders_with_a_map(tmp_path, monkeypatch):
    """HOMER+'s HouseholdA is listed as A, unless a folder A exists (then by its own name, which
    loads); folders without a nodes.csv and folders that cannot be read are passed over."""
    from pathlib import Path

    for folder in ("HouseholdA", "HouseholdB", "Mine", "B"):
        (tmp_path / folder).mkdir()
    for folder in ("HouseholdA", "HouseholdB", "Mine"):
        (tmp_path / folder / "nodes.csv").write_text("node\n")
    (tmp_path / "notes").mkdir()
    (tmp_path / "Household").mkdir()  # the prefix alone is a folder name like any other
    (tmp_path / "Household" / "nodes.csv").write_text("node\n")
    assert household_names(tmp_path) == ["Household", "A", "HouseholdB", "Mine"]
    assert all(household_dir(tmp_path, n).is_dir() for n in household_names(tmp_path))
    real = Path.iterdir

    def unreadable(self):
        if self.name == "Mine":
            raise PermissionError(13, "Permission denied", str(self))
        return real(self)

    monkeypatch.setattr(Path, "iterdir", unreadable)
    assert household_names(tmp_path) == ["Household", "A", "HouseholdB"]
