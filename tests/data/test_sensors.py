"""A household's every-sensor files (sensors.csv, events/<day>.csv): a round trip, each bad line
named by file, line and field, and the checks against the household's days (globe data validate)."""

import re
import subprocess
import sys

import numpy as np
import pytest

from globe.data.csv_logs import load_household
from globe.data.csv_logs import load_sensor_data as load_from_csv_logs
from globe.data.importers import import_casas
from globe.data.sensors import (
    Sensor,
    SensorData,
    SensorDay,
    _seconds,
    check_sensor_data,
    load_sensor_data,
    read_sensor_data,
    write_sensor_data,
)
from globe.errors import DataError

# Two kept days (11-04 train, 11-05 test): a motion sensor, an item sensor (the object), a thermometer.
LOG = """\
2010-11-04 05:50:00.000000 M001 ON Sleeping begin
2010-11-04 06:25:00.000000 M001 OFF Sleeping end
2010-11-04 07:02:00.250000 I001 ABSENT Cooking begin
2010-11-04 07:05:30.000000 I001 PRESENT Cooking end
2010-11-04 12:00:00.000000 T001 21.5
2010-11-05 07:00:00.000000 M001 ON Cooking begin
2010-11-05 07:00:05.000000 M001 OFF
2010-11-05 07:30:00.000000 I001 ABSENT Cooking end
2010-11-05 07:31:00.000000 I001 PRESENT
2010-11-06 00:30:00.000000 M001 ON
"""


def _sensors_and_days():
    sensors = (Sensor("M001", "motion", "hall"), Sensor("I001", "contact", "kitchen", "pot"),
               Sensor("T 1", "temperature"))
    days = {"2010-11-04": SensorDay.of("2010-11-04", [(1, 25320.25, 25530.0), (0, 21600.0, 23100.0)]),
            "2010-11-05": SensorDay.of("2010-11-05", [])}
    return SensorData(sensors, days)


def test_a_round_trip_writes_and_reads_the_same_data(tmp_path):
    data = _sensors_and_days()
    write_sensor_data(tmp_path, data)
    assert (tmp_path / "sensors.csv").read_text(encoding="utf-8") == (
        "sensor,type,room,object\nM001,motion,hall,\nI001,contact,kitchen,pot\nT 1,temperature,,\n")
    assert (tmp_path / "events" / "2010-11-04.csv").read_text(encoding="utf-8") == (
        "sensor,start,end\nM001,21600,23100\nI001,25320.25,25530\n")
    back = read_sensor_data(tmp_path)
    assert back is not None and back.sensors == data.sensors and set(back.days) == set(data.days)
    for stem, day in data.days.items():
        got = back.days[stem]
        assert got.name == stem and len(got) == len(day)
        for field in ("sensor", "start", "end"):
            assert np.array_equal(getattr(got, field), getattr(day, field))
    assert back.of("train/2010-11-04") is back.days["2010-11-04"] and back.of("test/2010-11-09") is None
    assert back.index("I001") == 1


@pytest.mark.parametrize(("value", "text"), [(25.0, "25"), (25.5, "25.5"), (25.0001, "25"), (86399.9996, "86400"),
                                             (0.125, "0.125"), (0.0, "0")])
def test_seconds_are_written_to_the_millisecond_never_with_a_bare_point(value, text):
    assert _seconds(value) == text


def test_a_folder_without_sensors_has_none(tmp_path):
    assert read_sensor_data(tmp_path) is None
    (tmp_path / "events").mkdir()
    with pytest.raises(DataError, match="an events folder without sensors.csv"):
        read_sensor_data(tmp_path)


SENSORS_HEADER = "sensor,type,room,object\n"
BAD_SENSORS = [
    ("M001,motion,,\nM001,door,,\n", 3, "sensor", "listed twice (first on line 2)"),
    ("M001,Motion sensor,,\n", 2, "type", "expected one lowercase word"),
    (",motion,,\n", 2, "sensor", "empty sensor name"),
    ("M001,motion,hall\n", 2, "object", "ragged row"),
    ("M001,motion,ha\x07ll,\n", 2, "room", "control character"),
]


@pytest.mark.parametrize(("rows", "line", "field", "message"), BAD_SENSORS)
def test_a_bad_line_of_sensors_csv_names_file_line_and_field(tmp_path, rows, line, field, message):
    (tmp_path / "sensors.csv").write_text(SENSORS_HEADER + rows, encoding="utf-8")
    with pytest.raises(DataError, match=re.escape(message)) as info:
        read_sensor_data(tmp_path)
    assert (info.value.source, info.value.line, info.value.field) == (str(tmp_path / "sensors.csv"), line, field)


BAD_EVENTS = [
    ("M001,21600,21700\nM009,21600,21700\n", 3, "sensor", "'M009' is not in sensors.csv"),
    ("M001,6am,21700\n", 2, "start", "is not a number of seconds"),
    ("M001,21600,nan\n", 2, "end", "outside the day"),
    ("M001,21700,21600\n", 2, "end", "ends (21600) before it starts (21700)"),
    ("M001,21600\n", 2, "end", "ragged row"),
]


