"""The rules every importer shares (days, steps, the split, the folder), on logs built in code."""

import json
from datetime import date, datetime, timedelta

import pytest

from globe.data.csv_logs import load_household
from globe.data.importers import grid
from globe.data.importers.grid import write_import
from globe.data.importers.objects import Choice, ObjectSelection, Sensor
from globe.data.importers.options import GridOptions
from globe.data.importers.sensor_log import Activation, Annotation, SensorLog
from globe.data.importers.uses import USE_RULES, use_limit
from globe.errors import ConfigError, DataError

START = datetime(2024, 1, 1)


def _log(days: int) -> tuple[SensorLog, ObjectSelection]:
    """``days`` annotated days: 'cooking' 07:00-07:30 each day and a cupboard opened at 07:05; the
    log runs from 00:00 on the first day to 00:30 after the last."""
    sensor_log = SensorLog("test", ("made-up",))
    selection = ObjectSelection(mapping=None, default=lambda s: (True, "test"), default_help="all")
    selection.choose(Sensor("c1", "cupboard", "", "kitchen"), source="made-up", line=1)
    for i in range(days):
        morning = START + timedelta(days=i, hours=7)
        sensor_log.annotations.append(Annotation("cooking", morning, morning + timedelta(minutes=30), "made-up", i + 1,
                                                 "cooking"))
        opened = morning + timedelta(minutes=5)
        sensor_log.activations.setdefault("c1", []).append(Activation(opened, opened))
        sensor_log.events["c1"] += 1
    sensor_log.saw(START)
    sensor_log.saw(START + timedelta(days=days, minutes=30))
    return sensor_log, selection


def _write(tmp_path, days, **options):
    sensor_log, selection = _log(days)
    return write_import(sensor_log=sensor_log, selection=selection, options=GridOptions(**options),
                        dest=tmp_path / "home")


