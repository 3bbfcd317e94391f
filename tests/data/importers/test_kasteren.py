"""The van Kasteren / Ordóñez importer on small logs written here: both forms round-tripped by hand,
and bad lines named by file, line and field."""

import json

import pytest

from globe.data.csv_logs import load_household
from globe.data.importers import import_kasteren
from globe.errors import DataError

# Ordóñez: a two-line header, tabs in some lines and spaces in others, sensors as Location Type Place.
ORDONEZ_SENSORS = """\
Start time          End time            Location  Type      Place
----------          --------            --------  ----      -----
2011-11-28 05:40:00\t\t2011-11-28 06:18:11\t\tBed\t\tPressure\tBedroom
2011-11-28 06:21:00\t\t2011-11-28 06:21:30\t\tCupboard\tMagnetic\tKitchen
2011-11-28 06:29:50\t\t2011-11-28 06:40:05\t\tToaster\t\tElectric\tKitchen
2011-11-28 06:35:00\t\t2011-11-28 06:35:02\t\tMaindoor\tMagnetic\tEntrance
2011-11-28 07:00:00\t\t2011-11-28 07:00:10\t\tBasin\t\tPIR\t\tBathroom
2011-11-29 08:00:00    2011-11-29 08:09:59    Fridge    Magnetic    Kitchen
2011-11-30 00:29:00    2011-11-30 00:30:00    Bed       Pressure    Bedroom
"""
ORDONEZ_ADLS = """\
Start time          End time            Activity
----------          --------            --------
2011-11-28 05:40:00\t\t2011-11-28 06:18:00\t\tSleeping
2011-11-28 06:19:00\t\t2011-11-28 06:45:00\t\tBreakfast
2011-11-28 07:00:00\t\t2011-11-28 07:05:00\t\tGrooming
2011-11-28 07:11:00\t\t2011-11-28 07:19:00\t\tToileting
2011-11-29 07:55:00    2011-11-29 08:20:00    Spare_Time/TV
2011-11-30 00:20:00    2011-11-30 00:30:00    Sleeping
"""

# van Kasteren: numeric ids, named by a sensor list and an activity list.
KASTEREN_SENSE = """\
Start time\tEnd time\tID\tVal
25-Feb-2008 05:59:00\t25-Feb-2008 06:01:00\t14\t1
25-Feb-2008 06:15:00\t25-Feb-2008 06:15:05\t7\t1
25-Feb-2008 06:16:00\t25-Feb-2008 06:33:00\t8\t1
26-Feb-2008 00:10:00\t26-Feb-2008 00:10:01\t12\t1
"""
KASTEREN_ACT = """\
Start time\tEnd time\tID
25-Feb-2008 05:50:00\t25-Feb-2008 06:05:00\t4
25-Feb-2008 06:14:00\t25-Feb-2008 06:40:00\t17
"""
SENSOR_LIST = "sensor,name,type,room\n7,Cups cupboard,reed,kitchen\n8,Fridge,reed,kitchen\n12,Frontdoor,reed,hall\n" \
              "14,ToiletFlush,flush,toilet\n"
ACTIVITY_LIST = "id,activity\n4,use toilet\n17,get drink\n"


def _files(tmp_path, **texts):
    paths = {}
    for name, text in texts.items():
        paths[name] = tmp_path / f"{name}.txt"
        paths[name].write_text(text, encoding="utf-8")
    return paths


def _used(home, day):
    in_use = {n.node for n in home.nodes if n.cls == "in_use"}
    return {obj: [m for m, row in zip(day.minutes, day.locations) if row[k] in in_use]
            for k, obj in enumerate(home.objects)}


def _acts(day):
    return {m: a for m, a in zip(day.minutes, day.activities) if a != "idle"}


