"""The Home Assistant importer on a small history export written here: a round trip on the home's
clock computed by hand, and bad rows named by file, line and field."""

import json

import pytest

from globe.data.csv_logs import load_household
from globe.data.importers import GridOptions, import_home_assistant
from globe.errors import ConfigError, DataError

# Grouped by entity, in UTC as Home Assistant writes it. Europe/Amsterdam is UTC+1 on 1 March 2024,
# so local times (in the comments) are one hour later. The export runs to 05:59 on 2 March.
HISTORY = """\
entity_id,state,last_changed
input_select.activity,sleeping,2024-03-01T04:00:00.000Z
input_select.activity,breakfast,2024-03-01T05:31:12.410Z
input_select.activity,unavailable,2024-03-01T05:55:00+00:00
input_select.activity,relax,2024-03-01T06:30:00Z
input_select.activity,relax,2024-03-01T06:45:00Z
input_select.activity,sleeping,2024-03-01T22:00:00Z
binary_sensor.fridge_door,off,2024-03-01T04:00:00.000Z
binary_sensor.fridge_door,on,2024-03-01T05:40:03.120Z
binary_sensor.fridge_door,off,2024-03-01T05:40:30.5Z
binary_sensor.fridge_door,unavailable,2024-03-01T07:00:00Z
binary_sensor.fridge_door,off,2024-03-01T07:10:00Z
binary_sensor.hallway_motion,on,2024-03-01T04:10:00Z
sensor.living_room_temperature,20.5,2024-03-02T04:59:00Z
switch.kettle,off,2024-03-01T04:00:00Z
switch.kettle,on,2024-03-01T21:55:00Z
switch.kettle,off,2024-03-01T23:05:00Z
"""
MAPPING = "sensor,object,room\nbinary_sensor.fridge_door,fridge,kitchen\nswitch.kettle,kettle,kitchen\n"


def _files(tmp_path, history=HISTORY, mapping=MAPPING):
    (tmp_path / "history.csv").write_text(history, encoding="utf-8")
    (tmp_path / "map.csv").write_text(mapping, encoding="utf-8")
    return tmp_path / "history.csv", tmp_path / "map.csv"


def _import(tmp_path, history=HISTORY, **kwargs):
    path, mapping = _files(tmp_path, history)
    kwargs.setdefault("timezone", "Europe/Amsterdam")
    result = import_home_assistant(history=path, dest=tmp_path / "home", activity_entity="input_select.activity",
                                   objects=mapping, **kwargs)
    return result, load_household(tmp_path, "home")


def test_round_trip_on_the_homes_clock_computed_by_hand(tmp_path):
    result, home = _import(tmp_path)
    assert home.objects == ("fridge", "kettle") and [d.name for d in home.train] == ["train/2024-03-01"]
    assert not home.test  # 2 March is partial (the export ends at 05:59), so one day: no test day
    day = home.train[0]
    # sleeping [05:00, 06:31:12) -> 06:00 .. 06:30; breakfast [06:31:12, 06:55) -> 06:40, 06:50;
    # unavailable [06:55, 07:30) is no activity -> idle 07:00 .. 07:20; relax (twice, merged)
    # [07:30, 23:00) -> 07:30 .. 22:50; sleeping from 23:00 -> 23:00 .. 24:00.
    expected = ({m: "sleeping" for m in range(360, 391, 10)} | {400: "breakfast", 410: "breakfast"}
                | {m: "idle" for m in range(420, 441, 10)} | {m: "relax" for m in range(450, 1371, 10)}
                | {m: "sleeping" for m in range(1380, 1441, 10)})
    assert dict(zip(day.minutes, day.activities)) == expected
    in_use = {n.node for n in home.nodes if n.cls == "in_use"}
    used = {obj: [m for m, row in zip(day.minutes, day.locations) if row[k] in in_use]
            for k, obj in enumerate(home.objects)}
    # fridge on 06:40:03-06:40:30.5 -> 06:40; kettle on 22:55 - 00:05 next day -> 22:50 .. 24:00
    assert used == {"fridge": [400], "kettle": list(range(1370, 1441, 10))}
    assert "binary_sensor.fridge_door was unavailable or unknown 1 time (counted as not in use)" in result.notes
    report = json.loads((tmp_path / "home" / "import.json").read_text(encoding="utf-8"))
    relax = next(a for a in report["activities"] if a["activity"] == "relax")
    assert relax["from"] == ["input_select.activity: relax"] and relax["annotations"] == 1
    left = {s["sensor"] for s in report["sensors_left_out"]}
    assert left == {"binary_sensor.hallway_motion", "sensor.living_room_temperature"}
    assert report["settings"] == {"activity_entity": "input_select.activity", "timezone": "Europe/Amsterdam",
                                  "skip_bad_lines": False}


