"""The command line as a user runs it: a real subprocess, exit codes and visible lines."""

import csv
import json
import subprocess
import sys

import pytest


def globe(*args, env=None):
    return subprocess.run([sys.executable, "-m", "globe", *args], capture_output=True, text=True, env=env, timeout=600)


def test_version():
    res = globe("--version")
    assert res.returncode == 0 and res.stdout.startswith("globe ")


def test_evaluate_writes_a_results_folder(tmp_path):
    (tmp_path / "next_activity.csv").write_text("stale\n")  # from an earlier run into the same folder
    res = globe("evaluate", "--households", "B", "--methods", "persistence,ngram", "--no-objects-ahead",
                "--no-activity-ahead", "--out", str(tmp_path))
    assert res.returncode == 0, res.stderr
    assert "Table I" in res.stdout and "n-gram Markov" in res.stdout and "(published)" in res.stdout
    assert "The activity ahead" not in res.stdout and not (tmp_path / "next_activity.csv").exists()  # not asked for
    for name in ("table1.csv", "table1.md", "timing.csv", "details.csv", "config.json", "table1.png"):
        assert (tmp_path / name).is_file(), name
    rows = list(csv.DictReader((tmp_path / "table1.csv").open()))
    assert {r["method"] for r in rows} == {"persistence", "ngram", "time_of_day", "hour_activity"}  # baselines always
    assert (tmp_path / "records" / "ngram_B_objects.csv").is_file()


def test_train_then_predict(tmp_path):
    assert globe("train", "--household", "A", "--model-dir", str(tmp_path), "--method", "ngram").returncode == 0
    res = globe("predict", "--model-dir", str(tmp_path), "--history", "wake_up,brushing_teeth")
    assert res.returncode == 0, res.stderr
    assert "next activity (06:20):" in res.stdout and "next object during" in res.stdout
    bad = globe("predict", "--model-dir", str(tmp_path), "--history", "wake_up,flying")
    assert bad.returncode == 1 and "unknown activity 'flying'" in bad.stderr
    dated = globe("predict", "--model-dir", str(tmp_path), "--history", "wake_up", "--date", "2024-01-06")
    assert dated.returncode == 0, dated.stderr
    no_date = globe("predict", "--model-dir", str(tmp_path), "--history", "wake_up", "--date", "2024-13-06")
    assert no_date.returncode == 1 and "--date: '2024-13-06' is not a date; expected YYYY-MM-DD" in no_date.stderr


def test_missing_data_folder_is_one_clean_line(tmp_path):
    res = globe("data", "validate", "--data", str(tmp_path / "nope"))
    assert res.returncode == 1
    assert "error:" in res.stderr and "data folder not found (from --data)" in res.stderr
    assert "Traceback" not in res.stderr


def test_bad_day_file_names_file_line_and_field(tmp_path, homer_root):
    import shutil

    home = tmp_path / "HouseholdZ"
    shutil.copytree(homer_root / "HouseholdA", home, ignore=shutil.ignore_patterns("0[1-6]*.csv"))
    path = home / "train" / "000.csv"
    lines = path.read_text().splitlines(keepends=True)
    lines[5] = lines[5].replace("dining_room#41", "garage#9", 1)
    path.write_text("".join(lines))
    res = globe("data", "validate", "--data", str(tmp_path), "--households", "Z")
    assert res.returncode == 1
    assert "000.csv:6: column 'knifeblock': unknown location 'garage#9'" in res.stderr.replace("\n", "")


def test_bad_config_value_is_reported(tmp_path):
    cfg = tmp_path / "globe.toml"
    cfg.write_text("[gate]\nthreshold = 1.5\n")
    res = globe("evaluate", "--config", str(cfg), "--households", "A", "--out", str(tmp_path / "r"))
    assert res.returncode == 1 and "gate.threshold" in res.stderr


@pytest.mark.parametrize("args", [["evaluate", "--methods", "magic", "--households", "A"]])
def test_unknown_method(args, tmp_path):
    res = globe(*args, "--out", str(tmp_path))
    assert res.returncode == 1 and "unknown method 'magic'" in res.stderr