@pytest.mark.parametrize(("rows", "line", "field", "message"), BAD_EVENTS)
def test_a_bad_line_of_an_events_file_names_file_line_and_field(tmp_path, rows, line, field, message):
    (tmp_path / "sensors.csv").write_text(SENSORS_HEADER + "M001,motion,,\n", encoding="utf-8")
    (tmp_path / "events").mkdir()
    path = tmp_path / "events" / "2010-11-04.csv"
    path.write_text("sensor,start,end\n" + rows, encoding="utf-8")
    with pytest.raises(DataError, match=re.escape(message)) as info:
        read_sensor_data(tmp_path)
    assert (info.value.source, info.value.line, info.value.field) == (str(path), line, field)


def _imported(tmp_path):
    (tmp_path / "log.txt").write_text(LOG, encoding="utf-8")
    import_casas(log_file=tmp_path / "log.txt", dest=tmp_path / "home")
    return tmp_path / "home"


def test_an_imported_household_loads_its_sensors_and_validates(tmp_path):
    folder = _imported(tmp_path)
    data = load_sensor_data(tmp_path, "home")
    assert data is not None and load_from_csv_logs(tmp_path, "home").sensors == data.sensors
    assert [(s.name, s.type, s.object) for s in data.sensors] == [("M001", "motion", ""), ("I001", "contact", "i001"),
                                                                  ("T001", "temperature", "")]
    train = data.of("train/2010-11-04")
    assert train is not None and train.start.tolist() == [21600.0, 25320.25]
    home = load_household(tmp_path, "home")
    checked = check_sensor_data(home)
    assert checked is not None and set(checked.days) == {"2010-11-04", "2010-11-05"}
    assert (folder / "events").is_dir() and sorted(p.name for p in (folder / "events").iterdir()) == [
        "2010-11-04.csv", "2010-11-05.csv"]


def test_an_events_file_without_its_day_file_is_an_error(tmp_path):
    folder = _imported(tmp_path)
    stray = folder / "events" / "2010-11-06.csv"
    stray.write_text("sensor,start,end\nM001,1800,1800\n", encoding="utf-8")
    with pytest.raises(DataError, match="no day file train/2010-11-06.csv or test/2010-11-06.csv") as info:
        load_sensor_data(tmp_path, "home")
    assert info.value.source == str(stray)
    with pytest.raises(DataError, match="no day file"):
        check_sensor_data(load_household(tmp_path, "home"))


def test_an_activation_outside_its_days_span_is_an_error(tmp_path):
    folder = _imported(tmp_path)
    events = folder / "events" / "2010-11-05.csv"
    # the day's rows cover 06:00 (21600 s) to its 24:00 row's end, 00:10 (87000 s)
    events.write_text("sensor,start,end\nM001,25200,25205\nM001,86990,87000.5\n", encoding="utf-8")
    span = r"87000.5 seconds after midnight is outside the day's span 21600..87000"
    with pytest.raises(DataError, match=span) as info:
        check_sensor_data(load_household(tmp_path, "home"))
    assert (info.value.source, info.value.line, info.value.field) == (str(events), 3, "end")
    events.write_text("sensor,start,end\nM001,21599,21600\n", encoding="utf-8")
    with pytest.raises(DataError, match="outside the day's span") as info:
        check_sensor_data(load_household(tmp_path, "home"))
    assert (info.value.line, info.value.field) == (2, "start")


def test_an_object_the_household_does_not_have_is_an_error(tmp_path):
    folder = _imported(tmp_path)
    listing = folder / "sensors.csv"
    listing.write_text(listing.read_text(encoding="utf-8").replace("i001", "kettle"), encoding="utf-8")
    with pytest.raises(DataError, match="object 'kettle' is not an object column") as info:
        check_sensor_data(load_household(tmp_path, "home"))
    assert (info.value.source, info.value.line, info.value.field) == (str(listing), 3, "object")


def test_a_household_without_sensors_loads_none(tmp_path):
    folder = _imported(tmp_path)
    (folder / "sensors.csv").unlink()
    for path in (folder / "events").iterdir():
        path.unlink()
    (folder / "events").rmdir()
    assert load_sensor_data(tmp_path, "home") is None and check_sensor_data(load_household(tmp_path, "home")) is None


def _validate(root):
    return subprocess.run([sys.executable, "-m", "globe", "data", "validate", "--data", str(root), "--households",
                           "home"], capture_output=True, text=True, timeout=300)


def test_globe_data_validate_checks_the_sensors(tmp_path):
    folder = _imported(tmp_path)
    res = _validate(tmp_path)
    assert res.returncode == 0, res.stderr
    assert "sensors" in res.stdout and "all files valid" in res.stdout
    events = folder / "events" / "2010-11-04.csv"
    events.write_text("sensor,start,end\nM001,abc,21700\n", encoding="utf-8")
    res = _validate(tmp_path)
    assert res.returncode == 1 and "2010-11-04.csv:2: column 'start'" in res.stderr.replace("\n", "")
