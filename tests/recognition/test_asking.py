"""Asking the person: the worth of an answer weighs how little its likely activities are labelled,
so on a simulated sensor home (tests/simulated_sensors.py) questions go to rarely labelled
activities far more often than at random times, and their answers are learnt."""

from __future__ import annotations

from collections import Counter
from functools import lru_cache

import numpy as np
import pytest

from globe.data.records import Day, Household
from globe.data.sensors import SensorData
from globe.evaluation import recognition as R
from globe.recognition.asking import DayAsker, QuestionPolicy, worth
from globe.recognition.recogniser import Recogniser, RecognitionSettings
from tests.simulated_sensors import sensor_home

STEP = 5


@lru_cache(maxsize=1)
def _home() -> tuple[Household, SensorData]:
    return sensor_home(days=12, test=3, step=STEP, seed=1)


def _rarity(answers: list[list[str | None]], labelled: Day) -> float:
    """The mean of 1 / sqrt(1 + labelled steps) over the activities answered: 1 for one never labelled."""
    counts = Counter(labelled.activities)
    asked = [a for day in answers for a in day if a is not None]
    assert asked, "no question was answered"
    return float(np.mean([1.0 / np.sqrt(1.0 + counts.get(a, 0)) for a in asked]))


def test_worth_weighs_how_little_the_likely_activities_are_labelled():
    unsure = np.array([[0.5, 0.5, 0.0, 0.0], [0.0, 0.0, 0.5, 0.5]])
    plain = worth(unsure)
    assert plain.tolist() == pytest.approx([0.5, 0.5])  # without counts: the chance of being wrong
    weighed = worth(unsure, [300.0, 300.0, 3.0])  # the fourth column: an activity named since, never counted
    assert weighed[1] > 5 * weighed[0]
    assert weighed[1] == pytest.approx(0.5 * (0.5 / 2.0 + 0.5))
    assert worth(np.array([[1.0, 0.0]]), [0.0, 0.0]).tolist() == [0.0]  # sure: an answer teaches no more


def test_the_asker_spends_its_budget_on_the_rarely_labelled_activity():
    reference = worth(np.array([[0.6, 0.4, 0.0], [0.4, 0.6, 0.0], [0.0, 0.6, 0.4]] * 20), [500.0, 500.0, 2.0])
    asker = DayAsker(QuestionPolicy(1, reference, gap=1), 6, labelled=[500.0, 500.0, 2.0])
    common, rare = np.array([0.5, 0.5, 0.0]), np.array([0.0, 0.5, 0.5])
    assert [asker(t, p) for t, p in enumerate([common, common, rare, common, common, common])] == [
        False, False, True, False, False, False]
    blind = DayAsker(QuestionPolicy(1, worth(np.array([[0.6, 0.4, 0.0]] * 60)), gap=1), 6)
    assert blind(0, common)  # by the chance of being wrong alone, the first unsure step is as good as any


def test_questions_go_to_rarely_labelled_activities_and_their_answers_are_learnt():
    home, sensors = _home()
    labelled, unlabelled = list(home.train[-1:]), list(home.train[:-1])
    settings = RecognitionSettings()
    before = Recogniser(settings).fit(labelled, sensors, STEP)
    after, answers = R.live_asking(settings, labelled, unlabelled, sensors, STEP, 3, "worth")
    _, at_random = R.live_asking(settings, labelled, unlabelled, sensors, STEP, 3, "random", seed=0)
    asked = sum(a is not None for day in answers for a in day)
    assert 0 < asked <= 3 * len(unlabelled)
    assert _rarity(answers, labelled[0]) > 1.4 * _rarity(at_random, labelled[0])
    # an activity labelled on at most two steps and then answered is recognised better on the test days
    counts = Counter(labelled[0].activities)
    taught = {a for day in answers for a in day if a is not None and counts.get(a, 0) <= 2}
    assert taught
    old, new = R._score(before, home.test), R._score(after, home.test)

    def recall(scores: R.Scores, activity: str) -> float:
        i = scores.labels.index(activity)
        return float(scores.confusion[i, i] / scores.confusion[i].sum())
    for activity in taught & {a for d in home.test for a in d.activities}:
        assert recall(new, activity) > recall(old, activity) + 0.2
        assert after.labelled_counts()[after.labels.index(activity)] > counts.get(activity, 0)


def test_the_asking_curve_averages_random_draws_and_names_its_labelled_days():
    home, sensors = _home()
    options = [RecognitionSettings()]
    rows = R.asking_curve(home, sensors, STEP, labelled_days=1, budgets=(0, 1), options=options, draws=2)
    assert [(r["labelled_days"], r["questions_per_day"]) for r in rows] == [(1, 0), (1, 1)]
    assert rows[0]["worth_class_accuracy"] == rows[0]["random_class_accuracy"]  # no question: the same
    assert rows[0]["worth_questions"] == 0 and "random_class_accuracy_sd" not in rows[0]
    assert rows[1]["random_questions"] == len(home.train) - 1  # one a day at random, every day
    assert 0 < rows[1]["worth_questions"] <= len(home.train) - 1
    assert rows[1]["random_class_accuracy_sd"] >= 0.0
    with pytest.raises(ValueError, match="unknown way of asking"):
        R.live_asking(options[0], list(home.train[-1:]), [], sensors, STEP, 1, "often")
