"""The fetch policy's candidates belong to the policy the session owns: where cross-validation
chose the clock-aware uses model (a home whose uses follow the clock), the session fetches from it,
step by step as the evaluation scores that model, and the fetch row is what the session decided."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from globe.config import Deployment, GlobeConfig
from globe.data.csv_logs import load_household
from globe.evaluation.anticipation import method_models
from globe.evaluation.deploy import choose_deployment
from globe.evaluation.fetch import (
    LAST_DATE,
    evaluate_fetch,
    evaluate_uses_baseline,
    fit_uses_baseline,
    forecast_day,
    pooled,
    replay_test_days,
)
from globe.evaluation.fetch_source import choose_fetch_source, fetch_cost
from globe.evaluation.lookahead import choose_settings, setting_of
from globe.evaluation.online import replay_dates
from globe.evaluation.selection import Memo
from globe.inference.fetch_policy import FetchContext, FetchReport
from globe.models.baselines import fit_uses_ahead, minutes_since_use, used_matrix
from globe.session import build_session
from globe.session.build import deployment_summary
from tests.simulated import activity_objects_home, clocked_objects_home, weekly_home

CONFIG = GlobeConfig().with_overrides({"llm.backend": "none", "selection.folds": 3})


@pytest.fixture(scope="module")
def home():
    return clocked_objects_home()


def session_of(home, fetch_objects: str, learn: bool = False):
    deployment = Deployment.configured(CONFIG).model_copy(update={"fetch_objects": fetch_objects})
    return build_session(home, CONFIG, deployment, None, learn=learn)


def test_the_session_fetches_step_by_step_what_the_clock_model_row_scores(home):
    session = session_of(home, "clock")
    assert session.policy.source == "clock"
    replayed = replay_test_days(session, home, home.test)
    policy = session.policy
    clock = fit_uses_baseline(home.train, home.objects, policy.min_lead_steps, policy.window_steps, clock=True)
    steps = 0
    for day, seen in zip(home.test, replayed):
        since = minutes_since_use(used_matrix(day, home.objects), day.minutes)
        for t, served in enumerate(seen.candidates):
            if served:  # the session decided after step t
                now = FetchContext(day.activities[t], day.minutes[t], day.weekday, since[t], lambda h: None)
                assert served == tuple(policy.candidates_from_uses(clock, now)), (day.name, t)
                steps += 1
    assert steps > 100
    scored = evaluate_uses_baseline(clock, policy, home.test, replayed, home.name, (3.0,), "routine")
    row = evaluate_fetch(session, home, home.test, (3.0,), "routine", replayed)
    assert row.report == scored.report and row.curve[0][2] == scored.curve[0][2]
    assert row.report.fetches > 0 and row.report.precision > 0.5  # the kettle at 15:00 on weekdays


def test_the_session_candidates_equal_the_rows_candidates_at_every_step(home):
    session = session_of(home, "clock")
    replayed = replay_test_days(session, home, home.test)
    policy = session.policy
    assert policy.uses is not None
    row = evaluate_uses_baseline(policy.uses, policy, home.test, replayed, home.name, (3.0,), "routine")
    assert row.report == pooled_reports(replayed)
    movements = replay_test_days(session_of(home, "movements"), home, home.test)
    assert [d.candidates for d in movements] != [d.candidates for d in replayed]  # the source matters here


def pooled_reports(replayed):
    return pooled([d.report for d in replayed])


def test_a_learning_session_counts_uses_as_fitting_on_every_day_at_once(home):
    session = session_of(home, "clock", learn=True)
    policy = session.policy
    assert policy.uses is not None
    policy.learn(home.test)
    once = fit_uses_ahead([*home.train, *home.test], home.objects, policy.min_lead_steps, policy.window_steps,
                          clock=True)
    since = np.array([-1.0, 20.0, 200.0] + [-1.0] * (len(home.objects) - 3))
    for minute in (840, 890, 1000):
        assert np.array_equal(policy.uses.proba("relax", minute, 2, since), once.proba("relax", minute, 2, since))


def test_the_deployment_a_service_builds_from_chooses_the_clock_model_where_it_won(home):
    deployment = choose_deployment(home, CONFIG)  # what globe train / POST /households keep with the household
    assert deployment.fetch_objects == "clock"
    session = build_session(home, CONFIG.deployed(deployment), deployment, None)
    assert session.policy.source == "clock" and "clock-aware" in deployment_summary(deployment)


def test_fetch_cost_counts_useless_fetches_and_uses_not_fetched_at_their_costs():
    report = FetchReport(fetches=10, useful_fetches=7, used_objects=12, used_fetched_in_advance=5)
    assert fetch_cost(report, CONFIG.policy) == 3.0 * 3 + 1.0 * 7
    cheap = CONFIG.with_overrides({"policy.cost_useless": 0.5, "policy.cost_missed": 2.0}).policy
    assert fetch_cost(report, cheap) == 0.5 * 3 + 2.0 * 7


def _routine_source(home):
    memo = Memo()
    models = method_models("routine", home, CONFIG, memo)
    return choose_fetch_source(home, CONFIG, models, setting_of(choose_settings(home, CONFIG, models, memo).best), memo)


def test_the_source_is_chosen_by_what_its_fetches_cost_on_held_out_training_days(home):
    chosen = _routine_source(home)
    cost = {params["objects"]: -score for params, score in chosen.scores}
    assert chosen.best == {"objects": "clock"} and cost["clock"] < cost["movements"]
    assert [p["objects"] for p, _ in chosen.scores] == ["movements", "clock"] and len(chosen.metrics) == 2
    # where the uses follow how long the activity has lasted, not the clock, the routine's forecast stays
    kept = _routine_source(activity_objects_home())
    cost = {params["objects"]: -score for params, score in kept.scores}
    assert kept.best == {"objects": "movements"} and cost["movements"] <= cost["clock"]
    # the paper's n-gram foresees those uses worse than the uses model: then the uses model is fetched by
    worse = choose_fetch_source(activity_objects_home(), CONFIG, CONFIG.models, (True, False, False))
    assert worse.best == {"objects": "clock"}


def test_a_day_forecast_at_once_is_the_day_a_session_replays(home, homer_root):
    """What the source's cross-validation reads (every step's forecast at once) is what a session
    that learns nothing decides step by step: the same uses, candidates, untouchable objects and
    fetches, on the clock home (a test day cut short, so the session decides at its last row),
    on undated days whose clock model tells weekends apart (the replay's weekdays), and on HOMER+
    at 10 and 5 minutes; a day off the session's grid is replayed."""
    short = replace(home.test[0], **{f: getattr(home.test[0], f)[:-5] for f in ("minutes", "activities",
                                                                              "locations")})
    cases = [(replace(home, test=(short, *home.test[1:3])), {})]
    weekly = weekly_home(30, 3, dated=False)
    cases.append((weekly, {"models": CONFIG.models.model_copy(update={
        "activity_estimator": "clock", "clock_day_types": "weekend"})}))
    for name, step in (("A", 10), ("B", 5)):
        h = load_household(homer_root, name, step_minutes=step, resample="locf" if step != 10 else "none")
        cases.append((replace(h, train=h.train[:12], test=h.test[:2]), {}))
    for h, models in cases:
        deployment = Deployment.configured(CONFIG).model_copy(update={"run_end": True, **models})
        session = build_session(h, CONFIG, deployment, None, learn=False)
        replayed = replay_test_days(session, h, h.test)
        dates = replay_dates(h.test, LAST_DATE)
        seen = [forecast_day(session, h, day, date) for day, date in zip(h.test, dates)]
        assert seen == replayed, h.name
        if h is cases[0][0]:  # the short day: decided at its last row, as the session did
            assert seen[0].candidates[-1] and not seen[1].candidates[-1]
        if h.name in ("A", "B"):
            assert sum(day.report.fetches for day in seen) > 0
