"""``globe data import``'s options shared by every format, through the command line: the use
mode, the limit of a use, the split by date, --until and --skip-bad-lines, and what the summary
says about them."""

import datetime as dt
import json
import re

import pytest
from typer.testing import CliRunner

from globe.cli.main import app
from globe.data.csv_logs import load_household
from globe.errors import DataError

STUCK_DAY, BACK_DAY = 3, 10


def _casas_log(days: int = 14) -> str:
    """``days`` days of Work 09:01-17:01, a pot (I001) taken 07:00-07:04 and a kettle (I002) taken
    08:00-08:03 each day; on day STUCK_DAY the kettle's sensor sticks on until 08:03 on day BACK_DAY."""
    lines = []
    for d in range(days):
        def stamp(h: int, m: int, d: int = d) -> str:
            return f"{dt.datetime(2010, 11, 1 + d, h, m):%Y-%m-%d %H:%M:%S}.000000"

        lines += [f"{stamp(7, 0)} I001 ABSENT", f"{stamp(7, 4)} I001 PRESENT",
                  f"{stamp(9, 1)} M002 ON Work begin", f"{stamp(17, 1)} M002 OFF Work end"]
        if not STUCK_DAY < d <= BACK_DAY:
            lines.append(f"{stamp(8, 0)} I002 ABSENT")
        if not STUCK_DAY <= d < BACK_DAY:
            lines.append(f"{stamp(8, 3)} I002 PRESENT")
    return "\n".join(sorted(lines)) + "\n"


def _run(*args):
    return CliRunner().invoke(app, ["data", "import", *map(str, args)])


def _used(day, k):
    return [m for m, row in zip(day.minutes, day.locations) if row[k].startswith("in_use#")]


def test_a_sensor_stuck_on_for_a_week_is_cut_and_the_summary_counts_it(tmp_path):
    log = tmp_path / "casas.txt"
    log.write_text(_casas_log(), encoding="utf-8")
    res = _run("casas", log, tmp_path / "home")
    assert res.exit_code == 0, res.output
    assert "cut 1 use far longer than its object's usual to its start (a sensor left on?)" in res.output
    home = load_household(tmp_path, "home")
    days = home.train + home.test
    assert len(days) == 12  # the first and last days are partial (the log runs 07:00 .. 17:01)
    for day in days:
        d = (dt.date.fromisoformat(day.name.split("/")[1]) - dt.date(2010, 11, 1)).days
        assert _used(day, 0) == [420]  # the pot, untouched
        assert _used(day, 1) == ([] if STUCK_DAY < d <= BACK_DAY else [480]), day.name  # not a week in use
    report = json.loads((tmp_path / "home" / "import.json").read_text(encoding="utf-8"))
    [stuck] = report["left_on"]
    assert (stuck["object"], stuck["sensor"], stuck["start"], stuck["end"]) == (
        "i002", "I002", "2010-11-04 08:00:00", "2010-11-11 08:03:00")
    assert stuck["minutes"] == 7 * 1440 + 3 and stuck["limit_minutes"] == 60.0


def test_the_shared_options_on_the_command_line(tmp_path):
    """--use start, --test-from, --until and --skip-bad-lines together, on a log with one bad line."""
    log = tmp_path / "casas.txt"
    lines = _casas_log().splitlines()
    log.write_text("\n".join(lines[:5] + ["2010-11-02 07:30:00.000000 I001 OFcF"] + lines[5:]) + "\n",
                   encoding="utf-8")
    res = _run("casas", log, tmp_path / "home", "--use", "start", "--test-from", "2010-11-08", "--until",
               "2010-11-09", "--skip-bad-lines", "--max-use-minutes", "2")
    assert res.exit_code == 0, res.output
    assert f"left out 1 bad line (--skip-bad-lines), the first: {log}:6: column 'value'" in res.output
    home = load_household(tmp_path, "home")
    assert [d.name for d in home.test] == ["test/2010-11-08", "test/2010-11-09"]
    assert home.train[0].name == "train/2010-11-02"  # the first day starts after 06:00: partial
    assert all(_used(day, 1) in ([], [480]) for day in home.train + home.test)
    report = json.loads((tmp_path / "home" / "import.json").read_text(encoding="utf-8"))
    assert report["grid"]["use"] == "start" and report["grid"]["test_from"] == "2010-11-08"
    assert "2 minutes (--max-use-minutes)" in report["grid"]["left_on_rule"]
    assert len(report["left_on"]) == 14 + 7  # every use: the pot's 14 (4 minutes), the kettle's 7 (3, and a week)
    assert [(b["line"], b["field"]) for b in report["bad_lines"]] == [(6, "value")]
    assert {d["why"] for d in report["dropped_days"] if d["date"] > "2010-11-09"} == {"after --until 2010-11-09"}


