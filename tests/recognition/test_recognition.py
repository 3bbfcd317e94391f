"""Activity recognition from ambient sensors: the features, the emission, the recogniser, asking,
and the scores, on hand-made days and on the simulated sensor home (tests/simulated_sensors.py)."""

from __future__ import annotations

import importlib.util
from functools import lru_cache

import numpy as np
import pytest
from sklearn.metrics import accuracy_score, balanced_accuracy_score

from globe.data.records import Day
from globe.data.sensors import Sensor, SensorDay
from globe.evaluation import recognition as R
from globe.recognition.asking import DayAsker, QuestionPolicy, random_steps, worth
from globe.recognition.emission import SensorEmission
from globe.recognition.features import ROOM_BINS, Layout, step_features
from globe.recognition.recogniser import Recogniser, RecognitionSettings
from tests.simulated_sensors import sensor_home

SENSORS = (Sensor("M_k", "motion", "kitchen"), Sensor("D_f", "door", "hall"), Sensor("M_b", "motion", "bedroom"))


def test_features_read_each_step_as_van_kasteren_does():
    # steps of 10 minutes from 06:00 (21600 s): [21600, 22200), [22200, 22800), [22800, 23400), [23400, 24000)
    day = SensorDay.of("d", [(0, 21700, 22900), (1, 22500, 22500), (2, 10000, 10060)])
    layout = Layout.of(SENSORS, ("raw", "change", "last", "room"))
    x = step_features(layout, day, [360, 370, 380, 390], 10)
    assert layout.names[:3] == ("raw:M_k", "raw:D_f", "raw:M_b")
    raw, change, last, room = x[:, 0:3], x[:, 3:6], x[:, 6], x[:, 7:]
    assert raw[:, 0].tolist() == [1, 1, 1, 0]  # on from the first step into the third
    assert raw[:, 1].tolist() == [0, 1, 0, 0]  # a firing marks its own step only
    assert change[:, 0].tolist() == [1, 0, 1, 0]  # begins in the first step, ends in the third
    assert change[:, 1].tolist() == [0, 1, 0, 0]
    assert change[:, 2].tolist() == [0, 0, 0, 0]  # before the day's grid: no change inside it
    assert last.tolist() == [0, 1, 0, 0]  # the kitchen motion's end (22900) is the last change from step 3 on
    assert layout.rooms == ("bedroom", "kitchen")
    kitchen = room[:, 1]
    assert kitchen.tolist() == [0, 0, 0, 2]  # seen in the step; then 1100 s before the step's end: 5-30 minutes
    assert ROOM_BINS[0] < 24000 - 22900 <= ROOM_BINS[1]
    assert room[:, 0].tolist() == [len(ROOM_BINS) + 1] * 4  # the bedroom's motion was hours before: the longest class


def test_a_day_without_recording_reads_quiet_and_layouts_refuse_unknown_features():
    layout = Layout.of(SENSORS, ("raw", "last"))
    x = step_features(layout, None, [360, 370], 10)
    assert x.tolist() == [[0, 0, 0, 3], [0, 0, 0, 3]]
    with pytest.raises(ValueError, match="expected some of"):
        Layout.of(SENSORS, ("colour",))


def test_the_emission_prefers_the_activity_whose_sensors_fired():
    x = np.array([[1, 0], [1, 0], [0, 1], [0, 1]])
    emission = SensorEmission(smoothing=1.0).fit([x], [["cook", "cook", "sleep", "sleep"]], np.array([2, 2]))
    log = emission.log_likelihoods(np.array([[1, 0], [0, 1]]), ["cook", "sleep", "never_seen"])
    assert log[0, 0] > log[0, 1] and log[1, 1] > log[1, 0]
    assert np.isfinite(log[:, 2]).all()  # an activity never labelled reads like the home at large
    like = emission.likelihoods(np.array([[1, 0]]), ["cook", "sleep"])
    assert like.max() == 1.0 and 0 < like[0, 1] < 1


@lru_cache(maxsize=1)
def _home():
    return sensor_home(days=12, test=3, step=5, seed=1)


def test_recognition_on_the_simulated_home_is_far_above_the_commonest_activity():
    home, sensors = _home()
    rec = Recogniser(RecognitionSettings(features=("raw", "change", "last"), weight=0.5)).fit(home.train, sensors, 5)
    scores = R._score(rec, home.test)
    truth = [a for d in home.test for a in d.activities]
    commonest = max(set(truth), key=truth.count)
    assert scores.time_slice > 0.8 and scores.time_slice > truth.count(commonest) / len(truth) + 0.3
    assert scores.class_accuracy > 0.7
    hindsight = R._score(rec, home.test, smooth=True)
    assert hindsight.class_accuracy >= scores.class_accuracy - 0.02