def test_noise_command_writes_loadable_levels_and_a_summary(tmp_path):
    res = globe("noise", "--noise-dir", str(tmp_path), "--households", "C", "--types", "pet",
                "--levels", "0.5,1", "--backend", "none", "--seed", "3")
    assert res.returncode == 0, res.stderr
    assert "HOMER-Noise" in res.stdout and "pet" in res.stdout
    import json

    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["seed"] == 3 and summary["scorer"] == "uniform"
    assert summary["types"]["pet"]["per_level"]["0.5"] <= summary["types"]["pet"]["per_level"]["1"]
    check = globe("data", "validate", "--data", str(tmp_path / "pet" / "1"), "--households", "C")
    assert check.returncode == 0, check.stderr


@pytest.mark.parametrize("args, message", [
    (["train", "--model-dir", "m"], "usage error: Missing option '--household'. (see 'globe train --help')"),
    (["predict", "--model-dir", "m", "--top", "0"],
     "usage error: Invalid value for '--top': Input should be greater than or equal to 1 (see 'globe predict --help')"),
    (["evaluate", "--households"], "usage error: Option '--households' requires an argument."),
])
def test_usage_errors_are_one_line_with_exit_2(args, message, tmp_path):
    res = globe(*args)
    assert res.returncode == 2 and res.stderr.splitlines() == [message], res.stderr
    assert res.stdout == ""


def test_verbose_shows_the_traceback_of_a_usage_error():
    res = globe("-v", "train", "--bogus")
    assert res.returncode == 2 and "Traceback (most recent call last)" in res.stderr
    assert res.stderr.splitlines()[-1] == "usage error: No such option: --bogus (see 'globe train --help')"


def test_error_boundary_works_without_a_separate_click():
    """The core install: typer bundles its own click, so none may be importable."""
    code = ("import sys; sys.modules['click'] = None\n"
            "from globe.cli.main import main\n"
            "main(['train', '--household', 'A', '--model-dir', 'm', '--bogus'])")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert res.returncode == 2, res.stderr
    assert res.stderr.splitlines() == ["usage error: No such option: --bogus (see 'globe train --help')"]


def test_messages_are_plain_text(tmp_path):
    res = globe("data", "validate", "--data", str(tmp_path / "root:x:0 [bold]b[/bold]"))
    assert res.returncode == 1
    assert res.stderr.splitlines() == [
        f"error: {tmp_path}/root:x:0 [bold]b[/bold]: data folder not found (from --data); "
        "pass --data DIR or set GLOBE_DATA"]


def test_predict_checks_the_household_and_the_objects(tmp_path):
    assert globe("train", "--household", "B", "--model-dir", str(tmp_path), "--method", "ngram").returncode == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model.json"]
    wrong = globe("predict", "--model-dir", str(tmp_path), "--household", "A", "--history", "wake_up")
    assert wrong.returncode == 1
    assert wrong.stderr.strip() == f"error: {tmp_path}/model.json: trained for household 'HouseholdB', not 'HouseholdA'"
    unknown = globe("predict", "--model-dir", str(tmp_path), "--history", "wake_up", "--objects", "bowl,unicorn")
    assert unknown.returncode == 1
    assert unknown.stderr.startswith("error: --objects: unknown object 'unicorn'; known: book, bowl")
    assert len(unknown.stderr.splitlines()) == 1


@pytest.mark.parametrize("args, exit_code, message", [
    (["train", "--household", "", "--model-dir", "m"], 2,
     "usage error: Invalid value for '--household': names no household"),
    (["train", "--household", "A", "--model-dir", "m", "--config", "BINARY"], 1,
     "not a TOML text file (not UTF-8 at byte"),
    (["robot", "--url", "127.0.0.1:1", "--token", "t"], 1, "must start with http:// or https://"),
    (["robot", "--url", "http://127.0.0.1:1", "--token", "t", "--days", "1"], 1, "no answer from the service at "
                                                                              "http://127.0.0.1:1"),
    (["serve", "--db", "DB", "--host", "no-such-host.invalid", "--backend", "none"], 1,
     "--host 'no-such-host.invalid': cannot resolve it"),
])
def test_usage_mistakes_are_one_line_with_exit_1_or_2(args, exit_code, message, tmp_path):
    """Each ended as 'internal error' (exit 70) or a traceback."""
    (tmp_path / "BINARY").write_bytes(bytes(range(256)) * 4)
    args = [str(tmp_path / a) if a in ("BINARY", "DB") else a for a in args]
    res = globe(*args)
    assert res.returncode == exit_code and "Traceback" not in res.stderr, res.stderr
    assert len(res.stderr.strip().splitlines()) == 1 and message in res.stderr, res.stderr
    assert "GLOBE service on" not in res.stdout + res.stderr