def test_ordonez_round_trip_computed_by_hand(tmp_path):
    f = _files(tmp_path, sensors=ORDONEZ_SENSORS, adls=ORDONEZ_ADLS)
    result = import_kasteren(sensors_file=f["sensors"], activities_file=f["adls"], dest=tmp_path / "home")
    home = load_household(tmp_path, "home")
    # Magnetic and Electric sensors that are not doors, by name; all in their place, the kitchen
    assert home.objects == ("cupboard", "fridge", "toaster")
    assert {n.cls: n.start_location for n in home.nodes if n.movable} == dict.fromkeys(home.objects, "kitchen#1")
    assert [d.name for d in home.train] == ["train/2011-11-28"] and [d.name for d in home.test] == ["test/2011-11-29"]
    day = home.train[0]
    # Sleeping [05:40, 06:18) -> 06:00, 06:10; Breakfast [06:19, 06:45) -> 06:20 .. 06:40;
    # Grooming [07:00, 07:05) -> 07:00; Toileting [07:11, 07:19) covers no step's start.
    assert _acts(day) == {360: "Sleeping", 370: "Sleeping", 380: "Breakfast", 390: "Breakfast", 400: "Breakfast",
                          420: "Grooming"}
    # cupboard open 06:21:00-06:21:30 (step 06:20); toaster on 06:29:50-06:40:05 (06:20, 06:30, 06:40)
    assert _used(home, day) == {"cupboard": [380], "fridge": [], "toaster": [380, 390, 400]}
    test_day = home.test[0]
    assert _acts(test_day) == {480: "Spare_Time/TV", 490: "Spare_Time/TV"}
    assert _used(home, test_day) == {"cupboard": [], "fridge": [480], "toaster": []}
    report = json.loads((tmp_path / "home" / "import.json").read_text(encoding="utf-8"))
    left = {s["sensor"]: s["why"] for s in report["sensors_left_out"]}
    assert set(left) == {"Bed Pressure Bedroom", "Maindoor Magnetic Entrance", "Basin PIR Bathroom"}
    assert "a door" in left["Maindoor Magnetic Entrance"] and "'PIR'" in left["Basin PIR Bathroom"]
    toileting = next(a for a in report["activities"] if a["activity"] == "Toileting")
    assert toileting["annotations_on_no_row"] == 1 and toileting["rows"] == 0
    assert report["dropped_days"] == [{"date": "2011-11-30", "why": "partial: the log ends at 2011-11-30 00:30:00, "
                                                                     "before this day's last row (24:00)"}]
    assert result.notes[:2] == (f"{f['sensors']}: skipped 2 header lines before the first record",
                                f"{f['adls']}: skipped 2 header lines before the first record")
    assert {s["date"] for s in report["silent_stretches"]} <= set(report["days"]["train"] + report["days"]["test"])


def test_van_kasteren_round_trip_with_sensor_and_activity_lists(tmp_path):
    f = _files(tmp_path, sense=KASTEREN_SENSE, act=KASTEREN_ACT, sensors=SENSOR_LIST, activities=ACTIVITY_LIST)
    import_kasteren(sensors_file=f["sense"], activities_file=f["act"], dest=tmp_path / "home",
                    sensor_list=f["sensors"], activity_list=f["activities"])
    home = load_household(tmp_path, "home")
    assert home.objects == ("cups_cupboard", "fridge")  # the Frontdoor is a door; the flush is not a contact
    assert len(home.train) == 1 and not home.test  # one kept day: no test day
    day = home.train[0]
    # use toilet [05:50, 06:05) -> 06:00; get drink [06:14, 06:40) -> 06:20, 06:30 (06:10 is before it)
    assert _acts(day) == {360: "use toilet", 380: "get drink", 390: "get drink"}
    # cups 06:15:00-06:15:05 -> 06:10; fridge 06:16-06:33 -> 06:10, 06:20, 06:30
    assert _used(home, day) == {"cups_cupboard": [370], "fridge": [370, 380, 390]}
    report = json.loads((tmp_path / "home" / "import.json").read_text(encoding="utf-8"))
    drink = next(a for a in report["activities"] if a["activity"] == "get drink")
    assert drink["from"] == ["17"]


