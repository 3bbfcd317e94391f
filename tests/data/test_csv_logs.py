import shutil
from pathlib import Path

import pytest

from globe.data.csv_logs import format_day, load_household, read_day
from globe.errors import DataError


def test_shipped_households_load(households):
    for name, h in households.items():
        assert len(h.train) == 65 and len(h.test) == 10, name
        assert len(h.objects) == 61
        assert all(len(d) == 109 for d in h.train + h.test)
        assert h.train[0].minutes[0] == 360 and h.train[0].minutes[-1] == 1440


def test_movement_counts_match_the_dataset_readme(households):
    # README: 4,914 changes in A, 3,979 in B and 4,014 in C across the 75 days
    expected = {"A": 4914, "B": 3979, "C": 4014}
    for name, h in households.items():
        changes = sum(a != b for d in h.train + h.test for t in range(1, len(d))
                      for a, b in zip(d.locations[t - 1], d.locations[t]))
        assert changes == expected[name]


def test_format_day_round_trips_the_shipped_file_byte_for_byte(households, homer_root):
    h = households["B"]
    path = homer_root / "HouseholdB" / "test" / "003.csv"
    assert format_day(h.test[3], h.objects) == path.read_text(encoding="utf-8")


@pytest.fixture()
def home(tmp_path, homer_root):
    """A writable copy of household A with two train days and one test day."""
    src = homer_root / "HouseholdA"
    dst = tmp_path / "HouseholdA"
    (dst / "train").mkdir(parents=True)
    (dst / "test").mkdir()
    shutil.copy(src / "nodes.csv", dst / "nodes.csv")
    for rel in ("train/000.csv", "train/001.csv", "test/000.csv"):
        shutil.copy(src / rel, dst / rel)
    return dst


def _edit(path: Path, line: int, edit) -> None:
    lines = path.read_text().splitlines(keepends=True)
    lines[line - 1] = edit(lines[line - 1])
    path.write_text("".join(lines))


def _load(home: Path):
    return load_household(home.parent, "A")


def _written_row_by_row(day, objects) -> str:
    """What format_day wrote before it joined pieces: csv.writer, one row at a time."""
    import csv
    import io

    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(("minute", "activity") + tuple(objects))
    for minute, activity, state in zip(day.minutes, day.activities, day.locations):
        writer.writerow((minute, activity, *state))
    return out.getvalue()


def test_format_day_writes_what_the_csv_writer_writes_for_any_cells(households, seed):
    import random

    from globe.data.records import Day

    h = households["B"]
    for day in h.train[:5] + h.test:
        assert format_day(day, h.objects) == _written_row_by_row(day, h.objects)
    rng = random.Random(seed)
    alphabet = ["a", "b", ",", '"', "\n", "\r", " ", "", "é", "x y"]
    for n_objects in (0, 1, 2, 5):
        objects = tuple(f"o{i}" for i in range(n_objects))
        rows = [tuple("".join(rng.choices(alphabet, k=rng.randint(0, 3))) for _ in objects) for _ in range(6)]
        acts = ["".join(rng.choices(alphabet, k=rng.randint(0, 3))) for _ in range(4)]
        n = 40
        day = Day("train/001", tuple(range(0, 10 * n, 10)), tuple(rng.choice(acts) for _ in range(n)),
                  tuple(rng.choice(rows) for _ in range(n)))
        assert format_day(day, objects) == _written_row_by_row(day, objects), (n_objects, rows, acts)


def test_missing_column_names_file_line_and_field(home):
    day = home / "train" / "001.csv"
    _edit(day, 1, lambda s: s.replace("minute,", "minutes,"))
    with pytest.raises(DataError, match=r"train/001\.csv:1: column 'minute': missing column") as err:
        _load(home)
    assert err.value.line == 1 and err.value.field == "minute"


def test_unknown_location_is_an_error(home):
    day = home / "train" / "000.csv"
    _edit(day, 7, lambda s: s.replace("dining_room#41", "attic#5", 1))
    with pytest.raises(DataError, match=r"train/000\.csv:7: column 'knifeblock': unknown location 'attic#5'"):
        _load(home)


def test_non_monotonic_minute_is_an_error(home):
    day = home / "test" / "000.csv"
    _edit(day, 4, lambda s: "370" + s[s.index(","):])  # line 4 is minute 380; line 3 is 370
    with pytest.raises(DataError, match=r"test/000\.csv:4: column 'minute': 370 is not after 370"):
        _load(home)