def test_serve_on_a_port_in_use_and_on_every_interface(tmp_path):
    """A busy port is one line before anything is printed; listening beyond loopback warns in
    plain words (the markup was printed literally)."""
    import os
    import socket
    import time

    env = {**os.environ, "GLOBE_LLM__BACKEND": "none"}
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        res = globe("serve", "--db", str(tmp_path / "a.sqlite3"), "--port", str(busy.getsockname()[1]), env=env)
    assert res.returncode == 1 and "Traceback" not in res.stderr, res.stderr
    assert res.stderr.strip().splitlines() == [res.stderr.strip()] and "cannot listen on 127.0.0.1:" in res.stderr
    assert "GLOBE service on" not in res.stderr
    from tests.helpers import free_port

    proc = subprocess.Popen([sys.executable, "-m", "globe", "serve", "--db", str(tmp_path / "b.sqlite3"), "--host",
                             "0.0.0.0", "--port", str(free_port())], stderr=subprocess.PIPE, text=True, env=env)
    try:
        first = proc.stderr.readline()
        deadline = time.time() + 60
        while "warning" not in first and time.time() < deadline and proc.poll() is None:
            first = proc.stderr.readline()
    finally:
        proc.terminate()
        proc.wait(timeout=30)
    assert first.startswith("warning: listening on 0.0.0.0") and "[yellow]" not in first, first


@pytest.mark.parametrize("mqtt, message", [
    ('broker = "mqtt://127.0.0.1:99999"', "mqtt.broker: Value error, broker 'mqtt://127.0.0.1:99999': the port"),
    ('broker = "mqtts://127.0.0.1"\nca_file = "missing-ca.pem"', "ca_file missing-ca.pem: no such file"),
])
def test_serve_refuses_an_mqtt_section_it_cannot_start_with_in_one_line(tmp_path, mqtt, message):
    """Both were a 55-line traceback from inside the app's start-up, exit 3."""
    import os

    config = tmp_path / "globe.toml"
    config.write_text(f"[mqtt]\nenabled = true\n{mqtt}\n", encoding="utf-8")
    res = globe("serve", "--db", str(tmp_path / "a.sqlite3"), "--config", str(config),
                env={**os.environ, "GLOBE_LLM__BACKEND": "none"})
    assert res.returncode == 1 and "Traceback" not in res.stderr, res.stderr
    assert message in res.stderr and "GLOBE service on" not in res.stderr, res.stderr


def test_data_import_reports_bad_options_and_bad_lines_in_one_line(tmp_path):
    log = tmp_path / "casas.txt"
    log.write_text("2010-11-04 05:00:00 M001 ON Sleeping begin\n2010-11-04 04:00:00 M001 OFF\n", encoding="utf-8")
    res = globe("data", "import", "casas", str(log), str(tmp_path / "home"), "--day-start", "6")
    assert res.returncode == 2 and res.stderr.count("\n") == 1 and "'--day-start'" in res.stderr
    res = globe("data", "import", "casas", str(log), str(tmp_path / "home"), "--test-days", "1",
                "--test-fraction", "0.5")
    assert res.returncode == 2 and "not both" in res.stderr
    res = globe("data", "import", "casas", str(log), str(tmp_path / "home"), "--step", "7")
    assert res.returncode == 1 and "does not divide the day" in res.stderr
    res = globe("data", "import", "casas", str(log), str(tmp_path / "home"))
    assert res.returncode == 1 and res.stderr.startswith(f"error: {log}:2: column 'time': ")
    assert not (tmp_path / "home").exists()
    res = globe("data", "import", "casas", str(log), str(tmp_path / "home"), "--timezone", "Mars/Olympus")
    assert res.returncode == 1 and "unknown time zone 'Mars/Olympus'" in res.stderr
    res = globe("data", "import", "casas", str(log), str(tmp_path / "home"), "--resident", "R1",
                "--timezone", "America/Chicago")  # 05:00 -> 04:00 is no repeated hour: still out of order
    assert res.returncode == 1 and "column 'time'" in res.stderr and "--timezone" not in res.stderr