def test_timestamps_without_offset_are_the_homes_clock(tmp_path):
    naive = HISTORY.replace("Z\n", "\n").replace("+00:00\n", "\n")
    _, home = _import(tmp_path, naive, timezone=None)
    day = home.train[0]  # an hour earlier: breakfast 05:31:12-05:55 is before the first row, idle
    assert day.activities[:4] == ("idle", "idle", "idle", "relax")  # [05:55, 06:30) unavailable, then relax


def test_without_a_mapping_there_are_no_objects(tmp_path):
    path, _ = _files(tmp_path)
    result = import_home_assistant(history=path, dest=tmp_path / "home", activity_entity="input_select.activity",
                                   timezone="UTC", options=GridOptions(step_minutes=2))
    assert result.objects == ()
    home = load_household(tmp_path, "home")
    assert home.objects == () and len(home.train[0]) == (1440 - 360) // 2 + 1


def _error(tmp_path, history, mapping=MAPPING, **kwargs):
    path, map_path = _files(tmp_path, history, mapping)
    kwargs.setdefault("timezone", "Europe/Amsterdam")
    kwargs.setdefault("activity_entity", "input_select.activity")
    with pytest.raises(DataError) as info:
        import_home_assistant(history=path, dest=tmp_path / "out", objects=map_path, **kwargs)
    assert not (tmp_path / "out").exists()
    return info.value, path, map_path


BAD_ROWS = [
    ("Binary Sensor,on,2024-03-01T05:00:00Z", "entity_id", "is not an entity id"),
    ("switch.kettle,on,2024-03-01 25:00:00Z", "last_changed", "not a valid date"),
    ("switch.kettle,on,1709269200", "last_changed", "is not an ISO 8601 timestamp"),
    ("switch.kettle,on,2024-03-01T03:59:59Z", "last_changed", "must be in time order"),
    ("switch.kettle,on,2024-03-01T05:00:00", "last_changed", "without a UTC offset among"),
    ("switch.kettle,opening,2024-03-01T05:00:00Z", "state", "is not a state of a mapped binary sensor"),
    ("input_select.activity,a\x07b,2024-03-01T23:00:00Z", "state", "contains a control character"),
    ("switch.kettle,on", "last_changed", "ragged row"),
]


@pytest.mark.parametrize("row, field, message", BAD_ROWS)
def test_a_bad_row_names_file_line_and_field(tmp_path, row, field, message):
    lines = HISTORY.splitlines()
    lines.insert(15, row)  # after switch.kettle's first row (line 15), so it is line 16
    err, path, _ = _error(tmp_path, "\n".join(lines) + "\n")
    assert (err.source, err.line, err.field) == (str(path), 16, field)
    assert message in err.message