def test_without_types_no_sensor_is_an_object_and_the_report_says_how_to_map_them(tmp_path):
    f = _files(tmp_path, sense=KASTEREN_SENSE, act=KASTEREN_ACT)
    result = import_kasteren(sensors_file=f["sense"], activities_file=f["act"], dest=tmp_path / "home",
                             allow_numeric_labels=True)
    assert result.objects == () and result.activities == ("17", "4", "idle")
    home = load_household(tmp_path, "home")
    assert home.objects == () and {n.category for n in home.nodes} == {"Home", "Rooms", "InUse"}
    report = json.loads((tmp_path / "home" / "import.json").read_text(encoding="utf-8"))
    assert all("no sensor type known" in s["why"] for s in report["sensors_left_out"])


def test_a_mapping_names_van_kasteren_ids(tmp_path):
    f = _files(tmp_path, sense=KASTEREN_SENSE, act=KASTEREN_ACT)
    mapping = tmp_path / "map.csv"
    mapping.write_text("sensor,object,room,furniture\n8,fridge,kitchen,\n7,cups,kitchen,cupboard\n", encoding="utf-8")
    import_kasteren(sensors_file=f["sense"], activities_file=f["act"], dest=tmp_path / "home", objects=mapping,
                    allow_numeric_labels=True)
    home = load_household(tmp_path, "home")
    assert home.objects == ("fridge", "cups")
    place = {n.cls: n.start_location for n in home.nodes if n.movable}
    assert place == {"fridge": "kitchen#1", "cups": "cupboard#3"}
    assert next(n for n in home.nodes if n.node == "cupboard#3").start_location == "kitchen#1"


def _error(tmp_path, **texts):
    lists = {k: texts.pop(k) for k in ("sensors", "activities") if k in texts}
    f = _files(tmp_path, **texts, **lists)
    with pytest.raises(DataError) as info:
        import_kasteren(sensors_file=f["sense"], activities_file=f["act"], dest=tmp_path / "out",
                        sensor_list=f.get("sensors"), activity_list=f.get("activities"))
    assert not (tmp_path / "out").exists()
    return info.value, f


@pytest.mark.parametrize("bad, field, message", [
    ("25-Fex-2008 06:15:00\t25-Feb-2008 06:15:05\t7\t1", "start", "is not a date"),
    ("25-Feb-2008 06:15\t25-Feb-2008 06:15:05\t7\t1", "start", "is not a time of day"),
    ("25-Feb-2008 06:15:00\t31-Feb-2008 06:15:05\t7\t1", "end", "not a valid date"),
    ("25-Feb-2008 06:15:00\t25-Feb-2008 06:15:05\t99\t1", "sensor", "unknown sensor '99'"),
    ("25-Feb-2008 06:15:00\t25-Feb-2008 06:14:59\t7\t1", "end", "before it starts"),
    ("25-Feb-2008 06:15:00\t25-Feb-2008 06:15:05\t7\t0", "value", "is not 1"),
    ("25-Feb-2008 06:15:00\t25-Feb-2008 06:15:05\tCups Reed Kitchen", "sensor", "one log, one form"),
    ("25-Feb-2008 06:15:00\t25-Feb-2008 06:15:05", "sensor", "nothing after the two times"),
    ("25-Feb-2008 06:15:00", "start", "not a record"),
    ("Start time\tEnd time\tID\tVal", "start", "'Start' is not a date"),  # a header only comes first
])
def test_a_bad_sensor_line_names_file_line_and_field(tmp_path, bad, field, message):
    lines = KASTEREN_SENSE.splitlines()
    lines.insert(3, bad)
    err, f = _error(tmp_path, sense="\n".join(lines) + "\n", act=KASTEREN_ACT, sensors=SENSOR_LIST)
    assert (err.source, err.line, err.field) == (str(f["sense"]), 4, field)
    assert message in err.message


@pytest.mark.parametrize("bad, field, message", [
    ("25-Feb-2008 06:20:00\t25-Feb-2008 06:30:00\t5", "activity", "unknown activity id '5'"),
    ("25-Feb-2008 06:20:00\t25-Feb-2008 06:10:00\t4", "end", "before it starts"),
    ("25-Feb-2008 06:39:59\t25-Feb-2008 06:50:00\t4", "start", "may not overlap"),
])
def test_a_bad_activity_line_names_file_line_and_field(tmp_path, bad, field, message):
    err, f = _error(tmp_path, sense=KASTEREN_SENSE, act=KASTEREN_ACT + bad + "\n", activities=ACTIVITY_LIST)
    assert (err.source, err.line, err.field) == (str(f["act"]), 4, field)
    assert message in err.message