def test_tables_keep_full_method_names_in_a_file_or_a_pipe(monkeypatch, capsys):
    """rich squeezes a table into 80 columns when stdout is not a terminal; the main job's tables
    must keep every method name whole there (logs, CI, ``| less``)."""
    from globe.cli.common import print_table
    from globe.cli.evaluate_cmd import table1_table
    from globe.evaluation.methods import METHODS
    from globe.evaluation.published import DataScope

    labels = {m.name: m.label for m in METHODS.values()}
    rows = [{"method": m, "household": h, "average": "weighted", "activity_f1": 0.8, "object_f1": 0.6, "mean_f1": 0.7}
            for m in METHODS for h in ("A", "B", "C", "mean")]
    print_table(table1_table(rows, labels, DataScope("HOMER+", ("A", "B", "C"), True)))
    printed = capsys.readouterr().out
    assert "…" not in printed and "stot (published)" in printed
    for label in labels.values():
        assert label in printed, label
    assert max(len(line) for line in printed.splitlines()) > 80  # wider than rich's default for a pipe


def test_one_home_of_ones_own_is_summed_up_plainly(tmp_path, capsys):
    """One household that is not HOMER+: no "Table I/II" (the paper's names, kept for HOMER+), no
    "mean of households", and its scores once; HOMER+'s three households keep the paper's layout."""
    from globe.cli.common import print_table
    from globe.cli.evaluate_cmd import print_anticipation, table1_table, timing_table
    from globe.evaluation.published import DataScope

    rows = [{"method": m, "household": h, "average": "weighted", "activity_f1": 0.8, "object_f1": 0.6, "mean_f1": 0.7}
            for m in ("persistence", "ngram") for h in ("Mine", "mean")]
    timing = [{"method": "ngram", "household": "Mine", "train_s": 0.1, "inference_s": 0.2, "llm_calls": 0, "llm_s": 0.0,
               "selection_s": 0.0}]
    mine = DataScope("household Mine", ("Mine",), False)
    table = table1_table(rows, {}, mine)
    assert table.title == "Scores on the test days of household Mine, weighted F1"
    assert [c.header for c in table.columns] == ["method", "activity", "object", "mean"]
    assert timing_table(timing, mine).title == "Time for the whole test split (s)"
    homer = DataScope("HOMER+", ("A", "B", "C"), True)
    three = [dict(r, household=h) for r in rows if r["household"] == "mean" for h in ("A", "B", "C", "mean")]
    table = table1_table(three, {}, homer)
    assert table.title == "Table I - HOMER+ test days, weighted F1 (mean of households)"
    assert [c.header for c in table.columns][4:] == ["A: act/obj", "B: act/obj", "C: act/obj"]
    assert timing_table(timing, homer).title == "Table II - time for the whole test split (s)"
    (tmp_path / "data.json").write_text(json.dumps(mine.as_dict()), encoding="utf-8")
    (tmp_path / "lookahead.csv").write_text("method,household,horizon_min,f1\nngram,Mine,10,0.5\nngram,mean,10,0.5\n")
    (tmp_path / "fetch_policy.csv").write_text("household,configured\n")
    (tmp_path / "missing_labels.csv").write_text("household,labels_pct,activity_f1,object_f1\nmean,0,0.7,0.6\n")
    capsys.readouterr()
    print_table(table1_table(rows, {}, mine))
    print_anticipation(tmp_path)
    printed = " ".join(capsys.readouterr().out.split())  # titles wrap over narrow tables
    assert "mean of households" not in printed and "Table I" not in printed
    assert "Lookahead on household Mine: relocation F1" in printed
    assert "Missing activity labels (household Mine)" in printed


def test_docs_tables_writes_stale_tables_and_check_reports_them(tmp_path):
    from pathlib import Path

    reference = Path(__file__).resolve().parents[1] / "reference" / "homer_plus"
    (tmp_path / "docs").mkdir()
    page = tmp_path / "docs" / "results.md"
    page.write_text("# R\n\n<!-- globe:table calibration -->\n| stale |\n<!-- /globe:table -->\n", encoding="utf-8")
    args = ("docs", "tables", "--root", str(tmp_path), "--results", str(reference))
    stale = globe(*args, "--check")
    assert stale.returncode == 1 and "results.md: its tables differ" in stale.stderr
    wrote = globe(*args)
    assert wrote.returncode == 0 and "wrote" in wrote.stdout
    text = page.read_text(encoding="utf-8")
    assert "| Routine model (CV) |" in text and "| stale |" not in text
    again = globe(*args, "--check")
    assert again.returncode == 0 and "every table matches" in again.stdout