def test_online_recognition_never_looks_ahead():
    home, sensors = _home()
    rec = Recogniser().fit(home.train, sensors, 5)
    day = home.test[0]
    full = rec.filter([day])[0]
    cut = Day(day.name, day.minutes[:100], day.activities[:100], day.locations[:100])
    assert np.allclose(rec.filter([cut])[0], full[:100])  # the steps after 100 change nothing before them
    assert np.allclose(full.sum(axis=1), 1.0)


def test_an_answer_pins_its_step_and_asking_online_equals_answers_given_in_advance():
    home, sensors = _home()
    rec = Recogniser().fit(home.train, sensors, 5)
    day = home.test[0]
    posts, said = rec.filter_asking(day, lambda t, p: t in (30, 90), lambda t: day.activities[t])
    assert [t for t, a in enumerate(said) if a] == [30, 90]
    assert posts[30, rec.labels.index(day.activities[30])] == pytest.approx(1.0)
    ahead = rec.filter([day], [said])[0]
    assert np.allclose(ahead, posts)


def test_answers_are_learnt_from():
    home, sensors = _home()
    labelled, unlabelled = home.train[-1:], home.train[:-1]
    settings = RecognitionSettings(features=("raw", "change", "last"), weight=0.5)
    before = R._score(Recogniser(settings).fit(labelled, sensors, 5), home.test).class_accuracy
    answers = [[a if t % 6 == 0 else None for t, a in enumerate(d.activities)] for d in unlabelled]
    after = R._score(Recogniser(settings).fit(labelled, sensors, 5, unlabelled, answers), home.test).class_accuracy
    every = [list(d.activities) for d in unlabelled]
    full = R._score(Recogniser(settings).fit(labelled, sensors, 5, unlabelled, every), home.test).class_accuracy
    assert after > before + 0.05  # an answer every half hour of the unlabelled days
    assert full >= after  # every step answered: as good as labelled days


def test_the_question_policy_paces_its_budget():
    policy = QuestionPolicy(2, np.linspace(0, 1, 101), gap=3)
    assert not policy.ask(0.5, 0, 0, 100, None)  # not in the top 2 % of what worth looks like
    assert policy.ask(0.99, 0, 0, 100, None)
    assert not policy.ask(0.99, 0, 2, 100, 0)  # within the gap
    assert not policy.ask(0.99, 2, 50, 100, 10)  # the budget is spent
    assert policy.ask(0.1, 0, 98, 100, None)  # as many steps left as questions: ask
    assert worth(np.array([[0.7, 0.3]])).tolist() == pytest.approx([0.3])
    asker = DayAsker(QuestionPolicy(1, [0.0, 0.5, 1.0]), 100, window=3)
    assert not asker(0, np.array([0.4, 0.6]))  # worth 0.4 now, but the budget is paced over 100 steps
    assert sum(asker(t, np.array([0.5, 0.5])) for t in range(1, 100)) == 1 and asker.asked == 1
    steps = random_steps(50, 5, (1, 2))
    assert len(set(steps)) == 5 and steps == sorted(steps) and steps == random_steps(50, 5, (1, 2))


def test_scores_match_scikit_learn():
    true = ["a", "a", "a", "b", "c", "c"]
    pred = ["a", "a", "b", "b", "a", "c"]
    s = R.recognition_scores(true, pred)
    assert s.time_slice == pytest.approx(accuracy_score(true, pred))
    assert s.class_accuracy == pytest.approx(balanced_accuracy_score(true, pred))
    assert s.confusion.sum() == 6 and s.f1["b"] == pytest.approx(2 / 3)


def test_cross_validation_keeps_the_default_unless_beaten_and_curves_have_their_rows():
    home, sensors = _home()
    options = [RecognitionSettings(), RecognitionSettings(features=("raw", "change", "last"), weight=0.5)]
    assert R.choose_settings(home.train[:1], sensors, 5, options=options) == options[0]
    chosen = R.choose_settings(home.train, sensors, 5, options=options)
    assert chosen.features in (options[0].features, options[1].features)
    rows = R.learning_curve(home, sensors, 5, counts=(1, 3, None), options=options)
    assert [r["labelled_days"] for r in rows] == [1, 3, len(home.train)]
    assert rows[-1]["class_accuracy"] > rows[0]["class_accuracy"]
    asking = R.asking_curve(home, sensors, 5, labelled_days=2, budgets=(0, 2), options=options, draws=1)
    assert asking[0]["worth_questions"] == 0 and 0 < asking[1]["worth_questions"] <= 2 * (len(home.train) - 2)