def test_ragged_row_is_an_error(home):
    day = home / "train" / "001.csv"
    last_column = day.read_text().splitlines()[0].split(",")[-1]
    _edit(day, 10, lambda s: s.rstrip("\n").rsplit(",", 1)[0] + "\n")
    ragged = rf"train/001\.csv:10: column '{last_column}': ragged row: 62 fields, header has 63"
    with pytest.raises(DataError, match=ragged):
        _load(home)


def test_empty_file_is_an_error(home):
    (home / "train" / "001.csv").write_text("")
    with pytest.raises(DataError, match=r"train/001\.csv:1: empty file"):
        _load(home)


def test_non_numeric_minute_is_an_error(home):
    _edit(home / "train" / "000.csv", 2, lambda s: "six" + s[s.index(","):])
    with pytest.raises(DataError, match=r"000\.csv:2: column 'minute': 'six' is not a whole number"):
        _load(home)


def test_unknown_object_column_is_an_error(home, households):
    h = households["A"]
    path = home / "train" / "000.csv"
    _edit(path, 1, lambda s: s.replace(",book,", ",novel,"))
    with pytest.raises(DataError, match=r"000\.csv:1: column 'book': missing column"):
        read_day(path, h.objects, h.locations)


def test_missing_data_folder_is_reported(tmp_path, monkeypatch):
    from globe.data.locate import resolve_data_root

    with pytest.raises(DataError, match=r"data folder not found \(from --data\)"):
        resolve_data_root(tmp_path / "nowhere")
    monkeypatch.setenv("GLOBE_DATA", str(tmp_path))
    assert resolve_data_root(None) == tmp_path


def test_a_covering_column_round_trips_and_is_checked(home, households):
    """The optional column after ``activity`` (the activity covering most of each step) is read,
    written and resampled with the day; a bad label in it names its field."""
    from dataclasses import replace

    from globe.data.csv_logs import check_step, parse_day_text

    h = households["A"]
    day = h.train[0]
    covered = replace(day, covering=day.activities[1:] + day.activities[-1:])
    text = format_day(covered, h.objects)
    assert text.splitlines()[0].startswith("minute,activity,covering,")
    back, _ = parse_day_text(text, h.objects, h.locations, day.name, day.source)
    assert back == covered and parse_day_text(format_day(day, h.objects), h.objects, h.locations, day.name,
                                              day.source)[0].covering is None
    coarse = check_step(replace(covered, minutes=covered.minutes[:3] + covered.minutes[4:5],
                                activities=covered.activities[:3] + covered.activities[4:5],
                                locations=covered.locations[:3] + covered.locations[4:5],
                                covering=covered.covering[:3] + covered.covering[4:5]), (), 10, "locf")
    assert coarse.covering == covered.covering[:3] + covered.covering[2:3] + covered.covering[4:5]
    bad = text.replace(f",{covered.covering[2]},", ",\x01,", 1)
    with pytest.raises(DataError) as err:
        parse_day_text(bad, h.objects, h.locations, day.name, "x.csv")
    assert err.value.field == "covering"


def test_places_are_named_as_a_person_would_by_their_class_and_room():
    from globe.data.records import Household, Node

    nodes = (Node("home#0", "home", "Home", False, "home#0"), Node("kitchen#1", "kitchen", "Rooms", False, "home#0"),
             Node("in_use#2", "in_use", "InUse", False, "kitchen#1"),
             Node("kitchen_counter#3", "kitchen_counter", "Furniture", False, "kitchen#1"),
             Node("coffee_maker#4", "coffee_maker", "Appliances", False, "kitchen_counter#3"),
             Node("loop#5", "loop", "Furniture", False, "loop#6"), Node("loop#6", "loop", "Furniture", False, "loop#5"))
    h = Household("H", nodes, (), (), ())
    assert h.place_name("in_use#2") == "in use, kitchen"
    assert h.place_name("kitchen_counter#3") == "kitchen counter, kitchen"
    assert h.place_name("coffee_maker#4") == "coffee maker, kitchen"  # up to the room
    assert h.place_name("kitchen#1") == "kitchen"
    assert h.place_name("loop#5") == "loop"  # a map that loops ends without a room
    assert h.place_name("gone#9") == "gone#9"
