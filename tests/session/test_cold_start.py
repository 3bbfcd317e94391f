"""A household with sensors and no labelled day: it asks from its first step, knows only the
activities the person names, and learns its first day from the answers."""

from __future__ import annotations

import dataclasses
import datetime as dt

import pytest

from globe.config import Deployment
from globe.session import Observation, build_session
from tests.session.test_sensors import CFG, SETTINGS, step_events
from tests.simulated_sensors import sensor_home

BUDGET = 5


@pytest.fixture(scope="module")
def home():
    return sensor_home(days=6, test=3, step=10)


def cold(home, sensors=True, budget=BUDGET):
    h, data = home
    return build_session(dataclasses.replace(h, train=()), CFG, Deployment.configured(CFG, "ngram"), None,
                         sensors=data if sensors else None, recognition=SETTINGS, questions_per_day=budget)


def live(session, home, days):
    """Each step of ``days`` observed with its sensors only, each question answered at once with the
    true activity. Per day: the questions (step, options) and the (recognised, true) activities of
    the steps nobody asked about."""
    _, data = home
    questions, recognised = [], []
    for i, day in enumerate(days):
        midnight = dt.datetime.combine(dt.date(2026, 3, 2) + dt.timedelta(days=i), dt.time())
        asked, read = [], []
        for t, minute in enumerate(day.minutes):
            at = midnight + dt.timedelta(minutes=minute)
            session.observe(Observation(at, None, {}, step_events(data, day, t, midnight)))
            decision = session.decide()
            if decision.question is not None:
                asked.append((decision.question.step, decision.question.options))
                session.observe(Observation(at + dt.timedelta(minutes=1), day.activities[t], {}))
            else:
                read.append((decision.recognised, day.activities[t]))
        questions.append(asked)
        recognised.append(read)
    return questions, recognised


def test_it_asks_from_the_first_step_offering_only_the_names_it_heard(home):
    session = cold(home)
    assert session.status == "learning" and session.known_activities() == ()
    questions, recognised = live(session, home, home[0].test[:1])
    asked = questions[0]
    assert asked[0] == (0, ())  # an open question: no activity has a name yet
    spacing = session.grid.steps // BUDGET  # spread evenly over the grid's day, not spent by breakfast
    assert all(b[0] - a[0] >= spacing for a, b in zip(asked, asked[1:])) and 3 <= len(asked) <= BUDGET
    day = home[0].test[0]
    for k, (_, options) in enumerate(asked[1:], start=1):
        heard = list(dict.fromkeys(day.activities[s] for s, _ in asked[:k]))
        assert [a for a, _ in options] == heard and {p for _, p in options} == {1.0 / len(heard)}
    assert all(found is None for found, _ in recognised[0])  # nothing to recognise with before a learned day


def test_its_answers_teach_it_the_first_day_and_it_recognises_the_next(home):
    session = cold(home)
    questions, recognised = live(session, home, home[0].test)
    assert session.status == "ready" and session.days_learned == 1
    answered = {home[0].test[0].activities[s] for s, _ in questions[0]}
    assert set(session.activity_model.classes_) == answered  # the names the person said, and no other
    later = [found for day in recognised[1:] for found, _ in day]
    assert all(found is not None and found[0] in answered and 0.0 < found[1] <= 1.0 for found in later)
    assert questions[1] and all(options for _, options in questions[1])  # now asked where unsure, with options
    # Measured on four simulated homes: 0.22 to 0.85 of a later day's steps right (the most frequent
    # activity 0.28 to 0.53): the activity model has learned the first day only (a later day is learned
    # once half its steps are labelled), so a cold start recognises, but not yet well.


def test_without_sensors_or_budget_it_asks_nothing(home):
    for session in (cold(home, sensors=False), cold(home, budget=0)):
        questions, _ = live(session, home, home[0].test[:1])
        assert questions == [[]] and session.status == "learning"
