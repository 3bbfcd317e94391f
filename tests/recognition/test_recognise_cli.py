"""``globe recognise`` as a user runs it: a household folder with sensors in, tables and a plot out."""

from __future__ import annotations

import csv
import subprocess
import sys

from tests.simulated_sensors import sensor_home, write_home


def _folder(root, days=8, test=2):
    home, sensors = sensor_home(days=days, test=test, step=10, seed=3)
    write_home(root / "Sensors", home, sensors)
    return home


def test_recognise_writes_its_tables_and_plot(tmp_path):
    home = _folder(tmp_path / "data")
    run = subprocess.run([sys.executable, "-m", "globe", "recognise", "--data", str(tmp_path / "data"), "--out",
                          str(tmp_path / "out"), "--labelled-days", "1,all", "--questions", "0,1"],
                         capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert run.returncode == 0, run.stderr[-2000:]
    folder = tmp_path / "out" / "Sensors"
    rows = list(csv.DictReader((folder / "recognition.csv").open(encoding="utf-8")))
    ours = [r for r in rows if r["model"].startswith("globe")]
    assert [int(r["labelled_days"]) for r in ours] == [1, len(home.train)]
    assert all(0 <= float(r["class_accuracy"]) <= 1 for r in ours)
    asking = list(csv.DictReader((folder / "asking.csv").open(encoding="utf-8")))
    assert [int(r["questions_per_day"]) for r in asking] == [0, 1]
    assert (folder / "confusion.png").stat().st_size > 10_000
    assert "recognition on the test days" in run.stdout and "the learning curve" in run.stderr
    said = " ".join(run.stdout.split())  # as wrapped to the terminal's width
    assert "annotated vs recognised history: one-step F1" in said
    assert "predicted by the recogniser's filter from the sensors (its clock dynamics): one-step F1 0." in said


def test_recognise_refuses_a_bad_list_and_a_home_without_sensors(tmp_path):
    _folder(tmp_path / "data")
    bad = subprocess.run([sys.executable, "-m", "globe", "recognise", "--data", str(tmp_path / "data"),
                          "--labelled-days", "1,x"], capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert bad.returncode != 0 and "'x' is not a whole number" in bad.stderr
    (tmp_path / "data" / "Sensors" / "sensors.csv").unlink()
    for stale in (tmp_path / "data" / "Sensors" / "events").iterdir():
        stale.unlink()
    (tmp_path / "data" / "Sensors" / "events").rmdir()
    none = subprocess.run([sys.executable, "-m", "globe", "recognise", "--data", str(tmp_path / "data"), "--out",
                           str(tmp_path / "out")], capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert none.returncode != 0 and "no household with sensors" in none.stderr