def test_an_ordonez_log_needs_no_sensor_list(tmp_path):
    err, f = _error(tmp_path, sense=ORDONEZ_SENSORS, act=ORDONEZ_ADLS, sensors=SENSOR_LIST)
    assert (err.source, err.line, err.field) == (str(f["sense"]), 3, "sensor")
    assert "leave out --sensor-list" in err.message


def test_sensor_and_activity_lists_are_checked(tmp_path):
    twice = SENSOR_LIST + "7,Cups again,reed,kitchen\n"
    err, f = _error(tmp_path, sense=KASTEREN_SENSE, act=KASTEREN_ACT, sensors=twice)
    assert (err.source, err.line, err.field) == (str(f["sensors"]), 6, "sensor") and "listed twice" in err.message
    err, f = _error(tmp_path, sense=KASTEREN_SENSE, act=KASTEREN_ACT, activities="id,label\n4,x\n")
    assert (err.source, err.line, err.field) == (str(f["activities"]), 1, "activity")


def test_empty_and_header_only_files_are_refused(tmp_path):
    err, f = _error(tmp_path, sense="", act=KASTEREN_ACT)
    assert (err.source, err.line) == (str(f["sense"]), 1) and "empty file" in err.message
    err, f = _error(tmp_path, sense=KASTEREN_SENSE, act="Start time\tEnd time\tID\n")
    assert (err.source, err.line) == (str(f["act"]), 1) and "no records (only 1 header line)" in err.message


def test_one_object_from_sensors_in_two_places_needs_its_room_in_the_mapping(tmp_path):
    f = _files(tmp_path, sensors=ORDONEZ_SENSORS, adls=ORDONEZ_ADLS)
    mapping = tmp_path / "map.csv"
    mapping.write_text("sensor,object\nCupboard Magnetic Kitchen,storage\nBasin PIR Bathroom,storage\n",
                       encoding="utf-8")
    with pytest.raises(DataError) as info:
        import_kasteren(sensors_file=f["sensors"], activities_file=f["adls"], dest=tmp_path / "home", objects=mapping)
    assert (info.value.source, info.value.line) == (str(f["sensors"]), 7) and "different rooms" in info.value.message
    mapping.write_text("sensor,object,room\nCupboard Magnetic Kitchen,storage,kitchen\n"
                       "Basin PIR Bathroom,storage,kitchen\n", encoding="utf-8")
    import_kasteren(sensors_file=f["sensors"], activities_file=f["adls"], dest=tmp_path / "home", objects=mapping)
    day = load_household(tmp_path, "home").train[0]
    # either sensor marks the use: the cupboard at 06:20, the basin at 07:00
    assert [m for m, row in zip(day.minutes, day.locations) if row[0] == "in_use#2"] == [380, 420]


# The files as distributed: their own lists of ids before the records, a Length footer after them.
DISTRIBUTED_SENSE = """\
Sensor labels:
7\t'Cups cupboard'
8: 'Fridge'
12,Frontdoor
[14] "ToiletFlush"

Start time\tEnd time\tID\tVal
--------------------------------------------------
""" + KASTEREN_SENSE.split("\n", 1)[1] + "Length: 4\n"
DISTRIBUTED_ACT = """\
Activity labels:
4\t'use toilet'
17\t'get drink'
Start time\tEnd time\tID
""" + KASTEREN_ACT.split("\n", 1)[1] + "  LENGTH : 2 \n"