def test_skip_bad_lines_leaves_out_every_bad_row_and_lists_it(tmp_path):
    """Every bad row of the test above at once: with --skip-bad-lines the household is the one the
    export without them gives, and each row is listed by line and column."""
    rows = [row for row, _, _ in BAD_ROWS]
    lines = HISTORY.splitlines()
    dirty = "\n".join(lines[:15] + rows + lines[15:]) + "\n"
    (tmp_path / "clean").mkdir()
    (tmp_path / "dirty").mkdir()
    _, want = _import(tmp_path / "clean")
    result, got = _import(tmp_path / "dirty", dirty, skip_bad_lines=True)
    assert [(d.activities, d.locations) for d in got.train] == [(d.activities, d.locations) for d in want.train]
    listed = json.loads(result.report.read_text())["bad_lines"]
    assert [(r["line"], r["field"]) for r in listed] == [(16 + i, field) for i, (_, field, _) in enumerate(BAD_ROWS)]
    assert result.bad_lines == len(BAD_ROWS) and "is not an entity id" in result.first_bad_line


def test_utc_timestamps_need_the_homes_time_zone(tmp_path):
    err, path, _ = _error(tmp_path, HISTORY, timezone=None)
    assert (err.source, err.line, err.field) == (str(path), 2, "last_changed") and "--timezone" in err.message
    with pytest.raises(ConfigError, match="unknown time zone 'Mars/Olympus'"):
        _error(tmp_path, HISTORY, timezone="Mars/Olympus")


def test_the_activity_entity_must_be_in_the_export_and_not_an_object(tmp_path):
    err, path, _ = _error(tmp_path, HISTORY, activity_entity="input_select.what_i_do")
    assert err.source == str(path) and "'input_select.what_i_do' is not in the export" in err.message
    mapping = MAPPING + "input_select.activity,what_i_do,kitchen\n"
    err, _, map_path = _error(tmp_path, HISTORY, mapping)
    assert (err.source, err.line, err.field) == (str(map_path), 4, "sensor")


@pytest.mark.parametrize("text, line, message", [
    ("", 1, "empty file"),
    ("entity_id,state\nswitch.kettle,on\n", 1, "missing column"),
    ("entity_id,state,last_changed\n\x00\x01\x02", 2, "binary data"),
])
def test_empty_headerless_and_binary_exports_are_refused(tmp_path, text, line, message):
    err, path, _ = _error(tmp_path, text)
    assert (err.source, err.line) == (str(path), line) and message in err.message


def test_mapping_errors_name_the_mapping_line(tmp_path):
    for mapping, line, field, message in [
        ("sensor,object\nswitch.kettle,kettle\nswitch.kettle,pot\n", 3, "sensor", "mapped twice"),
        ("sensor,object\nswitch.kettle,my kettle\n", 2, "object", "must be letters"),
        ("sensor,object\nswitch.kettle,activity\n", 2, "object", "column of its own"),
        ("sensor,object\nswitch.kettle,covering\n", 2, "object", "column of its own"),
        ("sensor,object,room\nswitch.kettle,kettle,kitchen\nbinary_sensor.fridge_door,kettle,hall\n", 3, "room",
         "one object, one home place"),
        ("sensor,object,colour\nswitch.kettle,kettle,red\n", 1, "colour", "unknown column"),
    ]:
        err, _, map_path = _error(tmp_path, HISTORY, mapping)
        assert (err.source, err.line, err.field) == (str(map_path), line, field), mapping
        assert message in err.message


def test_the_hour_a_clock_change_repeats_never_runs_the_clock_backwards(tmp_path):
    # Europe/Amsterdam goes back from 03:00 CEST to 02:00 CET on 27 October 2024 (01:00 UTC). A
    # toilet visit 02:30 CEST - 02:10 CET (00:30Z - 01:10Z) would end before it began on the wall
    # clock; its end is held at 02:30, and the night goes on as sleeping.
    history = ("entity_id,state,last_changed\n"
               "input_select.activity,sleeping,2024-10-25T20:00:00Z\n"
               "input_select.activity,toilet,2024-10-27T00:30:00Z\n"
               "input_select.activity,sleeping,2024-10-27T01:10:00Z\n"
               "input_select.activity,breakfast,2024-10-27T06:05:00Z\n"
               "input_select.activity,relax,2024-10-27T06:30:00Z\n"
               "input_select.activity,sleeping,2024-10-27T22:00:00Z\n"
               "input_select.activity,sleeping,2024-10-28T06:00:00Z\n")
    path, mapping = _files(tmp_path, history, "sensor,object\n")
    result = import_home_assistant(history=path, dest=tmp_path / "home", activity_entity="input_select.activity",
                                   timezone="Europe/Amsterdam")
    assert any(note.startswith("rows in an hour that a clock change repeats: 1;") for note in result.notes)
    home = load_household(tmp_path, "home")
    day = next(d for d in home.train + home.test if d.name.endswith("2024-10-27"))
    # CET (UTC+1) after the change: breakfast 07:05-07:30, relax from 07:30, sleeping from 23:00
    acts = dict(zip(day.minutes, day.activities))
    assert [acts[m] for m in (360, 420, 430, 440, 450, 1370, 1380)] == [
        "sleeping", "sleeping", "breakfast", "breakfast", "relax", "relax", "sleeping"]


