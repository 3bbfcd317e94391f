"""Shared model helpers: the cheap argmax and the memoised time-of-day prior."""

import random
from collections import Counter

from globe.models.activity import ActivityModel
from globe.models.base import rank, top, windowed_prior


def test_rank_sorts_by_probability_then_frequency_then_label_and_top_is_its_first():
    rng = random.Random(3)
    for _ in range(500):
        labels = [f"x{i}" for i in range(rng.randint(1, 8))]
        dist = {w: rng.choice([0.1, 0.2, 0.2, 0.5]) for w in labels}  # many ties on purpose
        freq = {w: rng.randint(0, 3) for w in labels}
        ranked = rank(dist, freq)
        assert sorted(ranked) == sorted(dist) and top(dist, freq) == ranked[0]
        for u, w in zip(ranked, ranked[1:]):  # each pair in order: probability, frequency, label
            assert dist[u] > dist[w] or (dist[u] == dist[w] and (freq[u] > freq[w] or (freq[u] == freq[w] and u < w)))
    assert top({}, {}) is None


def test_step_prior_is_the_windowed_prior_and_follows_new_days():
    days = [["sleep", "sleep", "eat", "work"], ["sleep", "eat", "eat", "work"]]
    model = ActivityModel(time_weight=1.0, time_window=1).fit(days)
    for step in range(5):
        assert model.step_prior(model.by_step_, step, 1) == windowed_prior(model.by_step_, step, 1, model.classes_)
    before = model.step_prior(model.by_step_, 0, 1)
    model.partial_fit([["eat", "eat", "eat", "eat"]])  # new counts: the memo must not answer with the old prior
    after = model.step_prior(model.by_step_, 0, 1)
    assert after == windowed_prior(model.by_step_, 0, 1, model.classes_) and after != before
    model.fit([["work"] * 4] * 3)  # a refit with as many days as before: the memo is dropped all the same
    assert model.step_prior(model.by_step_, 0, 1) == windowed_prior(model.by_step_, 0, 1, model.classes_)
    assert Counter(model.step_prior(model.by_step_, 2, 1)) == Counter({"work": 1.0})
