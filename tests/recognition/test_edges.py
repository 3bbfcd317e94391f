"""A step's evidence on the change after it (globe.recognition.edges): what it counts, how the
filter and forward-backward take it, and what it buys where the activity changes inside a step."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from globe.errors import ConfigError
from globe.evaluation import recognition as R
from globe.recognition.edges import SensorEdges
from globe.recognition.recogniser import Recogniser, RecognitionSettings, forward_backward, run_days
from globe.session.sensing import settings_from_dict, settings_to_dict
from tests.simulated_sensors import sensor_home

SIZES = np.array([2, 2])  # two binary columns: "the kettle fired", "the bathroom motion fired"


def test_a_pair_is_counted_against_what_usually_follows_and_a_pair_never_seen_says_nothing():
    # grooming, grooming, breakfast: the kettle fires in the grooming step breakfast begins in
    x = np.array([[0, 1], [1, 1], [1, 0], [0, 1], [1, 1], [1, 0]])
    acts = ["grooming", "grooming", "breakfast", "grooming", "grooming", "breakfast"]
    edges = SensorEdges().fit([x], [acts], SIZES)
    labels = ["grooming", "breakfast", "relax"]
    kettle = edges.tables(np.array([[1, 1]]), labels)[0]
    quiet = edges.tables(np.array([[0, 1]]), labels)[0]
    g, b, r = 0, 1, 2
    assert kettle[g, b] > kettle[g, g]  # a kettle in a grooming step: breakfast follows
    assert quiet[g, g] > quiet[g, b]  # none: grooming goes on
    assert kettle.max() == pytest.approx(1.0) and quiet.max() == pytest.approx(1.0)  # scaled per step
    # pairs never counted (anything from relax, breakfast -> relax) read alike: R = 1 before scaling
    assert kettle[r, g] == pytest.approx(kettle[r, r]) == pytest.approx(kettle[b, r])
    # a step with no label on either side is not counted
    assert SensorEdges().fit([x], [[None, *acts[1:]]], SIZES).training_data_ == 4.0


def test_edges_are_checked_and_learn_day_by_day_as_at_once():
    with pytest.raises(ConfigError, match="weight"):
        SensorEdges(weight=0).fit([], [], SIZES)
    x = np.array([[0, 1], [1, 1], [1, 0]])
    days = [["grooming", "grooming", "breakfast"], ["grooming", "breakfast", "breakfast"]]
    whole = SensorEdges().fit([x, x], days, SIZES)
    parts = SensorEdges().fit([x], days[:1], SIZES).partial_fit([x], days[1:], SIZES)
    step = np.array([[1, 1], [0, 0]])
    assert np.allclose(whole.tables(step, ["grooming", "breakfast"]), parts.tables(step, ["grooming", "breakfast"]))


def test_the_filter_and_forward_backward_take_the_same_evidence_on_changes():
    """With no pruning, the online filter's belief at a day's last step is forward-backward's there
    (both exact under first-order dynamics), with each step's evidence on the change after it."""
    home, sensors = sensor_home(days=6, test=1, step=10, seed=3)
    settings = RecognitionSettings(features=("raw", "change", "last"), weight=0.5, edges=True)
    rec = Recogniser(settings, max_hypotheses=10_000, min_weight=0.0).fit(home.train, sensors, 10)
    day = home.test[0]
    labels = list(rec.labels)
    likes, edges = rec._evidence(day, labels)
    assert edges is not None and edges.shape == (len(day), len(labels), len(labels))
    online = run_days(rec.filter_, [likes], [day.weekday], edges=[edges])[0]
    smooth = forward_backward(rec.filter_, likes, day.weekday, edges)
    assert np.allclose(online[-1], smooth[-1], atol=1e-9)
    without = run_days(rec.filter_, [likes], [day.weekday])[0]
    assert not np.allclose(online, without)  # the edges were taken in
    # nothing after a step changes what is recognised there: a day cut short reads its steps alike
    cut = run_days(rec.filter_, [likes[:20]], [day.weekday], edges=[edges[:20]])[0]
    assert np.allclose(cut, online[:20])
    # the next step expected takes what this step showed of the change: the next update's, before
    # that step's own evidence
    expected = run_days(rec.filter_, [likes], [day.weekday], mode="predictive", edges=[edges])[0]
    flt, belief = rec.filter_, rec.filter_.start(1, weekdays=[day.weekday])
    for t in range(12):
        belief = flt.update(belief, t, likelihood=likes[t][None], edges=edges[t - 1][None] if t else None)
    after = flt.posterior(flt.update(belief, 12, edges=edges[11][None]))[0]
    assert np.allclose(expected[11], after) and not np.allclose(expected[11], flt.predictive(belief)[0])


