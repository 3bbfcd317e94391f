"""The online scores carry, over exactly the steps the session's one-step predictions were scored
on, the two rules the deployed model must beat: persistence (the activity stays) and hour +
activity (the most frequent next activity given the current one and the hour, counted on the
days the household has learnt, as it learns them)."""

from __future__ import annotations

import datetime as dt

from globe.config import Deployment, GlobeConfig
from globe.evaluation.online import day_observations, replay, replay_days
from globe.models.baselines import HourActivityBaseline, mode
from globe.session import build_session
from tests.simulated import clock_home

CONFIG = GlobeConfig().with_overrides({"llm.backend": "none", "models.activity_estimator": "witten_bell"})


def test_the_baselines_are_scored_on_the_same_steps_learning_as_the_session_learns():
    home = clock_home(days=20, test=3)
    session = build_session(home, CONFIG, Deployment.configured(CONFIG), None)
    dates = [dt.date(2024, 3, 4) + dt.timedelta(days=i) for i in range(len(home.test))]
    _, scores = replay_days(session, home, home.test, dates)
    rule = HourActivityBaseline(1).fit(home.train)
    steps = persistence = hour_activity = 0
    for i, day in enumerate(home.test):  # every step labelled and watched: steps 1.. of each day are scored
        for t in range(1, len(day) - (i == len(home.test) - 1)):  # (the very last step is still open)
            before, now = day.activities[t - 1], day.activities[t]
            steps += 1
            persistence += before == now
            hour_activity += mode(rule.proba(before, day.minutes[t - 1], 1)) == now
        rule.partial_fit([day])  # the session learns the day when the next one begins
    assert scores.predictions == steps
    assert (scores.persistence_correct, scores.hour_activity_correct) == (persistence, hour_activity)
    assert scores.persistence_accuracy == persistence / steps and scores.hour_activity_accuracy == hour_activity / steps
    assert persistence != hour_activity  # two rules, two counts: neither copies the other


def test_a_step_without_label_takes_the_last_label_before_it_and_unscored_steps_count_nothing():
    home = clock_home(days=10, test=1)
    session = build_session(home, CONFIG, Deployment.configured(CONFIG), None, learn=False)
    day = home.test[0]
    hidden = range(30, 36)
    stream = [(day.name, t, obs) for t, obs in day_observations(home, day, dt.date(2024, 3, 4),
                                                                  visible=lambda t: t not in hidden)]
    _, scores = replay(session, stream)
    rule = HourActivityBaseline(1).fit(home.train)
    scored = [t for t in range(1, len(day) - 1) if t not in hidden]  # the last step is still open
    last_label = {t: day.activities[max(s for s in range(t) if s not in hidden)] for t in scored}
    assert scores.predictions == len(scored)
    assert scores.persistence_correct == sum(last_label[t] == day.activities[t] for t in scored)
    assert scores.hour_activity_correct == sum(
        mode(rule.proba(last_label[t], day.minutes[t - 1], 1)) == day.activities[t] for t in scored)


def test_hour_activity_learning_day_by_day_counts_what_fitting_at_once_does():
    home = clock_home(days=12, test=0)
    once = HourActivityBaseline(1).fit(home.train)
    stepwise = HourActivityBaseline(1).fit(home.train[:5])
    for day in home.train[5:]:
        stepwise.partial_fit([day])
    for minute in (420, 720, 1140):
        for activity in ("relax", "breakfast", "idle"):
            assert stepwise.proba(activity, minute, 1) == once.proba(activity, minute, 1)
    assert stepwise.first_ == once.first_ and stepwise.classes_ == once.classes_