def test_a_row_years_after_the_others_is_refused_naming_its_line(tmp_path):
    """A row three years after the rest of the export (a corrupt clock) once made three years of
    days: it is refused naming its line, or left out with --skip-bad-lines."""
    history, mapping = _files(tmp_path, HISTORY + "binary_sensor.fridge_door,on,2027-03-01T05:40:03Z\n")
    with pytest.raises(DataError) as err:
        import_home_assistant(history=history, dest=tmp_path / "home", activity_entity="input_select.activity",
                              objects=mapping, timezone="Europe/Amsterdam")
    assert err.value.line == HISTORY.count("\n") + 1 and err.value.field == "time"
    assert "far outside the log" in err.value.message and "--skip-bad-lines" in err.value.message
    result = import_home_assistant(history=history, dest=tmp_path / "home", activity_entity="input_select.activity",
                                   objects=mapping, timezone="Europe/Amsterdam", skip_bad_lines=True)
    far = json.loads(result.report.read_text())["far_outside"]
    assert [r["line"] for r in far] == [HISTORY.count("\n") + 1] and result.train_days == 1


def _events(folder, stem):
    lines = (folder / "events" / f"{stem}.csv").read_text(encoding="utf-8").splitlines()
    return [(s, float(a), float(b)) for s, a, b in (line.split(",") for line in lines[1:])]


def test_every_on_off_entity_is_kept_as_a_sensor_on_the_homes_clock(tmp_path):
    result, _ = _import(tmp_path)
    folder = tmp_path / "home"
    # binary sensors, switches and lights (and mapped entities), not the thermometer or the activity;
    # rooms from the mapping; types from the names (door, motion) and the domain (a switch: appliance)
    assert (folder / "sensors.csv").read_text(encoding="utf-8").splitlines() == [
        "sensor,type,room,object", "binary_sensor.fridge_door,door,kitchen,fridge",
        "binary_sensor.hallway_motion,motion,,", "switch.kettle,appliance,kitchen,kettle"]
    # local times: fridge on 06:40:03.120 .. 06:40:30.5; kettle 22:55 .. 00:05 next day. The hallway
    # motion is on from 05:10 until the export ends (05:59 next day): longer than a day, its limit
    # with one activation, so it is cut to a firing at 05:10, before the day's first row.
    assert _events(folder, "2024-03-01") == [("binary_sensor.fridge_door", 24003.12, 24030.5),
                                             ("switch.kettle", 82500, 86700)]
    report = json.loads((folder / "import.json").read_text(encoding="utf-8"))["sensors"]
    assert report["count"] == 3 and report["types"] == {"appliance": 1, "door": 1, "motion": 1}
    assert [(r["sensor"], r["start"]) for r in report["left_on"]] == [("binary_sensor.hallway_motion",
                                                                       "2024-03-01 05:10:00")]
    assert any("sensors of no object still on at the end of the export" in n and "hallway_motion" in n
               for n in result.notes)


