"""The fetch policy's candidates belong to the policy the session owns: where cross-validation
chose the clock-aware uses model (a home whose uses follow the clock), the session fetches from it,
step by step as the evaluation scores that model, and the fetch row is what the session decided."""

from __future__ import annotations

import numpy as np
import pytest

from globe.config import Deployment, GlobeConfig
from globe.evaluation.deploy import choose_deployment
from globe.evaluation.fetch import (
    evaluate_fetch,
    evaluate_uses_baseline,
    fit_uses_baseline,
    pooled,
    replay_test_days,
)
from globe.inference.fetch_policy import FetchContext
from globe.models.baselines import fit_uses_ahead, minutes_since_use, used_matrix
from globe.session import build_session
from globe.session.build import deployment_summary
from tests.simulated import clocked_objects_home

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
