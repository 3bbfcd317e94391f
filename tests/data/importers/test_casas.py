"""The CASAS importer on small logs written here: a round trip computed by hand, and one test per
kind of bad line naming its file, line and field."""

import json
import re

import pytest

from globe.data.csv_logs import load_household
from globe.data.importers import GridOptions, import_casas
from globe.errors import ConfigError, DataError

# Four dates. 11-04 and 11-06 are kept; 11-05 has no annotation; 11-07 is partial (the log ends at
# 00:30, before its last row at 24:00). 11-04 is covered from 05:50, before its first row at 06:00.
LOG = """\
2010-11-04 05:50:00.000000 M001 ON Sleeping begin
2010-11-04 06:25:00.000000 M001 OFF Sleeping end
2010-11-04 07:02:00.000000 I001 ABSENT Meal_Preparation begin
2010-11-04 07:05:30.000000 I001 PRESENT
2010-11-04 07:19:59.999999 I002 ABSENT
2010-11-04 07:31:00\tI002\tPRESENT\tMeal_Preparation\tend
2010-11-04 12:00:00.000000 T001 21.5
2010-11-04 23:58:00.000000 D001 OPEN
2010-11-05 00:05:00.000000 I001 ABSENT
2010-11-05 00:06:00.000000 I001 PRESENT
2010-11-05 03:00:00.000000 M002 ON
2010-11-06 08:00:00.000000 I002 ABSENT Relax begin
2010-11-06 08:00:00.000000 I002 PRESENT
2010-11-06 09:00:00.000000 M001 ON Relax end
2010-11-07 00:30:00.000000 M001 OFF
"""


