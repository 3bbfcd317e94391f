"""Days the sensors recorded and nobody annotated, in each format's small log written here: kept in
``unlabelled/`` (or dropped), listed in the report, checked by the validator and read back."""

import json
import subprocess
import sys

import pytest

from globe.data.csv_logs import load_household
from globe.data.importers import GridOptions, import_casas, import_home_assistant, import_kasteren
from globe.data.sensors import check_sensor_data, load_sensor_data, read_unlabelled_days
from globe.errors import ConfigError, DataError

# 11-04 annotated, 11-05 only sensors (a motion at 09:00, the item I001 taken at 12:00), 11-06
# annotated, 11-07 partial (the log ends at 00:00, before its last row).
CASAS = """\
2010-11-04 05:50:00.000000 M001 ON Sleeping begin
2010-11-04 07:00:00.000000 M001 OFF Sleeping end
2010-11-04 08:00:00.000000 I001 ABSENT
2010-11-04 08:05:00.000000 I001 PRESENT
2010-11-05 09:00:00.000000 M002 ON
2010-11-05 09:01:30.000000 M002 OFF
2010-11-05 12:00:00.000000 I001 ABSENT
2010-11-05 12:02:00.000000 I001 PRESENT
2010-11-06 07:00:00.000000 M001 ON Relax begin
2010-11-06 09:00:00.000000 M001 OFF Relax end
2010-11-07 00:00:00.000000 M001 ON
"""
# Ordóñez form: 11-29 has the fridge opened at 08:00 and no activity.
ORDONEZ_SENSORS = """\
Start time          End time            Location  Type      Place
----------          --------            --------  ----      -----
2011-11-28 05:40:00\t\t2011-11-28 06:18:11\t\tBed\t\tPressure\tBedroom
2011-11-28 06:21:00\t\t2011-11-28 06:21:30\t\tCupboard\tMagnetic\tKitchen
2011-11-29 08:00:00\t\t2011-11-29 08:09:59\t\tFridge\t\tMagnetic\tKitchen
2011-11-30 07:00:00\t\t2011-11-30 07:00:10\t\tBasin\t\tPIR\t\tBathroom
2011-12-01 00:29:00\t\t2011-12-01 00:30:00\t\tBed\t\tPressure\tBedroom
"""
ORDONEZ_ADLS = """\
Start time          End time            Activity
----------          --------            --------
2011-11-28 05:40:00\t\t2011-11-28 06:18:00\t\tSleeping
2011-11-30 06:50:00\t\t2011-11-30 07:05:00\t\tGrooming
"""
# Home Assistant on the home's clock: the activity entity unavailable from 1 March 23:00 to 3 March
# 05:30, so 2 March (a motion at 10:00, the fridge at 12:00) has no annotation.
HISTORY = """\
entity_id,state,last_changed
input_select.activity,sleeping,2024-03-01T05:00:00
input_select.activity,relax,2024-03-01T08:00:00
input_select.activity,unavailable,2024-03-01T23:00:00
input_select.activity,sleeping,2024-03-03T05:30:00
binary_sensor.hallway_motion,on,2024-03-01T05:10:00
binary_sensor.hallway_motion,off,2024-03-01T05:11:00
binary_sensor.hallway_motion,on,2024-03-02T10:00:00
binary_sensor.hallway_motion,off,2024-03-02T10:01:00
binary_sensor.fridge_door,on,2024-03-02T12:00:00
binary_sensor.fridge_door,off,2024-03-02T12:00:30
binary_sensor.hallway_motion,on,2024-03-04T00:20:00
"""


def _write(tmp_path, **texts):
    for name, text in texts.items():
        (tmp_path / name).write_text(text, encoding="utf-8")
    return {name: tmp_path / name for name in texts}


def _casas(tmp_path, **kwargs):
    files = _write(tmp_path, **{"log.txt": CASAS})
    return import_casas(log_file=files["log.txt"], dest=tmp_path / "home", **kwargs)


def _kasteren(tmp_path):
    files = _write(tmp_path, **{"sensors.txt": ORDONEZ_SENSORS, "adls.txt": ORDONEZ_ADLS})
    return import_kasteren(sensors_file=files["sensors.txt"], activities_file=files["adls.txt"], dest=tmp_path / "home")


def _home_assistant(tmp_path):
    files = _write(tmp_path, **{"history.csv": HISTORY,
                                "map.csv": "sensor,object,room\nbinary_sensor.fridge_door,fridge,kitchen\n"})
    return import_home_assistant(history=files["history.csv"], dest=tmp_path / "home",
                                 activity_entity="input_select.activity", objects=files["map.csv"])