def test_evaluate_takes_every_household_of_a_data_folder_by_default(tmp_path):
    """A folder of imported homes needs no --households: every folder with a nodes.csv is one; a
    home with objects gets the lookahead and fetch-policy tables too, its uses counted as
    departures (its map has a use place)."""
    from globe.data.csv_logs import write_day, write_nodes
    from tests.simulated import clock_home

    home = clock_home(12, 3)
    folder = tmp_path / "homes" / "Mine"
    for split, days in (("train", home.train), ("test", home.test)):
        (folder / split).mkdir(parents=True)
        for i, day in enumerate(days):
            write_day(folder / split / f"{i:03d}.csv", day, home.objects)
    write_nodes(folder / "nodes.csv", home.nodes)
    (tmp_path / "homes" / "notes").mkdir()  # not a household: no nodes.csv
    res = globe("evaluate", "--data", str(tmp_path / "homes"), "--methods", "persistence", "--backend", "none",
                "--no-activity-ahead", "--out", str(tmp_path / "out"))
    assert res.returncode == 0, res.stderr
    rows = list(csv.DictReader((tmp_path / "out" / "table1.csv").open()))
    assert {r["household"] for r in rows} - {"mean"} == {"Mine"}
    ahead = list(csv.DictReader((tmp_path / "out" / "lookahead.csv").open()))
    assert {r["method"] for r in ahead} == {"persistence", "hour_activity", "oracle"}  # baseline and oracle rows
    assert (tmp_path / "out" / "fetch_policy.csv").is_file()
    assert json.loads((tmp_path / "out" / "data.json").read_text())["uses"].startswith("departures only")
    assert "uses counted: departures only" in " ".join(res.stdout.split())
    empty = globe("evaluate", "--data", str(tmp_path / "homes" / "notes"), "--out", str(tmp_path / "o2"))
    assert empty.returncode != 0 and "no household folder" in empty.stderr


def test_a_listed_label_holding_a_comma_is_quoted_as_in_csv():
    from globe.cli.model_cmd import _split
    from globe.errors import DataError

    assert _split('sleeping, "Watching TV, couch" ,away') == ("sleeping", "Watching TV, couch", "away")
    assert _split("a,,b") == ("a", "b") and _split("") == ()
    with pytest.raises(DataError, match="cannot read the list"):
        _split("a,b\nc")


def test_train_deploys_what_cross_validation_chose_and_predict_answers_at_a_time(tmp_path):
    """``globe train`` runs the routine family's cross-validation and keeps what won in the model
    file; ``globe predict`` says so, answers at a time of day, and lists the objects expected
    within the horizon; ``globe household import`` keeps the same deployment in the database."""
    import json

    from tests.corpus.homes import write_home

    home = write_home(tmp_path / "data", train=8, test=1)
    models = tmp_path / "models"
    trained = globe("train", "--household", "T", "--data", str(tmp_path / "data"), "--model-dir", str(models))
    assert trained.returncode == 0, trained.stderr
    assert "chosen by cross-validation on its training days" in trained.stdout
    assert "next-activity log loss" in trained.stdout and "(persistence" in trained.stdout
    deployment = json.loads((models / "model.json").read_text())["deployment"]
    assert deployment["cross_validated"] is True and deployment["method"] == "routine"
    res = globe("predict", "--model-dir", str(models), "--at", "06:40", "--start", "06:00",
                "--history", "sleeping,breakfast", "--horizon", "30", "--date", "2026-03-02")
    assert res.returncode == 0, res.stderr
    lines = res.stdout.splitlines()
    assert "at 06:40 on 2026-03-02" in lines[1] and "step 4" in lines[1]
    assert lines[2] == "next activity (06:50):" and "expected within 30 minutes:" in res.stdout
    variant = globe("predict", "--model-dir", str(models), "--history", "Sleeping")
    assert variant.returncode == 1 and "a case or spacing variant of the known 'sleeping'" in variant.stderr
    db = tmp_path / "globe.sqlite3"
    imported = globe("household", "import", "--db", str(db), "--name", "t", str(home))
    assert imported.returncode == 0, imported.stderr
    assert "chosen by cross-validation" in imported.stderr
    from globe.service.store import Store

    store = Store(db)
    try:
        stored = store.settings("t")
    finally:
        store.close()
    assert stored["deployment"]["models"] == deployment["models"] and stored["grid"]["step_minutes"] == 10