@pytest.mark.parametrize("step", [1, 2, 5, 10])
def test_every_step_gives_a_grid_the_loader_reads_back_with_that_step(tmp_path, step):
    _write(tmp_path, 1, step_minutes=step)
    home = load_household(tmp_path, "home")  # the step is inferred from the rows, as for any household
    day = home.train[0]
    assert day.minutes == tuple(range(360, 1441, step)) and len(day) == 1080 // step + 1
    cooking = [m for m, a in zip(day.minutes, day.activities) if a == "cooking"]
    assert cooking == list(range(420, 450, step))  # [07:00, 07:30): starts 07:00 .. 07:30 - step
    used = [m for m, row in zip(day.minutes, day.locations) if row[0].startswith("in_use#")]
    assert used == [420 + (5 // step) * step]  # the step holding 07:05


def test_day_bounds_are_options(tmp_path):
    _write(tmp_path, 1, day_start_minute=7 * 60 + 15, day_end_minute=22 * 60, step_minutes=5)
    day = load_household(tmp_path, "home").train[0]
    assert day.minutes[0] == 435 and day.minutes[-1] == 1320 and len(day) == (1320 - 435) // 5 + 1
    assert day.activities[:4] == ("cooking", "cooking", "cooking", "idle")  # 07:15, 07:20, 07:25 of [07:00, 07:30)
    assert not any(row[0].startswith("in_use#") for row in day.locations)  # the cupboard's 07:05 is before the day


@pytest.mark.parametrize("days, options, test_days", [
    (1, {}, 0), (2, {}, 1), (4, {}, 1), (10, {}, 2), (11, {}, 2), (75, {}, 15),
    (10, {"test_fraction": 0.0}, 0), (10, {"test_days": 3}, 3), (10, {"test_days": 0}, 0),
])
def test_the_last_days_are_test_days(tmp_path, days, options, test_days):
    result = _write(tmp_path, days, **options)
    assert (result.train_days, result.test_days) == (days - test_days, test_days)
    home = load_household(tmp_path, "home")
    names = [d.name.split("/")[1] for d in home.train + home.test]
    assert names == [(START + timedelta(days=i)).date().isoformat() for i in range(days)]  # test days come last


@pytest.mark.parametrize("options, message", [
    ({"step_minutes": 7}, "does not divide the day"),
    ({"step_minutes": 0}, "does not divide the day"),
    ({"day_start_minute": 600, "day_end_minute": 600}, "must start before it ends"),
    ({"day_end_minute": 1450}, "must start before it ends"),
    ({"test_fraction": 1.0}, "test fraction"),
    ({"test_days": -1}, "0 or more"),
    ({"test_days": 2}, "would leave no training day"),
    ({"use": "sometimes"}, "use must be 'while-on' or 'start'"),
    ({"max_use_minutes": 0}, "more than 0 minutes"),
    ({"test_from": date(2024, 1, 1)}, "--test-from 2024-01-01 leaves no training day"),
    ({"test_from": date(2024, 1, 3)}, "--test-from 2024-01-03 leaves no test day"),
    ({"test_from": date(2024, 1, 2), "test_days": 1}, "not both"),
    ({"test_from": date(2024, 1, 2), "until": date(2024, 1, 1)}, "there would be no test day"),
])
def test_options_are_checked_when_the_import_starts(tmp_path, options, message):
    with pytest.raises(ConfigError, match=message):
        _write(tmp_path, 2, **options)
    assert not (tmp_path / "home").exists()


def test_the_destination_must_be_new_or_empty_and_a_failed_write_leaves_nothing(tmp_path, monkeypatch):
    (tmp_path / "home").mkdir()
    (tmp_path / "home" / "old.csv").write_text("x")
    with pytest.raises(DataError, match="not an empty folder"):
        _write(tmp_path, 2)
    (tmp_path / "home" / "old.csv").unlink()

    def broken(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(grid, "write_day", broken)
    with pytest.raises(DataError, match="cannot write the household folder: disk full") as err:
        _write(tmp_path, 2)
    assert err.value.source == str(tmp_path / "home")  # named as asked: once, the hidden draft folder's name
    assert sorted(p.name for p in tmp_path.iterdir()) == ["home"] and not any((tmp_path / "home").iterdir())


def test_days_outside_the_log_and_unannotated_days_are_dropped_and_listed(tmp_path):
    sensor_log, selection = _log(3)
    sensor_log.annotations.pop(1)  # the second day has no annotation left
    sensor_log.first = START + timedelta(hours=6, minutes=1)  # the log starts after the first day's 06:00
    result = write_import(sensor_log=sensor_log, selection=selection, options=GridOptions(), dest=tmp_path / "home")
    assert (result.train_days, result.test_days, result.dropped_days) == (1, 0, 3)
    report = json.loads(result.report.read_text(encoding="utf-8"))
    assert report["dropped_days"] == [
        {"date": "2024-01-01",
         "why": "partial: the log starts at 2024-01-01 06:01:00, after this day's first row (06:00)"},
        {"date": "2024-01-02", "why": "no annotation"},
        {"date": "2024-01-04",
         "why": "partial: the log ends at 2024-01-04 00:30:00, before this day's last row (24:00)"},
    ]


def test_a_day_that_only_carries_an_annotation_over_is_dropped(tmp_path):
    """Annotating stopped on the third evening: the fourth day has sleeping until 07:00 carried
    over from the night before and nothing that begins on it, so it is no day of the routine."""
    sensor_log, selection = _log(4)
    sensor_log.annotations.pop(3)
    night = START + timedelta(days=2, hours=22)
    sensor_log.annotations.append(Annotation("sleeping", night, night + timedelta(hours=9), "made-up", 9, "sleeping"))
    result = write_import(sensor_log=sensor_log, selection=selection, options=GridOptions(), dest=tmp_path / "home")
    report = json.loads(result.report.read_text(encoding="utf-8"))
    why = {d["date"]: d["why"] for d in report["dropped_days"]}
    assert why.keys() == {"2024-01-04", "2024-01-05"} and why["2024-01-05"].startswith("partial")
    assert why["2024-01-04"].startswith("no annotation begins on it")
    assert result.train_days + result.test_days == 3


def test_a_stretch_without_events_far_longer_than_usual_is_listed(tmp_path):
    """Events every 30 minutes, but none from 10:00 to 20:00 on the second day (10 hours) and none
    from 12:00 to 17:00 on the first (5 hours): the usual day's longest silence is 5 hours (the
    median), so only the 10 hours (past 1.5 times that) are listed."""
    sensor_log, selection = _log(3)
    quiet = {0: (12 * 60, 17 * 60), 1: (10 * 60, 20 * 60)}
    for day in range(3):
        for half_hours in range(48):
            lo, hi = quiet.get(day, (0, 0))
            if not lo < 30 * half_hours < hi:
                sensor_log.heard(START + timedelta(days=day, minutes=30 * half_hours))
    result = write_import(sensor_log=sensor_log, selection=selection, options=GridOptions(), dest=tmp_path / "home")
    report = json.loads(result.report.read_text(encoding="utf-8"))
    assert report["silent_stretches"] == [{"date": "2024-01-02", "from": "2024-01-02 10:00:00",
                                           "to": "2024-01-02 20:00:00"}]
    assert any(n.startswith("1 kept day has a stretch of 7.5 hours or more") for n in result.notes)


def test_silent_days_are_listed_even_when_most_days_are_silent(tmp_path):
    """Events on 3 of 10 annotated days only (a recorder that ran for 3 days): the usual silence is
    judged on the days a sensor was heard at all, so the 7 silent days are listed (judged on every
    day, the median day was silent and nothing could ever be)."""
    sensor_log, selection = _log(10)
    for day in (0, 4, 8):
        for half_hours in range(48):
            sensor_log.heard(START + timedelta(days=day, minutes=30 * half_hours))
    result = write_import(sensor_log=sensor_log, selection=selection, options=GridOptions(), dest=tmp_path / "home")
    report = json.loads(result.report.read_text(encoding="utf-8"))
    kept = report["days"]["train"] + report["days"]["test"]
    assert {s["date"] for s in report["silent_stretches"]} == set(kept) - {"2024-01-01", "2024-01-05", "2024-01-09"}


def test_a_day_one_annotation_covers_whole_is_kept(tmp_path):
    """Away from the first evening to the third morning: the second day has no annotation of its
    own, but one covers it to its last row (a day away), so it is a day of the routine."""
    sensor_log, selection = _log(3)
    sensor_log.annotations.pop(1)
    evening = START + timedelta(hours=20)
    sensor_log.annotations.append(Annotation("away", evening, evening + timedelta(hours=34), "made-up", 9, "away"))
    result = write_import(sensor_log=sensor_log, selection=selection, options=GridOptions(overlaps="latest"),
                          dest=tmp_path / "home")
    assert "2024-01-02" in json.loads(result.report.read_text(encoding="utf-8"))["days"]["train"]


def test_a_sensor_on_for_hours_is_no_silence(tmp_path):
    sensor_log, selection = _log(3)
    for day in range(3):
        for half_hours in range(48):
            if day != 1 or not 20 < half_hours < 40:
                sensor_log.heard(START + timedelta(days=day, minutes=30 * half_hours))
    day2 = START + timedelta(days=1)
    sensor_log.heard(day2 + timedelta(hours=10), day2 + timedelta(hours=20))  # a pressure mat, on all along
    result = write_import(sensor_log=sensor_log, selection=selection, options=GridOptions(), dest=tmp_path / "home")
    assert json.loads(result.report.read_text(encoding="utf-8"))["silent_stretches"] == []


def test_an_import_killed_before_it_cleaned_up_leaves_nothing_behind_the_next(tmp_path):
    """A killed import's hidden folder was removed only by an import that got the same process id;
    now the next import removes every one whose process is gone (one still running is left)."""
    import os
    import subprocess
    import sys

    gone = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    dead = tmp_path / f".home.importing-{gone.stdout.strip()}"
    (dead / "train").mkdir(parents=True)
    alive = tmp_path / f".home.importing-{os.getppid()}"  # a process that runs: an import under way
    alive.mkdir()
    _write(tmp_path, 2)
    assert not dead.exists() and alive.exists() and (tmp_path / "home" / "nodes.csv").is_file()


def _clock(day: int, hhmm: str) -> datetime:
    hours, minutes = hhmm.split(":")
    return START + timedelta(days=day, hours=int(hours), minutes=int(minutes))


def _in_use(day) -> list[int]:
    return [m for m, row in zip(day.minutes, day.locations) if row[0].startswith("in_use#")]


def _departures(day) -> int:
    """Moves into the in_use place: what the evaluation counts as uses."""
    places = [row[0] for row in day.locations]
    return sum(a.startswith("in_use#") and not b.startswith("in_use#") for b, a in zip(places, places[1:]))


@pytest.mark.parametrize("use, steps", [
    ("while-on", [420, 430, 440, 540, 550, 660, 670]),
    ("start", [420, 540, 660, 670]),
])
def test_a_use_is_in_use_while_on_or_at_its_start_only(tmp_path, use, steps):
    """On 07:05-07:25; on 09:02-09:12 and again 09:12-09:14 (never off between: one use); a firing
    at 11:00 and a use 11:10-11:11. Four uses; the last two begin in consecutive steps, which the
    grid can only show as one stay in use, so either mode makes three departures."""
    sensor_log, selection = _log(1)
    spans = [("07:05", "07:25"), ("09:02", "09:12"), ("09:12", "09:14"), ("11:00", "11:00"), ("11:10", "11:11")]
    sensor_log.activations["c1"] = [Activation(_clock(0, a), _clock(0, b)) for a, b in spans]
    result = write_import(sensor_log=sensor_log, selection=selection, options=GridOptions(use=use),
                          dest=tmp_path / "home")
    day = load_household(tmp_path, "home").train[0]
    assert _in_use(day) == steps and _departures(day) == 3
    report = json.loads(result.report.read_text(encoding="utf-8"))
    assert report["grid"]["use"] == use and report["grid"]["use_rule"] == USE_RULES[use]
    assert report["objects"][0]["uses"] == 4 and report["objects"][0]["rows_in_use"] == len(steps)


@pytest.mark.parametrize("durations, options, minutes", [
    ([60.0] * 200 + [7 * 86400.0], {}, 60),  # the 99th percentile (1 minute) x 3 is under the floor
    ([60.0] * 100 + [1e6], {}, 60),  # from 101 on, one stuck activation never sets its own limit
    ([60.0] * 99 + [1e6], {}, 60),  # 100: the median's rule (1 minute x 10), under the floor
    ([7200.0] * 150, {}, 360),  # usual uses of two hours: 3 x 2 hours
    ([7200.0] * 4 + [7 * 86400.0], {}, 1200),  # a few: 10 x the median, 20 hours
    ([60.0, 7 * 86400.0], {}, 1440),  # two: nothing usual to judge by, a day
    ([], {}, 1440),
    ([60.0] * 200, {"max_use_minutes": 30}, 30),
    ([60.0] * 200, {"step_minutes": 60}, 120),  # two steps at least
])
def test_the_limit_of_a_use_follows_the_objects_usual_uses(durations, options, minutes):
    assert use_limit(durations, GridOptions(**options)) == pytest.approx(minutes * 60)


def test_a_sensor_stuck_on_for_seven_days_is_cut_to_a_firing_and_listed(tmp_path):
    """A kettle used 07:05-07:09 each day is switched on on the third morning and left on for 7
    days: it is in use in that morning's 07:00 step only, not for a week; its other uses and the
    cupboard's stay as they were, and the report lists the stuck one with its limit."""
    sensor_log, selection = _log(12)
    selection.choose(Sensor("k1", "kettle", "", "kitchen"), source="made-up", line=1)
    stuck = Activation(_clock(2, "07:05"), _clock(9, "07:05"))
    sensor_log.activations["k1"] = [Activation(_clock(d, "07:05"), _clock(d, "07:09")) for d in (0, 1, 9, 10, 11)]
    sensor_log.activations["k1"].insert(2, stuck)
    sensor_log.events["k1"] += 6
    result = write_import(sensor_log=sensor_log, selection=selection, options=GridOptions(test_days=0),
                          dest=tmp_path / "home")
    home = load_household(tmp_path, "home")
    assert home.objects == ("cupboard", "kettle")
    for i, day in enumerate(home.train):
        cupboard = [m for m, row in zip(day.minutes, day.locations) if row[0].startswith("in_use#")]
        kettle = [m for m, row in zip(day.minutes, day.locations) if row[1].startswith("in_use#")]
        assert cupboard == [420]
        assert kettle == ([] if 3 <= i <= 8 else [420]), day.name
    report = json.loads(result.report.read_text(encoding="utf-8"))
    assert report["left_on"] == [{"object": "kettle", "sensor": "k1", "start": "2024-01-03 07:05:00",
                                  "end": "2024-01-10 07:05:00", "minutes": 10080.0, "limit_minutes": 60.0}]
    kettle = report["objects"][1]
    assert (kettle["left_on"], kettle["use_limit_minutes"], kettle["uses"]) == (1, 60.0, 6)
    assert report["objects"][0]["left_on"] == 0 and result.left_on == 1


def test_test_from_makes_the_days_from_a_date_on_test_days_and_until_drops_later_ones(tmp_path):
    result = _write(tmp_path / "a", 10, test_from=date(2024, 1, 8))
    assert (result.train_days, result.test_days) == (7, 3)
    home = load_household(tmp_path / "a", "home")
    assert [d.name for d in home.test] == ["test/2024-01-08", "test/2024-01-09", "test/2024-01-10"]
    result = _write(tmp_path / "b", 10, until=date(2024, 1, 6))
    assert (result.train_days, result.test_days) == (5, 1)  # six days kept: the 20 %, at least one
    report = json.loads(result.report.read_text(encoding="utf-8"))
    assert report["days"]["test"] == ["2024-01-06"] and report["grid"]["until"] == "2024-01-06"
    assert report["dropped_days"] == [{"date": f"2024-01-{d:02d}", "why": "after --until 2024-01-06"}
                                      for d in range(7, 12)]
    result = _write(tmp_path / "c", 10, until=date(2024, 1, 6), test_from=date(2024, 1, 5))
    assert (result.train_days, result.test_days) == (4, 2)
    with pytest.raises(DataError, match="no day to import.*: 6 after --until 2023-12-31"):
        _write(tmp_path / "d", 5, until=date(2023, 12, 31))


def test_a_log_without_sensors_writes_no_sensor_files(tmp_path):
    _write(tmp_path, 2)
    folder = tmp_path / "home"
    assert not (folder / "sensors.csv").exists() and not (folder / "events").exists()
    report = json.loads((folder / "import.json").read_text(encoding="utf-8"))
    assert report["sensors"]["count"] == 0 and report["sensors"]["activations"] == 0


def test_every_sensor_is_written_per_kept_day_and_cut_by_the_left_on_rule(tmp_path):
    sensor_log, selection = _log(3)
    selection.choices["m1"] = Choice(None, "", "", "a motion sensor: no object")
    sensor_log.sensor("c1", "contact", "kitchen")
    sensor_log.sensor("m1", "motion", "hall")
    for i in range(3):
        opened = START + timedelta(days=i, hours=7, minutes=5)
        sensor_log.sensor_on("c1", opened, opened + timedelta(minutes=90))  # longer than --max-use-minutes 60
        sensor_log.sensor_on("m1", opened, opened + timedelta(seconds=30.5))
    sensor_log.sensor_on("m1", START + timedelta(days=1, hours=23), START + timedelta(days=2, hours=1))  # over 60
    write_import(sensor_log=sensor_log, selection=selection, options=GridOptions(max_use_minutes=60, test_days=1),
                 dest=tmp_path / "home")
    folder = tmp_path / "home"
    assert (folder / "sensors.csv").read_text(encoding="utf-8") == (
        "sensor,type,room,object\nc1,contact,kitchen,cupboard\nm1,motion,hall,\n")
    assert sorted(p.name for p in (folder / "events").iterdir()) == ["2024-01-01.csv", "2024-01-02.csv",
                                                                     "2024-01-03.csv"]
    # the object's 90 minutes are cut to a firing (as its use is); m1's two hours from 23:00 too
    assert (folder / "events" / "2024-01-02.csv").read_text(encoding="utf-8") == (
        "sensor,start,end\nc1,25500,25500\nm1,25500,25530.5\nm1,82800,82800\n")
    report = json.loads((folder / "import.json").read_text(encoding="utf-8"))["sensors"]
    assert report["types"] == {"contact": 1, "motion": 1} and report["rooms"] == {"hall": 1, "kitchen": 1}
    assert [(r["sensor"], r["minutes"]) for r in report["left_on"]] == [("m1", 120.0)]