def _first_steps_right(recogniser: Recogniser, days) -> tuple[int, int]:
    """(changes whose new activity is recognised online at its first step, changes)."""
    right = total = 0
    for day, said in zip(days, recogniser.predict(days)):
        for t in range(1, len(day)):
            if day.activities[t] != day.activities[t - 1]:
                total += 1
                right += said[t] == day.activities[t]
    return right, total


def test_where_activities_change_inside_steps_the_new_one_is_read_at_its_first_step():
    """The simulated sensor home at 10-minute steps: an activity begins inside the step labelled
    with the one before (its first sensors fire there). Read with the evidence on changes, the
    new activity is recognised at its first step more often, and the days as a whole better."""
    home, sensors = sensor_home(days=28, test=7, step=10, seed=0)
    plain = RecognitionSettings(features=("raw", "change", "last"), weight=0.5)
    scores, first = {}, {}
    for settings in (plain, replace(plain, edges=True, edge_strength=2.0)):
        rec = Recogniser(settings).fit(home.train, sensors, 10)
        scores[settings.edges] = R._score(rec, home.test)
        first[settings.edges] = _first_steps_right(rec, home.test)
        assert rec.describe()["edges"] is settings.edges
    assert first[True][0] >= first[False][0] + 6, first  # measured: 87 against 77 of 93
    assert scores[True].time_slice > scores[False].time_slice + 0.02, scores
    assert scores[True].class_accuracy > scores[False].class_accuracy + 0.04, scores


def test_the_edges_compose_with_the_discriminative_emission():
    pytest.importorskip("sklearn")
    home, sensors = sensor_home(days=28, test=7, step=10, seed=0)
    plain = RecognitionSettings(features=("raw", "change", "last"), weight=0.5, emission="discriminative")
    read = {e: R._score(Recogniser(replace(plain, edges=e, edge_strength=2.0)).fit(home.train, sensors, 10),
                        home.test) for e in (False, True)}
    assert read[True].time_slice > read[False].time_slice + 0.01, read  # measured 0.980 against 0.962


def test_stored_settings_name_the_edges_and_older_ones_read_without():
    settings = RecognitionSettings(edges=True)
    assert settings_from_dict(settings_to_dict(settings)) == settings
    assert settings_from_dict({"features": ["change", "last"]}).edges is False


@pytest.mark.parametrize("gain, chosen", [((0.04, 0.05, 0.03, 0.04), 10.0), ((0.01, -0.01, 0.012, -0.008), None)])
def test_cross_validation_takes_the_edges_only_where_they_beat_the_settings_chosen_without(monkeypatch, gain, chosen):
    """The evidence on changes refines the settings chosen: it is taken (at the strength that reads
    held-out days best) where it beats them fold by fold beyond noise, not merely the default."""
    home, sensors = sensor_home(days=9, test=1, step=10, seed=1)
    fold_of = {d.name: i // 2 for i, d in enumerate(home.train)}

    class Stub:
        def __init__(self, settings):
            self.settings = settings

        def fit(self, *args, **kwargs):
            return self

    def score(fitted, days, smooth=False):
        s, fold = fitted.settings, fold_of[days[0].name]
        value = 0.5 if s == RecognitionSettings() else 0.8 + (0.001 if s.weight == 0.5 else 0.0)
        if s.edges:
            value += gain[fold] * (1.0 if s.edge_strength == 10.0 else 0.5)
        return R.Scores(value, value, {}, (), np.zeros((0, 0)))

    monkeypatch.setattr(R, "Recogniser", Stub)
    monkeypatch.setattr(R, "_score", score)
    monkeypatch.setattr(R.hybrid, "available", lambda: False)
    found = R.choose_settings(home.train[:8], sensors, 10)
    assert found.weight == 0.5  # the best without edges, beyond the default's noise
    assert found.edges is (chosen is not None) and (chosen is None or found.edge_strength == chosen)
