"""The discriminative (hybrid HMM) sensor emission: Bayes' rule over a classifier's posterior,
evidence that is not counted twice, learning day by day, and its place among the recogniser's
candidates, in the recogniser and in a household session."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from globe.evaluation import recognition as R
from globe.recognition.emission import SensorEmission
from globe.recognition.hybrid import DiscriminativeEmission
from globe.recognition.recogniser import Recogniser, RecognitionSettings, sensor_emission
from globe.session.sensing import settings_from_dict, settings_to_dict
from tests.simulated_sensors import sensor_home

pytest.importorskip("sklearn")


def _steps(copies: int, seed: int = 0) -> tuple[np.ndarray, list[str]]:
    """Steps of two activities told apart by one sensor ("on" in 80 % of cook's steps and 20 % of
    walk's), written ``copies`` times (as a door and the motion behind it report one event), and
    one unrelated noisy column."""
    rng = np.random.default_rng(seed)
    acts = ["cook"] * 400 + ["walk"] * 400
    on = np.concatenate([rng.random(400) < 0.8, rng.random(400) < 0.2]).astype(np.int64)
    noise = rng.integers(0, 2, 800)
    return np.column_stack([on] * copies + [noise]), acts


def _log_ratio(emission, x: np.ndarray) -> float:
    log = emission.log_likelihoods(x, ["cook", "walk"])
    return float(log[0, 0] - log[0, 1])


def test_a_sensor_reported_twice_counts_once_where_naive_bayes_counts_it_twice():
    ratios = {}
    for copies in (1, 4):
        x, acts = _steps(copies)
        sizes = np.full(x.shape[1], 2)
        nb = SensorEmission().fit([x], [acts], sizes)
        hybrid = DiscriminativeEmission().fit([x], [acts], sizes)
        on = np.array([[1] * copies + [0]])
        ratios[copies] = (_log_ratio(nb, on), _log_ratio(hybrid, on))
    assert ratios[1][0] > 1.0 and ratios[1][1] > 1.0  # both read "on" as cooking
    assert ratios[4][0] == pytest.approx(4 * ratios[1][0], rel=0.05)  # naive Bayes: four times the evidence
    assert ratios[4][1] < 1.5 * ratios[1][1]  # the classifier: the same evidence, however often reported


def test_the_scaled_likelihood_is_the_posterior_over_the_share_of_labelled_steps():
    x, acts = _steps(1)
    emission = DiscriminativeEmission().fit([x], [acts + []], np.array([2, 2]))
    post = emission.model_.predict_proba(emission._onehot(x[:5]))
    log = emission.log_likelihoods(x[:5], ["walk", "cook", "never_labelled"])
    assert np.allclose(log[:, 1], np.log(post[:, 0]) - np.log(0.5))  # classes in the order first labelled
    assert np.allclose(log[:, 0], np.log(post[:, 1]) - np.log(0.5))
    assert (log[:, 2] == 0).all()  # an activity never labelled reads like the home at large
    like = emission.likelihoods(x[:5], ["walk", "cook"])
    assert np.allclose(like.max(axis=1), 1.0)
    half = DiscriminativeEmission(weight=0.5).fit([x], [acts], np.array([2, 2]))
    assert np.allclose(half.log_likelihoods(x[:5], ["walk", "cook"]), 0.5 * log[:, :2])
    three = ["sleep" if i % 3 == 0 else a for i, a in enumerate(acts)]  # more classes: one row of weights each
    wider = DiscriminativeEmission().fit([x], [three], np.array([2, 2]))
    assert np.allclose(wider._posterior(x[:9]), wider.model_.predict_proba(wider._onehot(x[:9])))


def test_it_learns_day_by_day_as_from_all_days_at_once_and_waits_for_two_activities():
    x, acts = _steps(2, seed=1)
    days = [x[:300], x[300:500], x[500:]]
    labels = [acts[:300], [None] * 200, acts[500:]]  # an unlabelled day teaches it nothing
    sizes = np.full(x.shape[1], 2)
    whole = DiscriminativeEmission().fit(days, labels, sizes)
    growing = DiscriminativeEmission().fit([], [], sizes)
    assert not growing.log_likelihoods(x[:3], ["cook"]).any()  # nothing learnt: neutral
    growing.partial_fit(days[:1], labels[:1], sizes)
    assert growing.model_ is None and not growing.log_likelihoods(x[:3], ["cook"]).any()  # one activity: neutral
    for day, said in zip(days[1:], labels[1:]):
        growing.partial_fit([day], [said], sizes)
    assert np.allclose(growing.log_likelihoods(x, ["cook", "walk"]), whole.log_likelihoods(x, ["cook", "walk"]))
    assert growing.labelled_steps(["walk", "cook", "other"]).tolist() == [300.0, 300.0, 0.0]
    with pytest.raises(ValueError, match="columns"):
        growing.partial_fit([x[:, :1]], [acts[:1]], np.array([2]))


def test_the_settings_name_the_emission_and_cross_validation_is_offered_both():
    settings = RecognitionSettings(features=("raw", "last"), weight=0.5, emission="discriminative")
    assert settings_from_dict(settings_to_dict(settings)) == settings
    assert isinstance(sensor_emission(settings), DiscriminativeEmission)
    assert isinstance(sensor_emission(RecognitionSettings()), SensorEmission)
    with pytest.raises(ValueError, match="unknown sensor emission"):
        settings_from_dict({"emission": "neural"})


def test_cross_validation_offers_the_discriminative_emission_over_the_features_naive_bayes_chose(monkeypatch):
    home, sensors = sensor_home(days=6, test=1, step=10, seed=2)
    tried: list[RecognitionSettings] = []

    class Spy(Recogniser):
        def fit(self, *args, **kwargs):
            tried.append(self.settings)
            return super().fit(*args, **kwargs)
    monkeypatch.setattr(R, "Recogniser", Spy)
    chosen = R.choose_settings(home.train, sensors, 10)
    first = [s for s in tried if s.emission == "naive_bayes" and not s.edges]
    later = [s for s in tried if s.emission == "discriminative" and not s.edges]
    assert set(first) == set(R.candidates()) and all(s.emission == "naive_bayes" for s in R.candidates())
    assert tried.index(later[0]) > max(tried.index(s) for s in first)  # offered after the first search
    edged = {s for s in tried if s.edges}  # then the evidence on changes, over the one chosen so far
    assert {s.edge_strength for s in edged} == set(R.EDGE_STRENGTHS) and len({replace(s, edges=False,
            edge_strength=RecognitionSettings().edge_strength) for s in edged}) == 1
    assert min(tried.index(s) for s in edged) > tried.index(later[0])
    assert chosen.emission in ("naive_bayes", "discriminative")
    tried.clear()
    naive = R.choose_settings(home.train, sensors, 10, options=R.candidates())  # a search of one's own: as asked
    assert {s.emission for s in tried} == {"naive_bayes"} and not any(s.edges for s in tried)
    assert set(later) == {replace(naive, emission="discriminative")}  # one: naive Bayes's features and weight


def test_the_recogniser_reads_the_simulated_home_with_either_emission():
    home, sensors = sensor_home(days=8, test=2, step=10, seed=2)
    truth = [a for d in home.test for a in d.activities]
    scores = {}
    for emission in ("naive_bayes", "discriminative"):
        settings = RecognitionSettings(features=("raw", "change", "last"), weight=0.5, emission=emission)
        rec = Recogniser(settings).fit(home.train, sensors, 10)
        scores[emission] = R.recognition_scores(truth, [a for p in rec.predict(home.test) for a in p])
        assert rec.describe()["emission"] == emission
    majority = max(truth.count(a) for a in set(truth)) / len(truth)
    assert scores["discriminative"].time_slice > majority + 0.3
    assert scores["discriminative"].time_slice > scores["naive_bayes"].time_slice - 0.15