EXTRA_COLUMNS = """\
entity_id,state,last_changed,device_class,area
input_select.activity,cooking,2024-03-01T05:00:00,,
input_select.activity,cooking,2024-03-02T08:00:00,,
binary_sensor.pir_1,on,2024-03-01T07:00:00,occupancy,Living Room
binary_sensor.pir_1,off,2024-03-01T07:00:30,occupancy,Living Room
binary_sensor.window_x,open,2024-03-01T08:00:00,,
binary_sensor.window_x,closed,2024-03-01T08:10:00,,
binary_sensor.bathroom_leak,on,2024-03-01T09:00:00,,Bathroom
binary_sensor.bathroom_leak,unavailable,2024-03-01T09:00:10,,Bathroom
light.hall,on,2024-03-01T20:00:00,,
light.hall,off,2024-03-01T20:00:00.250,,
device_tracker.phone,home,2024-03-01T07:00:00,,
"""


def test_device_class_and_area_columns_give_type_and_room(tmp_path):
    path, _ = _files(tmp_path, EXTRA_COLUMNS)
    result = import_home_assistant(history=path, dest=tmp_path / "home", activity_entity="input_select.activity")
    folder = tmp_path / "home"
    assert (folder / "sensors.csv").read_text(encoding="utf-8").splitlines()[1:] == [
        "binary_sensor.pir_1,motion,living_room,", "binary_sensor.window_x,window,,",
        "binary_sensor.bathroom_leak,moisture,bathroom,", "light.hall,light,,"]
    assert _events(folder, "2024-03-01") == [("binary_sensor.pir_1", 25200, 25230),
                                             ("binary_sensor.window_x", 28800, 29400),
                                             ("binary_sensor.bathroom_leak", 32400, 32410),
                                             ("light.hall", 72000, 72000.25)]
    assert not any("columns not used" in n for n in result.notes)


@pytest.mark.parametrize(("entity", "device_class", "kind"), [
    ("binary_sensor.hallway_motion", "", "motion"), ("binary_sensor.bed_occupancy", "", "motion"),
    ("binary_sensor.front_door", "", "door"), ("binary_sensor.kitchen_window", "", "window"),
    ("binary_sensor.cupboard_opening", "", "contact"), ("binary_sensor.sink_moisture", "", "moisture"),
    ("binary_sensor.thing", "", "other"), ("switch.tv", "", "appliance"), ("light.hall", "", "light"),
    ("binary_sensor.thing", "garage_door", "door"), ("binary_sensor.thing", "Presence", "motion"),
    ("binary_sensor.thing", "sound", "sound"), ("binary_sensor.front_door", "opening", "contact"),
])
def test_the_type_rule(entity, device_class, kind):
    from globe.data.importers.home_assistant import sensor_type

    assert sensor_type(entity, device_class) == kind


def test_rows_may_stop_short_of_the_attribute_columns_a_climate_entity_adds(tmp_path):
    """The History panel adds a column per attribute of a climate (humidifier, water heater)
    entity and writes them on its rows only: every other row was 'ragged' and stopped the import.
    A row that holds the columns read is read; one with more fields than the header is still an
    error naming its line."""
    header = "entity_id,state,last_changed,current_temperature,hvac_action,target_temp_high,target_temp_low,temperature"
    climate = ["climate.living_room,heat,2024-03-01T04:00:00.000Z,20.5,heating,,,21",
               "climate.living_room,heat,2024-03-01T09:00:00.000Z,20.5,idle"]
    rows = HISTORY.splitlines()
    result, home = _import(tmp_path, "\n".join([header, *climate, *rows[1:]]) + "\n")
    (tmp_path / "plain").mkdir()
    _, want = _import(tmp_path / "plain")
    assert [(d.name, d.activities, d.locations) for d in home.train + home.test] == \
        [(d.name, d.activities, d.locations) for d in want.train + want.test]
    assert "columns not used: current_temperature, hvac_action, target_temp_high, target_temp_low, temperature" \
        in result.notes
    (tmp_path / "long").mkdir()
    with pytest.raises(DataError) as err:
        _import(tmp_path / "long", "\n".join([header, *climate, rows[1] + ",1,2,3,4,5,6"]) + "\n")
    assert err.value.line == 4 and "ragged row" in err.value.message