def test_the_files_as_distributed_name_their_own_ids_and_end_with_a_footer(tmp_path):
    f = _files(tmp_path, sense=DISTRIBUTED_SENSE, act=DISTRIBUTED_ACT)
    result = import_kasteren(sensors_file=f["sense"], activities_file=f["act"], dest=tmp_path / "home")
    assert result.activities == ("get drink", "idle", "use toilet")
    report = json.loads((tmp_path / "home" / "import.json").read_text(encoding="utf-8"))
    names = {s["sensor"] for s in report["sensors_left_out"]}
    assert names == {"7", "8", "12", "14"} and result.objects == ()  # the lists name, but say no type
    assert f"{f['sense']}: its own list names 4 sensors (lines 2-5); a list given as an option names the ids it " \
           "lists instead" in result.notes
    assert f"{f['sense']}: skipped 3 header lines before the first record" in result.notes
    assert not any("footer" in n for n in result.notes)  # both footers count their records right
    assert not report["bad_lines"]


def test_an_option_names_the_ids_it_lists_and_the_files_list_the_others(tmp_path):
    f = _files(tmp_path, sense=DISTRIBUTED_SENSE, act=DISTRIBUTED_ACT, sensors="sensor,name,type,room\n"
               "7,Cups,reed,kitchen\n8,Fridge,reed,kitchen\n", activities="id,activity\n4,toilet\n")
    result = import_kasteren(sensors_file=f["sense"], activities_file=f["act"], dest=tmp_path / "home",
                             sensor_list=f["sensors"], activity_list=f["activities"])
    assert result.objects == ("cups", "fridge") and result.activities == ("get drink", "idle", "toilet")
    err, f = _error(tmp_path, sense=DISTRIBUTED_SENSE.replace("\t7\t1\n", "\t99\t1\n"), act=DISTRIBUTED_ACT)
    assert (err.source, err.line, err.field) == (str(f["sense"]), 10, "sensor")
    assert f"unknown sensor '99' (not in the list at the head of {f['sense']})" in err.message


def test_a_footer_that_miscounts_is_noted_and_one_elsewhere_is_a_bad_line(tmp_path):
    f = _files(tmp_path, sense=DISTRIBUTED_SENSE.replace("Length: 4", "Length: 40"), act=DISTRIBUTED_ACT)
    result = import_kasteren(sensors_file=f["sense"], activities_file=f["act"], dest=tmp_path / "home")
    assert f"{f['sense']}: its footer says Length: 40, but it holds 4 records (checked, not enforced)" in result.notes
    lines = DISTRIBUTED_ACT.splitlines()
    err, f = _error(tmp_path, sense=DISTRIBUTED_SENSE, act="\n".join(lines[:5] + [lines[-1]] + lines[5:]) + "\n")
    assert (err.source, err.line, err.field) == (str(f["act"]), 6, "start") and "not a record" in err.message


@pytest.mark.parametrize("act, line, field, message", [
    ("Labels:\n4 'use toilet'\n4 'toilet again'\n", 3, "id", "id '4' is listed twice (also line 2)"),
    ("Labels:\n4 ''\n", 2, "name", "empty"),
])
def test_a_bad_line_of_a_files_own_list_names_file_line_and_field(tmp_path, act, line, field, message):
    err, f = _error(tmp_path, sense=DISTRIBUTED_SENSE, act=act + KASTEREN_ACT)
    assert (err.source, err.line, err.field) == (str(f["act"]), line, field) and message in err.message


def test_numbered_activities_nothing_names_are_refused_unless_allowed(tmp_path):
    err, f = _error(tmp_path, sense=KASTEREN_SENSE, act=KASTEREN_ACT)
    assert (err.source, err.line, err.field) == (str(f["act"]), 2, "activity")
    assert "'4' is a number" in err.message and "--activity-list" in err.message
    assert "--allow-numeric-labels" in err.message
    result = import_kasteren(sensors_file=f["sense"], activities_file=f["act"], dest=tmp_path / "home",
                             allow_numeric_labels=True)
    assert result.activities == ("17", "4", "idle")
    assert json.loads(result.report.read_text())["settings"]["allow_numeric_labels"] is True