@pytest.mark.parametrize("run, unlabelled, labelled, in_use", [
    (_casas, "2010-11-05", ["2010-11-04", "2010-11-06"], ("i001", 720)),
    (_kasteren, "2011-11-29", ["2011-11-28", "2011-11-30"], ("fridge", 480)),
    (_home_assistant, "2024-03-02", ["2024-03-01", "2024-03-03"], ("fridge", 720)),
])
def test_each_format_keeps_the_unannotated_day_apart_and_reads_it_back(tmp_path, run, unlabelled, labelled, in_use):
    result = run(tmp_path)
    home = load_household(tmp_path, "home")
    assert [d.name.split("/")[1] for d in home.train + home.test] == labelled  # no training or test day
    assert result.unlabelled_days == 1 and not (tmp_path / "home" / "train" / f"{unlabelled}.csv").exists()
    report = json.loads((tmp_path / "home" / "import.json").read_text(encoding="utf-8"))
    assert report["unlabelled_days"] == [unlabelled] and report["grid"]["unlabelled"] == "keep"
    assert unlabelled not in {d["date"] for d in report["dropped_days"]}
    text = (tmp_path / "home" / "unlabelled" / f"{unlabelled}.csv").read_text(encoding="utf-8")
    assert text.splitlines()[0] == "minute," + ",".join(home.objects)  # no activity column
    days = read_unlabelled_days(home)
    assert [d.name for d in days] == [f"unlabelled/{unlabelled}"] and set(days[0].activities) == {""}
    obj, minute = in_use
    in_use_places = {n.node for n in home.nodes if n.cls == "in_use"}
    used = [m for m, row in zip(days[0].minutes, days[0].locations) if row[home.objects.index(obj)] in in_use_places]
    assert used == [minute]
    sensors = check_sensor_data(home)  # its events lie in its span
    assert sensors is not None and len(sensors.of(days[0].name) or ()) >= 1
    assert load_sensor_data(tmp_path, "home") is not None  # an events file of an unlabelled day has its day


def test_drop_leaves_the_day_out_as_before(tmp_path):
    result = _casas(tmp_path, options=GridOptions(unlabelled="drop"))
    assert result.unlabelled_days == 0 and not (tmp_path / "home" / "unlabelled").exists()
    assert not (tmp_path / "home" / "events" / "2010-11-05.csv").exists()
    report = json.loads((tmp_path / "home" / "import.json").read_text(encoding="utf-8"))
    assert {d["date"]: d["why"] for d in report["dropped_days"]}["2010-11-05"] == "no annotation"
    assert report["unlabelled_days"] == []
    with pytest.raises(ConfigError, match="unlabelled must be 'keep' or 'drop'"):
        GridOptions(unlabelled="maybe").check()  # type: ignore[arg-type]


def test_a_log_with_no_annotated_day_says_it_has_unlabelled_ones(tmp_path):
    log = "\n".join(line.split(" Sleeping")[0].split(" Relax")[0] for line in CASAS.splitlines()) + "\n"
    _write(tmp_path, **{"log.txt": log})
    with pytest.raises(DataError, match="3 with sensor records and no annotation"):
        import_casas(log_file=tmp_path / "log.txt", dest=tmp_path / "home")


def test_the_validator_checks_the_unlabelled_days(tmp_path):
    _casas(tmp_path)
    home = load_household(tmp_path, "home")
    path = tmp_path / "home" / "unlabelled" / "2010-11-05.csv"
    good = path.read_text(encoding="utf-8")
    path.write_text(good.replace(",room#1", ",nowhere", 1), encoding="utf-8")
    with pytest.raises(DataError, match="unknown location") as info:
        check_sensor_data(home)
    assert info.value.source == str(path) and info.value.field == "i001"
    lines = good.splitlines()
    path.write_text("\n".join(["minute,activity," + lines[0].split(",", 1)[1]]
                              + [f"{r.split(',', 1)[0]},idle,{r.split(',', 1)[1]}" for r in lines[1:]]) + "\n",
                    encoding="utf-8")
    with pytest.raises(DataError, match="an unlabelled day has no activity column"):
        read_unlabelled_days(home)
    path.write_text(good, encoding="utf-8")
    (tmp_path / "home" / "unlabelled" / "2010-11-04.csv").write_text(good, encoding="utf-8")
    with pytest.raises(DataError, match="also a labelled day"):
        read_unlabelled_days(home)


def test_the_command_line_keeps_drops_and_validates(tmp_path):
    _write(tmp_path, **{"log.txt": CASAS})

    def globe(*args):
        return subprocess.run([sys.executable, "-m", "globe", *args], capture_output=True, text=True, timeout=300,
                              cwd=tmp_path)
    kept = globe("data", "import", "casas", "log.txt", "homes/Kept")
    assert kept.returncode == 0, kept.stderr[-2000:]
    assert "kept 1 day with sensor records and no annotation" in kept.stdout
    dropped = globe("data", "import", "casas", "log.txt", "homes/Dropped", "--unlabelled", "drop")
    assert dropped.returncode == 0 and "no annotation" not in dropped.stdout.split("left out")[0]
    assert not (tmp_path / "homes" / "Dropped" / "unlabelled").exists()
    bad = globe("data", "import", "casas", "log.txt", "homes/Bad", "--unlabelled", "some")
    assert bad.returncode != 0 and "is not 'keep' or 'drop'" in bad.stderr
    valid = globe("data", "validate", "--data", "homes", "--households", "Kept")
    assert valid.returncode == 0 and "unlabelled" in valid.stdout and "all files valid" in valid.stdout
