"""The baselines as rows wherever a model is scored (Table I, the lookahead, the fetch policy), on
simulated homes: a home whose objects follow the clock, where the object baseline (the most
frequent use given the hour and the activity) must win, and a home with no routine, where no
rule of the clock beats persistence."""

from __future__ import annotations

import csv
import datetime as dt
from pathlib import Path

import numpy as np
import pytest

from globe.config import GlobeConfig
from globe.data.records import Day, Household
from globe.evaluation import main_job
from globe.evaluation.deploy import choose_deployment
from globe.evaluation.experiments import run_methods, table1_rows
from globe.evaluation.lookahead import BASELINE, ORACLE, baseline_days, first_moves, fit_moves_baseline
from globe.evaluation.methods import BASELINES, METHODS, object_baseline, with_baselines
from globe.evaluation.online import day_observations, replay
from globe.evaluation.relocation import LookaheadRun, reference_queries
from globe.session import build_session
from globe.session.build import deployment_summary
from tests.simulated import HOME_PLACES, IN_USE, OBJECTS, _nodes, random_home

CONFIG = GlobeConfig().with_overrides({"llm.backend": "none", "selection.folds": 3})


def hour_home(days: int = 24, test: int = 4) -> Household:
    """Two meals a day, alike but for the clock: the kettle is taken at breakfast (07:20), the
    microwave at dinner (19:20), each put back a step later (a return: no use)."""
    minutes = tuple(range(360, 1440, 10))
    acts = tuple("sleeping" if m < 420 else "meal" if m < 450 else "relax" if m < 1140 else "meal" if m < 1170
                 else "relax" for m in minutes)
    taken = {440: "kettle", 1160: "microwave"}
    rows = tuple(tuple(IN_USE if taken.get(m) == o else HOME_PLACES[o] for o in OBJECTS) for m in minutes)
    out = [Day(f"day{i:03d}", minutes, acts, rows) for i in range(days)]
    return Household("Hours", _nodes(), OBJECTS, tuple(out[:-test]), tuple(out[-test:]))


def weighted(runs) -> dict[str, dict]:
    return {r["method"]: r for r in table1_rows(runs) if r["household"] == "mean" and r["average"] == "weighted"}


def test_every_table_gets_the_baselines_after_the_last_listed():
    assert BASELINES == ("persistence", "time_of_day", "hour_activity")
    assert with_baselines(["ngram"]) == ["persistence", "time_of_day", "hour_activity", "ngram"]
    assert with_baselines(["ngram", "persistence", "routine"]) == ["ngram", "persistence", "time_of_day",
                                                                     "hour_activity", "routine"]
    assert with_baselines(list(BASELINES)) == list(BASELINES)
    assert all(METHODS[b].shown.endswith("(baseline)") for b in BASELINES) and METHODS["ngram"].shown == "n-gram Markov"


def test_the_object_baseline_counts_departures_only():
    home = hour_home()
    model = object_baseline(home, "previous")
    assert dict(model.overall_) == {"kettle": len(home.train), "microwave": len(home.train)}  # no return counted


def test_on_a_home_of_clocked_objects_the_object_baseline_wins_table_one():
    home = hour_home()
    rows = weighted(run_methods(CONFIG, [home], ["ngram", "time_of_day", "hour_activity"], None))
    # the n-gram knows objects by activity only: one meal's object is right, the other's never
    assert rows["ngram"]["object_f1"] < 0.7
    assert rows["hour_activity"]["object_f1"] == 1.0 and rows["time_of_day"]["object_f1"] == 1.0