def _write(tmp_path, text, name="data.txt"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def _import(tmp_path, text=LOG, **kwargs):
    dest = tmp_path / "home"
    result = import_casas(log_file=_write(tmp_path, text), dest=dest, **kwargs)
    return result, load_household(tmp_path, "home")


def _rows(day, minutes_of):
    return {m: a for m, a in zip(day.minutes, day.activities) if m in minutes_of}


def test_round_trip_at_ten_minutes_matches_the_grid_computed_by_hand(tmp_path):
    result, home = _import(tmp_path)
    assert home.objects == ("i001", "i002")  # item sensors only; M, T and D sensors stay out
    assert [d.name for d in home.train] == ["train/2010-11-04"] and [d.name for d in home.test] == ["test/2010-11-06"]
    day = home.train[0]
    assert day.minutes == tuple(range(360, 1441, 10))  # 06:00 .. 24:00, 109 rows as HOMER+
    # Sleeping [05:50, 06:25) covers the starts 06:00, 06:10, 06:20; Meal_Preparation [07:02, 07:31)
    # covers 07:10, 07:20, 07:30 (not 07:00: the step's start is before the annotation).
    expected = {m: "idle" for m in day.minutes} | {360: "Sleeping", 370: "Sleeping", 380: "Sleeping",
                                                  430: "Meal_Preparation", 440: "Meal_Preparation",
                                                  450: "Meal_Preparation"}
    assert dict(zip(day.minutes, day.activities)) == expected
    nodes = {n.cls: n for n in home.nodes if n.movable}
    in_use = {n.node for n in home.nodes if n.cls == "in_use"}
    assert len(in_use) == 1 and nodes["i001"].start_location == "room#1"
    used = {obj: [m for m, row in zip(day.minutes, day.locations) if row[k] in in_use]
            for k, obj in enumerate(home.objects)}
    # i001: taken 07:02-07:05:30 (step 07:00) and 00:05-00:06 (the 24:00 row's step [00:00, 00:10)).
    # i002: taken from 07:19:59.999999 (step 07:10) to 07:31 (step 07:30).
    assert used == {"i001": [420, 1440], "i002": [430, 440, 450]}
    test_day = home.test[0]
    assert [m for m, a in zip(test_day.minutes, test_day.activities) if a == "Relax"] == [480, 490, 500, 510, 520, 530]
    # a firing at 08:00 sharp (ABSENT and PRESENT at once) is a use in the step that starts then
    assert [m for m, row in zip(test_day.minutes, test_day.locations) if row[1] in in_use] == [480]
    assert result.train_days == 1 and result.test_days == 1 and result.dropped_days == 2


def test_round_trip_at_five_minutes(tmp_path):
    _, home = _import(tmp_path, options=GridOptions(step_minutes=5))
    day = home.train[0]
    assert day.minutes == tuple(range(360, 1441, 5))
    sleeping = [m for m, a in zip(day.minutes, day.activities) if a == "Sleeping"]
    meal = [m for m, a in zip(day.minutes, day.activities) if a == "Meal_Preparation"]
    assert sleeping == [360, 365, 370, 375, 380]  # 06:25 is the end, not covered
    assert meal == [425, 430, 435, 440, 445, 450]  # 07:05 .. 07:30
    in_use = {n.node for n in home.nodes if n.cls == "in_use"}
    used = {obj: [m for m, row in zip(day.minutes, day.locations) if row[k] in in_use]
            for k, obj in enumerate(home.objects)}
    # i001: 07:02 (step 07:00) to 07:05:30 (step 07:05); 00:05 is the end of the 24:00 row's step
    # [00:00, 00:05), so that use is on no row. i002: 07:19:59.999999 (step 07:15) to 07:31 (07:30).
    assert used == {"i001": [420, 425], "i002": [435, 440, 445, 450]}


def test_report_says_what_became_of_every_sensor_annotation_and_day(tmp_path):
    _import(tmp_path)
    report = json.loads((tmp_path / "home" / "import.json").read_text(encoding="utf-8"))
    assert [o["object"] for o in report["objects"]] == ["i001", "i002"]
    assert report["objects"][0]["sensors"] == ["I001"] and report["objects"][0]["events"] == 4
    assert report["objects"][0]["rows_in_use"] == 2  # 07:00 and 24:00 on the kept days
    left = {s["sensor"]: s["why"] for s in report["sensors_left_out"]}
    assert set(left) == {"M001", "M002", "T001", "D001"}
    assert "motion" in left["M001"] and "door" in left["D001"] and "temperature" in left["T001"]
    dropped = {d["date"]: d["why"] for d in report["dropped_days"]}
    assert dropped["2010-11-05"] == "no annotation"
    assert dropped["2010-11-07"].startswith("partial: the log ends at 2010-11-07 00:30:00")
    assert report["days"] == {"train": ["2010-11-04"], "test": ["2010-11-06"]}
    meal = next(a for a in report["activities"] if a["activity"] == "Meal_Preparation")
    assert meal["rows"] == 3 and meal["annotations"] == 1
    assert report["grid"]["step_minutes"] == 10 and report["grid"]["day_start"] == "06:00"


def test_a_mapping_chooses_the_objects_and_their_rooms(tmp_path):
    mapping = _write(tmp_path, "sensor,object,room\nD001,front_door,hall\nI002,pot,kitchen\n", "map.csv")
    # the door's one activation, open for two days, would be cut as left on (over a day): no limit here
    _, home = _import(tmp_path, objects=mapping, options=GridOptions(max_use_minutes=10_000))
    assert home.objects == ("front_door", "pot")  # the mapping's order; I001 is not mapped, so left out
    place = {n.cls: n.start_location for n in home.nodes if n.movable}
    assert place == {"front_door": "hall#1", "pot": "kitchen#3"}
    day = home.train[0]
    # OPEN at 23:58 and never CLOSE: on until the log ends (11-07 00:30), so in use from the 23:50
    # row of 11-04 through its 24:00 row ([00:00, 00:10) of 11-05), and all day on 11-06
    assert [m for m, row in zip(day.minutes, day.locations) if row[0] == "in_use#2"] == [1430, 1440]
    assert {row[0] for row in home.test[0].locations} == {"in_use#2"}


def test_a_sensor_left_on_counts_until_the_log_ends_and_is_noted(tmp_path):
    text = LOG.replace("2010-11-06 08:00:00.000000 I002 PRESENT\n", "")
    result, home = _import(tmp_path, text=text)
    test_day = home.test[0]
    in_use = [m for m, row in zip(test_day.minutes, test_day.locations) if row[1].startswith("in_use#")]
    assert in_use == list(range(480, 1441, 10))  # from 08:00 through the 24:00 row (the log ends 00:30)
    assert any("I002 is still on at the end of the log" in note for note in result.notes)


def _error(tmp_path, text, **kwargs):
    with pytest.raises(DataError) as info:
        log_file = _write(tmp_path, text) if isinstance(text, str) else text
        import_casas(log_file=log_file, dest=tmp_path / "out", **kwargs)
    assert not (tmp_path / "out").exists()  # nothing is written when a line is bad
    return info.value


GOOD = "2010-11-04 05:00:00.000000 M001 ON Sleeping begin\n"


@pytest.mark.parametrize("line, field, message", [
    ("2010-13-04 06:00:00 M001 ON", "date", "not a valid date"),
    ("2010-11-4 06:00:00 M001 ON", "date", "is not a date"),
    ("2010-11-04 6:00:00 M001 ON", "time", "not a time of day"),
    ("2010-11-04 06:00 M001 ON", "time", "not a time of day"),
    ("2010-11-04 06:00:00 M001", "value", "missing field"),
    ("2010-11-04 06:00:00 M001 ONM026", "value", "is not ON, OFF"),
    ("2010-11-04 06:00:00 M001 ON Sleeping", "begin/end", "must be followed by 'begin' or 'end'"),
    ("2010-11-04 06:00:00 M001 ON Sleeping stop", "begin/end", "is not 'begin' or 'end'"),
    ("2010-11-04 06:00:00 M001 ON Sleeping end extra", "begin/end", "7 fields"),
    ("2010-11-04 06:00:00 M0/1 ON", "sensor", "is not a sensor id"),
    ("2010-11-04 04:59:59.999999 M001 OFF", "time", "events must be in time order"),
    ("2010-11-04 06:00:00 M001 OFF Relax end", "activity", "'Relax' ends but never began"),
    ("2010-11-04 06:00:00 M001 OFF Sleeping begin", "activity", "begins again before it ended"),
    ("2010-11-04 06:00:00 M001 OFF Relax begin\n2010-11-04 07:00:00 M001 OFF Relax end", "activity",
     "'Relax' begins at 2010-11-04 06:00:00 while 'Sleeping' (line 1)"),
    ("2010-11-04 06:00:00 I001 12.5", "value", "is a reading, not a use"),
])
def test_a_bad_line_names_file_line_and_field(tmp_path, line, field, message):
    err = _error(tmp_path, GOOD + line + "\n2010-11-06 00:00:00 M001 OFF Sleeping end\n")
    assert (err.source, err.line, err.field) == (str(tmp_path / "data.txt"), 2, field)
    assert message in err.message
    assert re.match(rf"{re.escape(str(tmp_path / 'data.txt'))}:2: column '{re.escape(field)}': ", str(err))


def test_an_activity_left_open_names_the_line_that_began_it(tmp_path):
    err = _error(tmp_path, "2010-11-04 05:00:00 M001 ON\n" + GOOD.replace("05:00:00.000000", "05:01:00"))
    assert (err.line, err.field) == (2, "activity") and "never ends" in err.message
    assert "--skip-bad-lines leaves it out" in err.message  # the way out for a log cut off mid-activity


def test_binary_garbage_empty_files_and_other_encodings_are_refused(tmp_path):
    garbage = tmp_path / "garbage.txt"
    garbage.write_bytes(GOOD.encode() + b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR")
    err = _error(tmp_path, garbage)
    assert err.line == 4 and "binary data" in err.message  # the PNG signature holds two line ends before its NUL
    latin = tmp_path / "latin.txt"
    latin.write_bytes(GOOD.encode() + "2010-11-04 06:00:00 M001 ON Caf\u00e9 begin\n".encode("latin-1"))
    err = _error(tmp_path, latin)
    assert err.line == 2 and "not UTF-8" in err.message
    err = _error(tmp_path, "\n  \n")
    assert err.line == 1 and "empty file" in err.message


def test_overlapping_annotations_can_let_the_later_one_win(tmp_path):
    # Sleeping [05:50, 06:55) holds a Toilet visit [06:12, 06:31): the visit covers 06:20 and 06:30.
    text = ("2010-11-04 05:50:00 M001 ON Sleeping begin\n"
            "2010-11-04 06:12:00 M002 ON Toilet begin\n"
            "2010-11-04 06:31:00 M002 OFF Toilet end\n"
            "2010-11-04 06:55:00 M001 OFF Sleeping end\n"
            "2010-11-05 00:00:00 M001 ON\n")
    err = _error(tmp_path, text)
    assert (err.line, err.field) == (2, "activity") and "may not overlap" in err.message
    _, home = _import(tmp_path, text=text, options=GridOptions(overlaps="latest"))
    day = home.train[0]
    assert day.activities[:7] == ("Sleeping", "Sleeping", "Toilet", "Toilet", "Sleeping", "Sleeping", "idle")


def test_a_mapped_sensor_missing_from_the_log_is_an_error_in_the_mapping(tmp_path):
    mapping = _write(tmp_path, "sensor,object\nI001,pot\nI01,kettle\n", "map.csv")
    err = _error(tmp_path, LOG, objects=mapping)
    assert (err.source, err.line, err.field) == (str(mapping), 3, "sensor") and "'I01' is not in the log" in err.message


def test_a_log_with_no_complete_annotated_day_is_refused(tmp_path):
    err = _error(tmp_path, "2010-11-04 05:00:00 M001 ON\n2010-11-05 01:00:00 M001 OFF\n")
    assert "no day to import" in err.message and "1 no annotation" in err.message


def test_skip_bad_lines_leaves_out_exactly_the_bad_lines_and_lists_them(tmp_path):
    """Corrupt lines of every kind, spread through the log: with --skip-bad-lines the household is
    the one the log without them gives, each left-out line is named in the report, and an
    activity that never ends is left out too; without it the first bad line stops the import."""
    bad = ["2010-11-04 06:30:00 M001 OFcF", "2010-11-04 06:31:00 M001", "2010-11-04 06:32:00 M0/1 ON",
           "2010-11-04 06:00:00 M001 OFF", "2010-11-04 06:33:00 M001 OFF Relax end",
           "2010-11-04 06:34:00 M001 OFF Sleeping stop", "2010-11-04 07:10:00 I001 12.5",
           "2010-11-04 07:20:00 M004 ON Meal_Preparation begin"]  # a duplicated begin, nothing between
    lines = LOG.splitlines()
    dirty = [*lines[:2], *bad[:6], *lines[2:5], *bad[6:], *lines[5:-1], lines[-1] + " Relax begin"]  # never ends
    expected_dir, dirty_dir = tmp_path / "clean", tmp_path / "dirty"
    expected_dir.mkdir(), dirty_dir.mkdir()
    _, want = _import(expected_dir)
    result, got = _import(dirty_dir, "\n".join(dirty) + "\n", skip_bad_lines=True)
    def content(days):
        return [(d.name, d.minutes, d.activities, d.locations) for d in days]

    assert content(got.train) == content(want.train) and content(got.test) == content(want.test)
    assert got.objects == want.objects
    sensors = [{k: json.loads((d / "home" / "import.json").read_text())[k] for k in ("objects", "sensors_left_out")}
               for d in (expected_dir, dirty_dir)]
    assert sensors[0] == sensors[1]
    listed = json.loads(result.report.read_text())["bad_lines"]
    assert result.bad_lines == len(bad) + 1 and result.first_bad_line.startswith(f"{tmp_path / 'dirty'}")
    assert [r["line"] for r in listed] == [3, 4, 5, 6, 7, 8, 12, 13, len(dirty)]
    assert all(r["source"].endswith("data.txt") and r["field"] and r["why"] for r in listed)
    with pytest.raises(DataError) as err:
        _import(tmp_path, "\n".join(dirty) + "\n")
    assert err.value.line == 3 and "--skip-bad-lines" in err.value.message


def test_each_row_also_names_the_activity_covering_most_of_its_step(tmp_path):
    """07:00 is idle at its start but the meal (from 07:02) covers 8 of its 10 minutes; 06:20 is
    half sleep, half nothing: a tie goes to the row's own activity; 07:30 holds one minute of the
    meal: idle."""
    _, home = _import(tmp_path)
    day = home.train[0]
    rows = dict(zip(day.minutes, zip(day.activities, day.covering or ())))
    assert rows[420] == ("idle", "Meal_Preparation") and rows[380] == ("Sleeping", "Sleeping")
    assert rows[450] == ("Meal_Preparation", "idle") and rows[390] == ("idle", "idle")
    assert all(c == a for m, (a, c) in rows.items() if m not in (420, 450))


def test_a_begin_whose_end_was_lost_is_left_out_with_skip_bad_lines(tmp_path):
    """The first night's 'Sleeping end' is lost: the next 'Sleeping begin' shows it. Pairing the first
    begin with the next night's end would make one annotation of a day and a half; the first begin is
    left out instead, and named in the report."""
    text = ("2010-11-04 05:50:00 M001 ON Sleeping begin\n"
            "2010-11-04 07:00:00 M002 ON Cook begin\n"
            "2010-11-04 07:30:00 M002 OFF Cook end\n"
            "2010-11-04 22:00:00 M001 ON Sleeping begin\n"
            "2010-11-05 06:25:00 M001 OFF Sleeping end\n"
            "2010-11-05 07:00:00 M002 ON Cook begin\n"
            "2010-11-05 07:30:00 M002 OFF Cook end\n"
            "2010-11-06 00:30:00 M001 OFF\n")
    err = _error(tmp_path, text)
    assert (err.line, err.field) == (4, "activity") and "--skip-bad-lines" in err.message
    result, home = _import(tmp_path, text, skip_bad_lines=True)
    first, second = home.train[0], home.test[0]
    assert _rows(first, {360, 420, 1440}) == {360: "idle", 420: "Cook", 1440: "Sleeping"}
    assert second.activities[0] == "Sleeping"  # 06:00 of the second day: the night that did end
    [lost] = json.loads(result.report.read_text())["bad_lines"]
    assert lost["line"] == 1 and "end was lost" in lost["why"] and result.bad_lines == 1


# US daylight saving time ended on 2010-11-07 at 02:00: 01:00-02:00 was logged twice.
FALL_BACK = """\
2010-11-06 05:50:00 M001 ON Sleeping begin
2010-11-06 06:25:00 M001 OFF Sleeping end
2010-11-06 07:00:00 M002 ON Cook begin
2010-11-06 07:30:00 M002 OFF Cook end
2010-11-07 01:50:00 M003 ON Toilet begin
2010-11-07 01:05:00 M003 OFF Toilet end
2010-11-07 01:40:00 M003 ON
2010-11-07 07:00:00 M002 ON Cook begin
2010-11-07 07:30:00 M002 OFF Cook end
2010-11-08 00:30:00 M001 OFF
"""


def test_the_hour_logged_twice_when_clocks_go_back_is_read_in_order_given_the_time_zone(tmp_path):
    err = _error(tmp_path, FALL_BACK)
    assert (err.line, err.field) == (6, "time") and "--timezone" in err.message
    err = _error(tmp_path, FALL_BACK, timezone="Europe/Amsterdam")  # clocks went back a week earlier there
    assert (err.line, err.field) == (6, "time")
    result, home = _import(tmp_path, FALL_BACK, timezone="America/Los_Angeles")
    assert [d.name.split("/")[1] for d in home.train + home.test] == ["2010-11-06", "2010-11-07"]
    assert any("2 events logged in the hour repeated" in n for n in result.notes)
    report = json.loads(result.report.read_text(encoding="utf-8"))
    assert report["settings"]["timezone"] == "America/Los_Angeles"
    (tmp_path / "x").mkdir()
    for name in ("Mars/Olympus", "America", "x" * 300):  # no zone; a folder of the zone data; no file name
        with pytest.raises(ConfigError, match="unknown time zone"):
            _import(tmp_path / "x", FALL_BACK, timezone=name)


def test_an_activity_spelled_decomposed_and_composed_is_one_activity(tmp_path):
    nfd, nfc = "De\u0301tente", "D\u00e9tente"
    text = (f"2010-11-04 05:50:00 M001 ON {nfd} begin\n2010-11-04 07:00:00 M001 OFF {nfc} end\n"
            "2010-11-05 00:30:00 M001 OFF\n")
    _, home = _import(tmp_path, text)
    assert home.train[0].activities[0] == nfc


def test_an_item_taken_again_before_it_was_put_back_counts_the_first_taking_as_one_firing(tmp_path):
    """I001's PRESENT after breakfast is lost; it is taken again in the evening. The pot is used at
    07:10, not all day, and at 18:00 until it is put back."""
    text = ("2010-11-04 05:50:00 M001 ON Sleeping begin\n2010-11-04 06:25:00 M001 OFF Sleeping end\n"
            "2010-11-04 07:10:00 I001 ABSENT\n2010-11-04 18:00:00 I001 ABSENT\n2010-11-04 18:25:00 I001 PRESENT\n"
            "2010-11-05 00:30:00 M001 OFF\n")
    result, home = _import(tmp_path, text)
    day = home.train[0]
    used = [m for m, row in zip(day.minutes, day.locations) if row[0].startswith("in_use")]
    assert used == [430, 1080, 1090, 1100]  # 07:10; 18:00-18:25
    assert any("went on while on" in n and "I001 1x" in n for n in result.notes)


def test_one_resident_of_a_multi_resident_log(tmp_path):
    """R1 and R2 overlap all morning; --resident R1 takes R1's annotations without the prefix, and
    the ones named for no one."""
    text = ("2010-11-04 05:50:00 M001 ON R1_Sleep begin\n2010-11-04 05:55:00 M009 ON R2_Sleep begin\n"
            "2010-11-04 06:25:00 M001 OFF R1_Sleep end\n2010-11-04 06:40:00 M002 ON r1_Meal begin\n"
            "2010-11-04 07:10:00 M002 OFF R1_Meal end\n2010-11-04 07:30:00 M009 OFF R2_Sleep end\n"
            "2010-11-04 08:00:00 D001 OPEN Leave_Home begin\n2010-11-04 08:01:00 D001 CLOSE Leave_Home end\n"
            "2010-11-05 00:30:00 M001 OFF\n")
    assert _error(tmp_path, text).field == "activity"  # R2_Sleep overlaps R1's annotations
    both = text.replace("r1_Meal", "R1_Meal")
    (tmp_path / "both").mkdir()
    overlap = _error(tmp_path / "both", both)  # ... and the error says how to take one person's
    assert "may not overlap" in overlap.message and "a log of 2 residents: --resident R1 (CASAS)" in overlap.message
    result, home = _import(tmp_path, text, resident="R1")
    assert _rows(home.train[0], {360, 400, 480, 490}) == {360: "Sleep", 400: "Meal", 480: "Leave_Home", 490: "idle"}
    assert any("other residents left out (--resident R1): R2 1" in n for n in result.notes)
    (tmp_path / "x").mkdir()
    with pytest.raises(ConfigError, match="--resident"):
        _import(tmp_path / "x", text, resident="Alice")
    err = _error(tmp_path / "x", text, resident="R3")
    assert "no annotation is named for resident R3" in err.message and "R1, R2" in err.message


def _month(last_end: str | None = None, first: str | None = None) -> str:
    """Ten days of a kitchen item sensor every hour and Work 09:01-17:01, as CASAS lines; the last
    ``Work end`` replaced by ``last_end`` and a line ``first`` put before the others."""
    import datetime as dt

    lines = []
    for d in range(10):
        day = dt.datetime(2010, 11, 4) + dt.timedelta(days=d)
        for h in range(6, 23):
            t = day + dt.timedelta(hours=h)
            back = t + dt.timedelta(minutes=4)
            lines += [f"{t:%Y-%m-%d %H:%M:%S}.000000 I001 ABSENT", f"{back:%Y-%m-%d %H:%M:%S}.000000 I001 PRESENT"]
        lines += [f"{day:%Y-%m-%d} 09:01:00.000000 M002 ON Work begin",
                  f"{day:%Y-%m-%d} 17:01:00.000000 M002 OFF Work end"]
    lines.sort()
    if last_end is not None:
        lines.remove("2010-11-13 17:01:00.000000 M002 OFF Work end")
        lines.append(f"{last_end} M002 OFF Work end")
    return "\n".join(([first] if first else []) + lines) + "\n"


@pytest.mark.parametrize("text, line, when", [
    (_month(first="0001-01-01 00:00:00.000000 M003 ON"), 1, "0001-01-01 00:00:00"),
    (_month(last_end="9999-12-31 10:00:00.000000"), 360, "9999-12-31 10:00:00"),
    (_month(last_end="2012-11-13 17:01:00.000000"), 360, "2012-11-13 17:01:00"),
])
def test_a_timestamp_far_outside_the_log_is_refused_or_left_out(tmp_path, text, line, when):
    """A year 0001 first line once wrote a 51 MB report, an end dated 9999 hung (every date of
    the span listed), an end dated two years late wrote two years of one 'Work': judged against
    the log's own records, each is refused naming its line, or left out with --skip-bad-lines
    (with the annotation reaching it) and listed in the report."""
    with pytest.raises(DataError) as err:
        _import(tmp_path, text)
    assert (err.value.line, err.value.field) == (line, "time") and when in err.value.message
    assert "far outside the log" in err.value.message and "--skip-bad-lines" in err.value.message
    assert not (tmp_path / "home").exists()
    result, home = _import(tmp_path, text, skip_bad_lines=True)
    report = json.loads(result.report.read_text())
    assert [r["line"] for r in report["far_outside"]] == [line] and report["log_span"][1] < "2010-11-14"
    assert len(home.train) + len(home.test) <= 10 and result.report.stat().st_size < 100_000
    assert all(day.activities.count("Work") <= 48 for day in home.train + home.test)


def test_old_mac_line_endings_read_as_lines(tmp_path):
    """A log whose lines end with a carriage return only was one line ("line 1: 88 fields")."""
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    _, crlf = _import(tmp_path / "a", LOG.replace("\n", "\r\n"))
    _, cr = _import(tmp_path / "b", LOG.replace("\n", "\r"))
    assert [d.activities for d in cr.train] == [d.activities for d in crlf.train]
    assert [d.locations for d in cr.train] == [d.locations for d in crlf.train]


@pytest.mark.parametrize("kind", ["fifo", "device"])
def test_something_that_is_no_file_is_refused_at_once(tmp_path, kind):
    """A named pipe blocked the import for ever, /dev/zero read until memory ran out."""
    import os

    if kind == "fifo":
        source = tmp_path / "pipe"
        os.mkfifo(source)
    else:
        source = __import__("pathlib").Path("/dev/zero")
    with pytest.raises(DataError, match="is not a regular file"):
        import_casas(log_file=source, dest=tmp_path / "home")
    assert not (tmp_path / "home").exists()


def _events(folder, stem):
    """An events file's rows as (sensor, start, end) with the times as numbers."""
    lines = (folder / "events" / f"{stem}.csv").read_text(encoding="utf-8").splitlines()
    assert lines[0] == "sensor,start,end"
    return [(s, float(a), float(b)) for s, a, b in (line.split(",") for line in lines[1:])]


def test_every_sensor_is_kept_with_its_type_and_activations_in_seconds(tmp_path):
    result, home = _import(tmp_path)
    folder = tmp_path / "home"
    assert (folder / "sensors.csv").read_text(encoding="utf-8").splitlines() == [
        "sensor,type,room,object", "M001,motion,,", "I001,contact,,i001", "I002,contact,,i002", "T001,temperature,,",
        "D001,door,,", "M002,motion,,"]
    # 11-04's rows cover 06:00 (21600 s) to the 24:00 row's end (00:10 next day, 87000 s). M001 ON
    # 05:50 .. OFF 06:25 is cut to the span; I002's ON at 07:19:59.999999 is written to the ms; the
    # door D001 opens at 23:58 and never closes: on for two days, longer than a day (its limit with
    # one activation), so cut to a firing, as an object's sensor left on; I001 at 00:05 next day.
    assert _events(folder, "2010-11-04") == [
        ("M001", 21600, 23100), ("I001", 25320, 25530), ("I002", 26400, 27060), ("D001", 86280, 86280),
        ("I001", 86700, 86760)]
    # 11-06: I002 fires at 08:00; M001 on from 09:00 to 00:30 next day, cut to the span's end
    assert _events(folder, "2010-11-06") == [("I002", 28800, 28800), ("M001", 32400, 87000)]
    assert sorted(p.name for p in (folder / "events").iterdir()) == ["2010-11-04.csv", "2010-11-06.csv"]  # kept days
    report = json.loads((folder / "import.json").read_text(encoding="utf-8"))["sensors"]
    assert report["count"] == 6 and report["types"] == {"contact": 2, "door": 1, "motion": 2, "temperature": 1}
    assert report["activations"] == 7 and report["days"] == 2
    assert [(r["sensor"], r["start"], r["limit_minutes"]) for r in report["left_on"]] == [
        ("D001", "2010-11-04 23:58:00", 1440.0), ("M002", "2010-11-05 03:00:00", 1440.0)]
    assert any("sensors of no object still on at the end of the log" in n and "M002" in n for n in result.notes)


def test_a_sensors_room_comes_from_the_mapping(tmp_path):
    mapping = tmp_path / "objects.csv"
    mapping.write_text("sensor,object,room\nI001,pot,kitchen\nD001,front_door,hall\n", encoding="utf-8")
    _import(tmp_path, objects=mapping)
    rows = (tmp_path / "home" / "sensors.csv").read_text(encoding="utf-8").splitlines()
    assert rows[1:4] == ["M001,motion,,", "I001,contact,kitchen,pot", "I002,contact,,"]
    assert "D001,door,hall,front_door" in rows


@pytest.mark.parametrize(("key", "kind"), [("M012", "motion"), ("MA003", "motion"), ("D001", "door"),
                                           ("I006", "contact"), ("T102", "temperature"), ("LS005", "light"),
                                           ("AD1-A", "appliance"), ("P001", "power"), ("E002", "other"),
                                           ("123", "other")])
def test_a_casas_sensors_type_comes_from_its_letters(key, kind):
    from globe.data.importers.casas import sensor_type

    assert sensor_type(key) == kind


def test_a_sensor_that_goes_on_while_on_counts_the_earlier_on_as_a_firing(tmp_path):
    log = LOG.replace("2010-11-04 12:00:00.000000 T001 21.5\n",
                      "2010-11-04 12:00:00.000000 M003 ON\n2010-11-04 12:01:00.000000 M003 ON\n"
                      "2010-11-04 12:02:00.000000 M003 OFF\n")
    result, _ = _import(tmp_path, log)
    assert [e for e in _events(tmp_path / "home", "2010-11-04") if e[0] == "M003"] == [
        ("M003", 43200, 43200), ("M003", 43260, 43320)]
    assert any("a sensor of no object went on while on" in n and "M003 1x" in n for n in result.notes)


def test_one_timestamp_corrupted_to_a_later_date_costs_its_own_line_only(tmp_path):
    """A line dated a year late in the middle of a log: with --skip-bad-lines every later line was
    left out as 'before the previous event' (the corrupt line kept, 11 of 12 days lost); now that
    line alone is left out, named, and the household is the one the log without it gives."""
    lines = _month(None).splitlines()
    at = next(i for i in range(len(lines) // 3, len(lines)) if lines[i].endswith("ABSENT"))
    moved = lines[at].replace("2010-11-", "2011-11-", 1)
    dirty = lines[:at] + [moved] + lines[at + 1:]
    clean_dir, dirty_dir = tmp_path / "clean", tmp_path / "dirty"
    clean_dir.mkdir(), dirty_dir.mkdir()
    _, want = _import(clean_dir, "\n".join(lines[:at] + lines[at + 1:]) + "\n")
    result, got = _import(dirty_dir, "\n".join(dirty) + "\n", skip_bad_lines=True)
    assert [d.name for d in got.train + got.test] == [d.name for d in want.train + want.test]
    assert [d.locations for d in got.train + got.test] == [d.locations for d in want.train + want.test]
    [bad] = json.loads(result.report.read_text())["bad_lines"]
    assert (bad["line"], bad["field"]) == (at + 1, "time") and "out of time order" in bad["why"]
    # a line dated early is left out alone, as before
    early = lines[:at] + [lines[at].replace("2010-11-", "2009-11-", 1)] + lines[at + 1:]
    (tmp_path / "early").mkdir()
    result, _ = _import(tmp_path / "early", "\n".join(early) + "\n", skip_bad_lines=True)
    assert [r["line"] for r in json.loads(result.report.read_text())["bad_lines"]] == [at + 1]


def test_out_of_order_keeps_the_longest_run_in_time_order_and_the_earlier_of_two():
    from datetime import datetime

    from globe.data.importers.text import out_of_order

    def at(hours):
        return [datetime(2010, 11, 4, h) if h is not None else None for h in hours]

    assert out_of_order(at([1, 2, 20, 3, 4])) == [2]  # one far ahead
    assert out_of_order(at([9, 1, 2, 3])) == [0]  # the first line far ahead
    assert out_of_order(at([1, 3, 2, 4])) == [2]  # two swapped: the later line is the odd one
    assert out_of_order(at([1, None, 0, 5, 5])) == [2] and out_of_order([]) == []


def test_an_activity_of_several_words_as_cairo_writes_them(tmp_path):
    """Cairo names activities in words ('Bed to toilet begin', 'R1 sleep end'): every such line was
    '7 fields' or '8 fields' and stopped the import. The words make one activity; 'R1 sleep' is
    R1's, as 'R1_sleep' is."""
    text = GOOD.replace("Sleeping begin", "Night wandering begin") + (
        "2010-11-04 06:20:00.000000 M002 OFF Night  wandering\tend\n"
        "2010-11-04 07:00:00.000000 M003 ON R1 work in office begin\n"
        "2010-11-04 07:30:00.000000 M003 OFF R2 take medicine begin\n"
        "2010-11-04 07:40:00.000000 M003 ON R2 take medicine end\n"
        "2010-11-04 09:00:00.000000 M004 OFF R1 work in office end\n"
        "2010-11-05 00:00:00.000000 M004 ON\n")
    result, home = _import(tmp_path, text, resident="R1")
    assert result.activities == ("Night wandering", "idle", "work in office")
    assert _rows(home.train[0], {360, 420, 480, 540}) == {360: "Night wandering", 420: "work in office",
                                                          480: "work in office", 540: "idle"}
    assert any("other residents left out (--resident R1): R2 1" in n for n in result.notes)
    (tmp_path / "x").mkdir()
    err = _error(tmp_path / "x", GOOD + "2010-11-04 06:00:00 M001 ON Night wandering stop\n")
    assert (err.line, err.field) == (2, "begin/end") and "4 fields" not in err.message and "7 fields" in err.message