def test_skip_bad_lines_leaves_out_the_bad_records_of_both_files_and_lists_them(tmp_path):
    """A corrupt line of every kind in both files: with --skip-bad-lines the household is the one
    the files without them give, and the report lists each by file and line."""
    sense = KASTEREN_SENSE.splitlines()
    act = KASTEREN_ACT.splitlines()
    at = "25-Feb-2008 06:15:00\t25-Feb-2008 06:15:05"
    bad_sense = ["25-Fex-2008 06:15:00\t25-Feb-2008 06:15:05\t7\t1", "25-Feb-2008 06:15:00\t25-Feb-2008 06:14:59\t7\t1",
                 f"{at}\t99\t1", f"{at}\t7\t0", f"{at}\tCups Reed Kitchen", "25-Feb-2008 06:15:00"]
    bad_act = ["25-Feb-2008 06:20:00\t25-Feb-2008 06:30:00\t5", "25-Feb-2008 06:20:00\t25-Feb-2008 06:10:00\t4"]
    dirty_sense = sense[:2] + bad_sense + sense[2:]
    dirty_act = act[:2] + bad_act + act[2:]
    (tmp_path / "clean").mkdir()
    (tmp_path / "dirty").mkdir()
    lists = {"sensors": SENSOR_LIST, "activities": ACTIVITY_LIST}
    clean = _files(tmp_path / "clean", sense=KASTEREN_SENSE, act=KASTEREN_ACT, **lists)
    dirty = _files(tmp_path / "dirty", sense="\n".join(dirty_sense) + "\n", act="\n".join(dirty_act) + "\n", **lists)
    for f, skip in ((clean, False), (dirty, True)):
        import_kasteren(sensors_file=f["sense"], activities_file=f["act"], dest=f["sense"].parent / "home",
                        sensor_list=f["sensors"], activity_list=f["activities"], skip_bad_lines=skip)
    want, got = (load_household(tmp_path / d, "home") for d in ("clean", "dirty"))
    assert [(d.activities, d.locations) for d in got.train] == [(d.activities, d.locations) for d in want.train]
    listed = json.loads((tmp_path / "dirty" / "home" / "import.json").read_text())["bad_lines"]
    assert [(r["source"], r["line"], r["field"]) for r in listed] == [
        (str(dirty["sense"]), 3, "start"), (str(dirty["sense"]), 4, "end"), (str(dirty["sense"]), 5, "sensor"),
        (str(dirty["sense"]), 6, "value"), (str(dirty["sense"]), 7, "sensor"), (str(dirty["sense"]), 8, "start"),
        (str(dirty["act"]), 3, "activity"), (str(dirty["act"]), 4, "end")]
    with pytest.raises(DataError) as err:
        import_kasteren(sensors_file=dirty["sense"], activities_file=dirty["act"], dest=tmp_path / "x",
                        sensor_list=dirty["sensors"], activity_list=dirty["activities"])
    assert err.value.line == 3 and not (tmp_path / "x").exists()


def _sensor_rows(folder):
    return (folder / "sensors.csv").read_text(encoding="utf-8").splitlines()[1:]


def _events(folder, stem):
    lines = (folder / "events" / f"{stem}.csv").read_text(encoding="utf-8").splitlines()
    return [(s, float(a), float(b)) for s, a, b in (line.rsplit(",", 2) for line in lines[1:])]


def test_every_sensor_of_a_van_kasteren_log_is_kept_with_its_listed_type_and_room(tmp_path):
    f = _files(tmp_path, sense=KASTEREN_SENSE, act=KASTEREN_ACT, sensors=SENSOR_LIST, activities=ACTIVITY_LIST)
    import_kasteren(sensors_file=f["sense"], activities_file=f["act"], dest=tmp_path / "home",
                    sensor_list=f["sensors"], activity_list=f["activities"])
    folder = tmp_path / "home"
    # types from the list: flush flush, reed contact (door: the name says so); rooms from the list
    assert _sensor_rows(folder) == ["14,flush,toilet,", "7,contact,kitchen,cups_cupboard", "8,contact,kitchen,fridge",
                                    "12,door,hall,"]
    # the day's span is 06:00 (21600 s) .. 00:10 next day (87000 s): the flush 05:59-06:01 is cut
    # to it; the front door at 00:10:00 next day begins as the span ends, so it is the next day's
    assert _events(folder, "2008-02-25") == [("14", 21600, 21660), ("7", 22500, 22505), ("8", 22560, 23580)]
    report = json.loads((folder / "import.json").read_text(encoding="utf-8"))["sensors"]
    assert report["types"] == {"contact": 2, "door": 1, "flush": 1} and report["activations"] == 3