def test_end_to_end_scores_both_histories_against_the_annotation():
    from globe.models.clock import ClockModel
    home, sensors = _home()
    model = ClockModel(step_minutes=5).fit([d.activities for d in home.train])
    rec = Recogniser(RecognitionSettings(features=("raw", "change", "last"), weight=0.5)).fit(home.train, sensors, 5)
    out = R.end_to_end(model, home.test, rec.predict(home.test))
    same = R.end_to_end(model, home.test, [d.activities for d in home.test])
    assert same["annotated_one_step_f1"] == same["recognised_one_step_f1"]
    assert 0 < out["recognised_one_step_f1"] <= 1 and out["annotated_one_step_f1"] == same["annotated_one_step_f1"]


def test_the_crf_row_runs_when_installed():
    pytest.importorskip("sklearn_crfsuite")
    home, sensors = _home()
    scores = R.crf_scores(home, sensors, 5)
    assert scores is not None and scores.time_slice > 0.7


def test_the_plain_hmm_row_decodes_with_hmmlearn_and_both_library_rows_are_listed():
    pytest.importorskip("hmmlearn")
    home, sensors = _home()
    scores = R.hmm_scores(home, sensors, 5)
    assert scores is not None and scores.time_slice > 0.7
    rows = R.library_rows(home, sensors, 5)
    assert rows["plain hmm (hmmlearn)"].row() == scores.row()
    assert ("crf (sklearn-crfsuite)" in rows) == (importlib.util.find_spec("sklearn_crfsuite") is not None)


def test_the_emission_learns_day_by_day_as_from_all_days_at_once():
    home, sensors = _home()
    rec = Recogniser(RecognitionSettings(features=("raw", "change", "last", "room"))).fit(home.train[:1], sensors, 5)
    features = [rec.features(d) for d in home.train]
    labels = [list(d.activities) for d in home.train]
    labels[2] = [None] * len(labels[2])  # an unlabelled day counts only in the home-at-large rates
    sizes = rec.layout_.sizes
    whole = SensorEmission().fit(features, labels, sizes)
    daily = SensorEmission().fit(features[:1], labels[:1], sizes)
    for x, acts in zip(features[1:], labels[1:]):
        daily.partial_fit([x], [acts], sizes)
    names = sorted(whole.classes_)
    assert sorted(daily.classes_) == names
    test = rec.features(home.test[0])
    assert np.allclose(whole.log_likelihoods(test, names), daily.log_likelihoods(test, names))
    with pytest.raises(ValueError, match="columns"):
        daily.partial_fit([x[:, :3]], [acts], sizes[:3])


def test_without_a_routine_the_sensors_are_read_and_only_what_they_cannot_tell_apart_is_confused():
    """A home whose activities come in random order at random times: the clock says nothing, so
    what is recognised is what the sensors show; the steps are read to the right group of
    activities the sensors cannot tell apart (the same room, mat and door: breakfast, lunch and
    dinner; meal preparation and washing dishes; toileting and grooming until the flush), and
    the errors are almost all inside such a group."""
    from tests.simulated_sensors import _PLACES

    home, sensors = sensor_home(days=12, test=3, step=10, seed=1, routine=False)
    rec = Recogniser(RecognitionSettings(features=("raw", "change", "last"), weight=0.5)).fit(home.train, sensors, 10)
    group = {a: (room, mat, at_start) for a, (room, _rate, mat, at_start) in _PLACES.items()}
    labels = list(rec.labels)
    pairs = [(a, labels[int(i)]) for day, post in zip(home.test, rec.filter(home.test))
             for a, i in zip(day.activities, post.argmax(axis=1))]
    wrong = [(a, b) for a, b in pairs if a != b]
    assert len(wrong) > 0.2 * len(pairs)  # the groups are real: the sensors alone cannot name their members
    assert sum(group[a] == group[b] for a, b in pairs) > 0.95 * len(pairs)
    assert sum(group[a] == group[b] for a, b in wrong) > 0.85 * len(wrong)