@pytest.mark.parametrize("args, message", [
    (["--use", "sometimes"], "'sometimes' is not 'while-on' or 'start'"),
    (["--test-from", "2010-13-01"], "'2010-13-01' is not a date YYYY-MM-DD"),
    (["--until", "1.11.2010"], "is not a date YYYY-MM-DD"),
    (["--test-from", "2010-11-08", "--test-days", "2"], "give --test-from, --test-days or --test-fraction"),
    (["--test-from", "2010-11-08", "--test-fraction", "0.5"], "give --test-from, --test-days or --test-fraction"),
    (["--max-use-minutes", "0"], "is not more than 0"),
])
def test_bad_options_are_usage_errors(tmp_path, args, message):
    log = tmp_path / "casas.txt"
    log.write_text(_casas_log(3), encoding="utf-8")
    res = _run("casas", log, tmp_path / "home", *args)
    assert res.exit_code == 2 and message in " ".join(re.sub("[│╭╮╰╯─]", " ", res.output).split()), res.output
    assert not (tmp_path / "home").exists()


def test_kasteren_and_home_assistant_take_the_shared_options(tmp_path):
    from tests.data.importers.test_home_assistant import HISTORY, MAPPING
    from tests.data.importers.test_kasteren import KASTEREN_ACT, KASTEREN_SENSE

    (tmp_path / "sense.txt").write_text(KASTEREN_SENSE + "25-Feb-2008 07:00:00\n", encoding="utf-8")
    (tmp_path / "act.txt").write_text(KASTEREN_ACT, encoding="utf-8")
    res = _run("kasteren", tmp_path / "sense.txt", tmp_path / "act.txt", tmp_path / "k")
    assert isinstance(res.exception, DataError) and res.exception.line == 6  # the bad line stops it
    res = _run("kasteren", tmp_path / "sense.txt", tmp_path / "act.txt", tmp_path / "k", "--skip-bad-lines")
    assert isinstance(res.exception, DataError) and "--allow-numeric-labels" in res.exception.message
    res = _run("kasteren", tmp_path / "sense.txt", tmp_path / "act.txt", tmp_path / "k", "--skip-bad-lines",
               "--allow-numeric-labels", "--use", "start")
    assert res.exit_code == 0 and "left out 1 bad line" in res.output, res.output
    (tmp_path / "history.csv").write_text(HISTORY + "switch.kettle,on,yesterday\n", encoding="utf-8")
    (tmp_path / "map.csv").write_text(MAPPING, encoding="utf-8")
    res = _run("home-assistant", tmp_path / "history.csv", tmp_path / "ha", "--activity-entity",
               "input_select.activity", "--objects", tmp_path / "map.csv", "--timezone", "Europe/Amsterdam",
               "--skip-bad-lines", "--until", "2024-03-01", "--use", "start")
    assert res.exit_code == 0 and "left out 1 bad line" in res.output, res.output
    report = json.loads((tmp_path / "ha" / "import.json").read_text(encoding="utf-8"))
    assert report["grid"]["use"] == "start" and report["bad_lines"][0]["line"] == HISTORY.count("\n") + 1