def test_ordonez_sensors_take_their_type_and_place(tmp_path):
    f = _files(tmp_path, sensors=ORDONEZ_SENSORS, adls=ORDONEZ_ADLS)
    import_kasteren(sensors_file=f["sensors"], activities_file=f["adls"], dest=tmp_path / "home")
    folder = tmp_path / "home"
    assert _sensor_rows(folder) == [
        "Bed Pressure Bedroom,pressure,bedroom,", "Cupboard Magnetic Kitchen,contact,kitchen,cupboard",
        "Toaster Electric Kitchen,appliance,kitchen,toaster", "Maindoor Magnetic Entrance,door,entrance,",
        "Basin PIR Bathroom,motion,bathroom,", "Fridge Magnetic Kitchen,contact,kitchen,fridge"]
    assert _events(folder, "2011-11-28")[0] == ("Bed Pressure Bedroom", 21600, 22691)  # 05:40 .. 06:18:11, cut


# The file's own list names the sensors, with no type or room: both come from the names.
NAMED_SENSE = """\
1 Hall-Toilet door
2 Pressure mat
3 Microwave
4 ToiletFlush
5 Washingmachine
6 Thing
Start time\tEnd time\tID\tVal
25-Feb-2008 05:59:00\t25-Feb-2008 06:00:30\t1\t1
25-Feb-2008 06:15:00\t25-Feb-2008 06:15:05\t3\t1
25-Feb-2008 06:16:00\t25-Feb-2008 06:16:00\t4\t1
25-Feb-2008 07:00:00\t25-Feb-2008 07:30:00\t2\t1
25-Feb-2008 08:00:00\t25-Feb-2008 08:00:01\t5\t1
25-Feb-2008 09:00:00\t25-Feb-2008 09:00:01\t6\t1
26-Feb-2008 00:10:00\t26-Feb-2008 00:10:01\t6\t1
"""


def test_without_a_type_the_name_gives_type_and_room(tmp_path):
    f = _files(tmp_path, sense=NAMED_SENSE, act=KASTEREN_ACT, activities=ACTIVITY_LIST)
    import_kasteren(sensors_file=f["sense"], activities_file=f["act"], dest=tmp_path / "home",
                    activity_list=f["activities"])
    folder = tmp_path / "home"
    assert _sensor_rows(folder) == ["1,door,toilet,", "3,contact,kitchen,", "4,flush,toilet,", "2,pressure,,",
                                    "5,contact,,", "6,other,,"]
    assert _events(folder, "2008-02-25") == [("1", 21600, 21630), ("3", 22500, 22505), ("4", 22560, 22560),
                                             ("2", 25200, 27000), ("5", 28800, 28801), ("6", 32400, 32401)]


@pytest.mark.parametrize(("name", "kind", "listed", "room", "expected"), [
    ("Hall-Bedroom door", "", "", "bedroom", "door"),
    ("Frontdoor", "reed", "", "", "door"),
    ("Cups cupboard", "reed", "", "kitchen", "contact"),
    ("Fridge", "", "Kitchen", "kitchen", "contact"),
    ("Seat", "Pressure", "Living", "living", "pressure"),
    ("Toilet", "Flush", "Bathroom", "bathroom", "flush"),
    ("Cooktop", "PIR", "", "kitchen", "motion"),
    ("Lamp", "Dimmer", "", "", "dimmer"),
    ("Lamp", "Weird Type!", "", "", "weird_type"),
    ("Kettle", "", "", "kitchen", "appliance"),
    ("Shelf", "", "", "", "other"),
])
def test_the_type_and_room_rules(name, kind, listed, room, expected):
    from globe.data.importers.kasteren import sensor_room, sensor_type
    from globe.data.importers.objects import Sensor

    sensor = Sensor("k", name, kind, listed)
    assert sensor_type(sensor) == expected and sensor_room(sensor) == room
    assert sensor_room(sensor, "garage") == "garage"  # the mapping's room wins
