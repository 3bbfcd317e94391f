"""``globe evaluate --activities recognised``: the models are shown the test days' activities as
recognised from the home's sensors, and still scored against the annotation."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from dataclasses import replace

import pytest

from globe.config import GlobeConfig
from globe.data.csv_logs import load_household
from globe.data.records import Day, Household
from globe.errors import ConfigError, DataError
from globe.evaluation import main_job
from globe.evaluation.activity_anticipation import score_anticipation
from globe.evaluation.deploy import choose_deployment
from globe.evaluation.experiments import run_methods
from globe.evaluation.fetch import LAST_DATE
from globe.evaluation.methods import METHODS
from globe.evaluation.metrics import records_f1
from globe.evaluation.online import day_observations, replay_dates
from globe.evaluation.protocol import evaluate_days, seen_day
from globe.evaluation.recognised import recognise_households, recognise_test_days, scope_of, sensors_of
from globe.evaluation.selection import Memo
from globe.recognition.recogniser import RecognitionSettings
from globe.session import build_session
from tests.simulated_sensors import sensor_home, write_home

FAST = [RecognitionSettings()]  # one candidate: the settings' cross-validation is tested in tests/recognition
QUICK = {"selection": {"folds": 2, "routine_orders": [2], "time_weights": [0.0], "stay_margins": [1.0],
                       "clock_slots": [60], "clock_floors": [0.0], "clock_shrinkages": [2.0],
                       "clock_day_types": ["none"]},
         "lookahead": {"thresholds": [0.3], "run_memory": [False], "run_next": [False]}}
"""Small cross-validation grids: these tests are about what the models are shown, not what is chosen."""


def _folder(root, days=8, test=2):
    home, sensors = sensor_home(days=days, test=test, step=10, seed=3)
    return write_home(root / "Sensors", home, sensors)


@pytest.fixture(scope="module")
def imported(tmp_path_factory) -> Household:
    root = tmp_path_factory.mktemp("homes")
    _folder(root)
    return load_household(root, "Sensors")


def _wrong(day: Day) -> Day:
    """``day`` seen through a recogniser that is always wrong (each step shown the next step's
    activity of another name)."""
    names = sorted(set(day.activities))
    return replace(day, observed=tuple(names[(names.index(a) + 1) % len(names)] for a in day.activities))


def test_a_day_is_seen_as_observed_else_as_annotated(imported):
    day = imported.test[0]
    assert day.observed is None and day.seen == day.activities and seen_day(day) is day
    wrong = _wrong(day)
    assert wrong.seen == wrong.observed != wrong.activities
    assert seen_day(wrong).activities == wrong.observed and seen_day(wrong).observed is None


@pytest.mark.parametrize("method", ["ngram", "hour_activity"])  # a history model, and one told the whole day
def test_the_model_sees_the_observed_history_and_is_scored_on_the_annotation(imported, method):
    prepared = METHODS[method].prepare(imported, GlobeConfig(), None, Memo())
    days = list(imported.test)

    def run(test):
        return evaluate_days(imported, test, prepared.activity, prepared.chooser, stay_margin=prepared.stay_margin)

    plain, echoed, misled = run(days), run([replace(d, observed=d.activities) for d in days]), run(
        [_wrong(d) for d in days])
    assert [r.as_row() for r in echoed.activity] == [r.as_row() for r in plain.activity]
    assert [r.as_row() for r in echoed.objects] == [r.as_row() for r in plain.objects]
    # the truth (activity, previous activity, object runs) is the annotation's whatever the model was shown
    assert [(r.true, r.previous) for r in misled.activity] == [(r.true, r.previous) for r in plain.activity]
    assert [(r.true, r.true_activity) for r in misled.objects] == [(r.true, r.true_activity) for r in plain.objects]
    assert [r.predicted_activity for r in misled.objects] != [r.predicted_activity for r in plain.objects]
    assert records_f1(misled.activity, "weighted") < records_f1(plain.activity, "weighted") - 0.15
    if method == "ngram":  # the activity ahead: the same references and truth, a misled model does worse
        misled_days = [_wrong(d) for d in days]
        ahead = [score_anticipation("S", prepared.activity, imported.train, test, 3, 10)
                 for test in (days, misled_days)]
        first = [[h for h in s.horizons if h.method == "model" and h.steps == 1][0] for s in ahead]
        assert first[0].references == first[1].references
        assert first[1].accuracy < first[0].accuracy - 0.3
        assert ahead[0].next_activity["model"][0] == ahead[1].next_activity["model"][0]  # the same change events


def test_recognised_test_days_carry_the_recognisers_activities(imported):
    done = recognise_test_days(imported, sensors_of(imported, 10), 10, FAST)
    home = done.household
    assert home.train == imported.train  # the models learn from the annotation
    assert [d.activities for d in home.test] == [d.activities for d in imported.test]
    assert all(d.observed is not None and len(d.observed) == len(d) for d in home.test)
    right = sum(a == b for d in home.test for a, b in zip(d.activities, d.observed or ()))
    steps = sum(len(d) for d in home.test)
    assert done.scores.time_slice == pytest.approx(right / steps)
    assert 0.5 < done.scores.time_slice < 1.0  # recognised, imperfectly
    assert done.row()["steps"] == steps and json.loads(done.row()["settings"])["features"] == ["change", "last"]
    assert "recognised from sensors" in scope_of([home]).title and "recognised" not in scope_of([imported]).title


def test_a_home_without_sensors_is_a_clear_error(tmp_path, imported):
    bare = replace(imported, source=str(tmp_path))
    with pytest.raises(ConfigError, match=f"household Sensors has no sensor data.*no sensors.csv in {tmp_path}"):
        recognise_households(GlobeConfig(), [bare])


def _rows(path):
    with path.open(newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def _quick() -> GlobeConfig:
    return GlobeConfig().with_overrides({f"{part}.{k}": v for part, values in QUICK.items() for k, v in values.items()})


def test_evaluate_with_recognised_activities_writes_both_and_scores_the_annotation(tmp_path, imported, monkeypatch):
    monkeypatch.setattr("globe.evaluation.recognition.candidates", lambda: FAST)
    config = _quick()
    memo = Memo()  # the training days are the same: one cross-validation for both runs
    folders = {a: tmp_path / a for a in ("annotated", "recognised")}
    for activities, out in folders.items():
        main_job.evaluate(config, [imported], ["ngram"], out, None, memo=memo, objects_ahead=True,
                          activities=activities)
    data = {a: json.loads((out / "data.json").read_text(encoding="utf-8")) for a, out in folders.items()}
    assert data["annotated"]["activities"] == "annotated" and data["recognised"]["activities"] == "recognised"
    assert not (folders["annotated"] / "recognition.csv").exists()
    [row] = _rows(folders["recognised"] / "recognition.csv")
    assert row["household"] == "Sensors" and 0 < float(row["class_accuracy"]) <= 1
    assert "recognised" in (folders["recognised"] / "table1.md").read_text(encoding="utf-8")
    f1 = {a: {r["method"]: float(r["activity_f1"]) for r in _rows(out / "table1.csv")
              if r["household"] == "Sensors" and r["average"] == "weighted"} for a, out in folders.items()}
    assert f1["annotated"]["persistence"] != f1["recognised"]["persistence"]  # shown other activities
    assert abs(f1["annotated"]["ngram"] - f1["recognised"]["ngram"]) < 0.2
    for out in folders.values():  # every record's truth is the annotation
        records = _rows(out / "records" / "ngram_Sensors_activity.csv")
        truth = [a for d in imported.test for a in d.activities[1:]]
        assert [r["true"] for r in records] == truth
    assert all((folders["recognised"] / name).is_file() for name in ("lookahead.csv", "fetch_policy.csv"))


def _globe(*args, cwd):
    return subprocess.run([sys.executable, "-m", "globe", *args], capture_output=True, text=True, timeout=600,
                          cwd=cwd)


def test_the_cli_option_end_to_end(tmp_path):
    _folder(tmp_path / "data", days=6)
    toml = tmp_path / "quick.toml"
    toml.write_text("".join(f"[{part}]\n" + "".join(f"{k} = {json.dumps(v)}\n" for k, v in values.items())
                            for part, values in QUICK.items()), encoding="utf-8")
    run = _globe("evaluate", "--data", str(tmp_path / "data"), "--methods", "ngram", "--no-objects-ahead",
                 "--config", str(toml), "--activities", "recognised", "--out", str(tmp_path / "out"), cwd=tmp_path)
    assert run.returncode == 0, run.stderr[-2000:]
    assert "Sensors: test-day activities recognised from the sensors online" in run.stdout
    assert "recognised from sensors" in run.stdout  # the tables' title
    assert (tmp_path / "out" / "recognition.csv").is_file()
    bad = _globe("evaluate", "--data", str(tmp_path / "data"), "--activities", "guessed", cwd=tmp_path)
    assert bad.returncode != 0 and "'guessed' is not one of annotated, recognised" in bad.stderr


def test_homer_plus_has_no_sensors_to_recognise_from(tmp_path, homer_root):
    run = _globe("evaluate", "--data", str(homer_root), "--households", "A", "--methods", "ngram",
                 "--activities", "recognised", "--out", str(tmp_path / "out"), cwd=tmp_path)
    assert run.returncode != 0
    assert "household A has no sensor data" in run.stderr and "HOMER+ has none" in run.stderr


def _served(home, sensors, config, deployment, recognition):
    """(next activity said, activity recognised) after each step of ``home``'s test days but
    their last, by a session deployed with ``deployment`` told their sensors and no label."""
    session = build_session(home, config, deployment, None, sensors=sensors, recognition=recognition,
                            questions_per_day=0)
    said, recognised = [], []
    for day, date in zip(home.test, replay_dates(home.test, LAST_DATE)):
        for t, obs in day_observations(home, day, date, visible=lambda _row: False, sensors=sensors):
            session.observe(obs)
            if t < len(day) - 1:
                top, found = session.next_activity(), session.recognised()
                assert top is not None and found is not None
                said.append(top[0])
                recognised.append(found[0])
    return said, recognised


@pytest.mark.parametrize("method, days", [("ngram", 8), ("routine", 8), ("routine", 4)])
def test_a_deployable_row_scores_what_its_session_served(tmp_path, imported, method, days):
    """Where a row is a method a household runs, its next activity at each test step is what the
    session deployed with it said after the step before (told no label, the sensors as evidence),
    its stay margin (the deployment's) kept at the activity recognised; a baseline reads the
    recognised activities. With too few training days to deploy the routine family by
    cross-validation, its row is what the configured models its household runs then serve."""
    if days != 8:  # 2 training days, fewer than the 3 folds: the configured models are deployed
        _folder(tmp_path, days=days)
        imported = load_household(tmp_path, "Sensors")
    config = _quick().with_overrides({"models.stay_margin": 1.5, "selection.stay_margins": [3.0, 4.0],
                                      "selection.folds": 3})
    memo, sensors = Memo(), sensors_of(imported, 10)
    done = recognise_test_days(imported, sensors, 10, FAST, config, memo)
    served, = run_methods(config, [done.household], [method], None, memo, [done])
    read, = run_methods(config, [done.household], [method], None, memo)  # the model reading the recognised days
    deployment = choose_deployment(imported, config, memo, method)
    assert deployment.cross_validated == (method == "routine" and days == 8)
    said, recognised = _served(imported, sensors, config, deployment, done.recognition)
    assert [r.predicted for r in served.evaluation.activity] == said
    assert [r.true for r in served.evaluation.activity] == [a for d in imported.test for a in d.activities[1:]]
    assert [r.predicted for r in read.evaluation.activity] != said  # the sensors said more than the activities
    persistence, = run_methods(config, [done.household], ["persistence"], None, memo, [done])
    shown = [a for d in done.household.test for a in (d.observed or ())[:-1]]  # by the deployed (routine) session
    assert [r.predicted for r in persistence.evaluation.activity] == shown  # a rule on what was recognised
    replayed = [r.deployment.method for r in done.replays]
    assert replayed == (["routine"] if method == "routine" else ["routine", "ngram"])  # one replay per deployment
    if days == 8:
        assert (recognised == shown) == (method == "routine")  # each deployment recognises with its own dynamics


def test_the_fetch_policy_of_a_recognised_home_is_decided_by_a_session_told_its_sensors_and_no_label(imported,
                                                                                                      monkeypatch):
    from globe.evaluation import anticipation

    config = _quick().with_overrides({"evaluation.workers": 1})  # in this process: the spy sees the session
    memo, sensors = Memo(), sensors_of(imported, 10)
    done = recognise_test_days(imported, sensors, 10, FAST, config, memo)
    built = []

    def spy(*args, **kw):
        session = build_session(*args, **kw)
        built.append((kw.get("sensors"), session))
        return session

    monkeypatch.setattr(anticipation, "build_session", spy)
    served, = anticipation.run_anticipation(config, [done.household], memo=memo, recognised=[done]).fetch[:1]
    (given, session), = built
    assert given is sensors and session.sensing is not None and served.report.fetches > 0
    assert session.step_counts() == (0, len(done.household.test[-1]))  # the last day: no label, every step recognised


def test_a_day_that_begins_late_is_served_and_a_day_with_a_gap_is_a_clear_error(imported):
    """Each row's belief is P(the next row's activity) only where the rows follow the household's
    grid: a test day that begins late is replayed; one missing a row in its middle is an error
    naming the day, rather than beliefs a step off."""
    from globe.evaluation.recognised import served_days

    config, sensors = _quick(), sensors_of(imported, 10)
    deployment = choose_deployment(imported, config, Memo(), "ngram")
    day = imported.test[0]

    def cut(rows):
        return replace(day, minutes=tuple(day.minutes[t] for t in rows),
                       activities=tuple(day.activities[t] for t in rows),
                       locations=tuple(day.locations[t] for t in rows))

    late = replace(imported, test=(cut(range(6, len(day))),))
    replay = served_days(late, sensors, config, deployment, RecognitionSettings())
    assert len(replay.days[0].beliefs) == len(day) - 6
    gap = replace(imported, test=(cut([t for t in range(len(day)) if t != 20]),))
    with pytest.raises(DataError, match="row 20 .* is step 21 of the household's 10-minute grid") as err:
        served_days(gap, sensors, config, deployment, RecognitionSettings())
    assert err.value.field == "minute" and day.name in str(err.value)