def test_cross_validation_deploys_the_object_baseline_where_it_wins_and_the_session_serves_it(tmp_path):
    """On the clocked-objects home the object baseline is an object model cross-validation offers
    beside the n-gram (``models.object_model``): chosen there, it is the routine row's object model
    (object F1 1.0 where the n-gram's is below 0.7), the one the deployment names, and the one the
    household's session serves: the kettle before breakfast, the microwave before dinner, read
    from the clock of the step predicted; it is learnt from each finished day and saved with its
    minutes. A session over the n-gram says one object for both meals."""
    home = hour_home()
    rows = weighted(run_methods(CONFIG, [home], ["routine"], None))
    assert rows["routine"]["object_f1"] == 1.0
    deployment = choose_deployment(home, CONFIG)
    assert deployment.models.object_model == "hour_activity"
    assert "objects by the most frequent use given the hour and the activity" in deployment_summary(deployment)

    def meals(dep):
        session = build_session(home, CONFIG, dep, None)
        day = home.test[0]
        steps = [(day.name, t, obs) for t, obs in day_observations(home, day, dt.date(2026, 3, 2))]
        records, _ = replay(session, steps)
        out = {day.minutes[r.decision.step]: r.decision.choice.obj for r in records
               if r.decision.activity == "meal" and r.decision.step < len(day) and r.decision.choice is not None}
        return out, session

    served, session = meals(deployment)
    assert served and all(obj == ("kettle" if minute < 720 else "microwave") for minute, obj in served.items())
    assert {minute // 600 for minute in served} == {0, 1}  # both meals were asked
    learnt = len(session.chooser.model.training_data_)
    session.learn([home.test[1]])
    new = session.chooser.model.training_data_[learnt:]
    assert sorted(m for _, _, minutes in new for m in minutes) == [430, 1150]  # each use with its step's minute
    ngram, _ = meals(deployment.model_copy(update={"models": deployment.models.model_copy(
        update={"object_model": "ngram"})}))
    assert len(set(ngram.values())) == 1


def test_on_a_home_with_no_routine_no_rule_of_the_clock_beats_persistence():
    home = random_home(40, 8)
    rows = weighted(run_methods(CONFIG, [home], ["persistence", "time_of_day", "hour_activity"], None))
    assert rows["time_of_day"]["activity_f1"] < rows["persistence"]["activity_f1"] - 0.3
    assert rows["hour_activity"]["activity_f1"] <= rows["persistence"]["activity_f1"] + 0.01


def test_the_baselines_first_moves_are_the_truth_the_lookahead_scores():
    home = hour_home(6, 2)
    la = CONFIG.lookahead
    fitted = fit_moves_baseline(home.train, home.objects, 6, la)
    run = baseline_days(fitted, home.test, 6)
    for s in range(6):
        truth = np.concatenate([first_moves(day, [r], 6)[:, s].ravel()
                                for day, r in reference_queries(home.test, 6)])
        assert (np.concatenate(run.pairs[s].true) == truth).all()
    day = home.test[0]
    at_use = day.minutes.index(1160)  # the microwave in use: its next move is being put back, never foreseen
    assert not first_moves(day, [at_use], 6)[0, :, OBJECTS.index("microwave")].any()
    before = day.minutes.index(1110)  # 19:20 is five steps after 18:30: within 50 minutes, not 40
    assert first_moves(day, [before], 6)[0, :, OBJECTS.index("microwave")].tolist() == [False] * 4 + [True] * 2


def test_the_lookahead_baseline_foresees_clocked_uses():
    home = hour_home()
    fitted = fit_moves_baseline(home.train, home.objects, 6, CONFIG.lookahead)
    run: LookaheadRun = baseline_days(fitted, home.test, 6)
    # every use foreseen an hour ahead; the clock's hour-wide slot also says so at its first step, too early
    counts = run.pairs[5].counts(0.4)
    assert counts.recall == 1.0 and counts.precision == 0.75
    assert run.activity_accuracy()[0] > 0.95  # hour + activity: the changes an hour-wide slot cannot time missed


def read(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as fh:
        return list(csv.DictReader(fh))


@pytest.mark.slow
def test_evaluate_writes_the_baseline_rows_and_says_they_are_baselines(tmp_path):
    cfg = CONFIG.with_overrides({"lookahead.methods": ("persistence",), "policy.method": "persistence",
                                 "policy.cost_useless": 1.0,
                                 "policy.curve_ratios": (1.0, 3.0)})
    main_job.evaluate(cfg, [hour_home()], ["ngram"], tmp_path, None, objects_ahead=True)
    table1 = read(tmp_path / "table1.csv")
    assert list(dict.fromkeys(r["method"] for r in table1)) == ["persistence", "time_of_day", "hour_activity", "ngram"]
    assert "Hour + activity (baseline)" in (tmp_path / "table1.md").read_text()
    look = {(r["method"], r["horizon_min"]): r for r in read(tmp_path / "lookahead.csv") if r["household"] == "mean"}
    assert float(look[(BASELINE, "60")]["f1"]) > float(look[("persistence", "60")]["f1"])
    fetch = [r for r in read(tmp_path / "fetch_policy.csv") if r["household"] == "all" and r["configured"] == "True"]
    assert [r["method"] for r in fetch] == ["persistence", BASELINE, ORACLE]
    mine = fetch[1]
    # every use fetched in advance; the hour-wide slot also fetches at its first step, an hour early
    assert float(mine["recall"]) == 1.0 and float(mine["precision"]) >= 0.5
    assert {r["method"] for r in read(tmp_path / "lookahead_selection.csv")} == {"persistence", BASELINE, "ngram",
                                                                                ORACLE}
