"""Smoothed estimates against hand-computed values on toy sequences."""

import math

import pytest

from globe.models.backoff import witten_bell_distribution
from globe.models.objects import ObjectModel
from globe.models.routine import RoutineModel
from globe.models.suffix_index import SuffixIndex
from globe.reasoning.choice import object_distribution


def test_witten_bell_by_hand():
    # training "a b a b a c": after "a": b twice, c once (c=3, N1+=2);
    # unigram level (empty context): a 3, b 2, c 1 (c=6, N1+=3); floor: uniform 1/3
    index = SuffixIndex()
    index.add_all(["ababac"])
    vocab = ("a", "b", "c")
    state, matched = index.match("a")
    p = witten_bell_distribution(index, state, matched, max_context=1, vocabulary=vocab)
    p0 = {w: (n + 3 * (1 / 3)) / (6 + 3) for w, n in {"a": 3, "b": 2, "c": 1}.items()}  # 4/9, 3/9, 2/9
    p1 = {w: (n + 2 * p0[w]) / (3 + 2) for w, n in {"a": 0, "b": 2, "c": 1}.items()}
    assert p == pytest.approx(p1)
    assert p["b"] == pytest.approx((2 + 2 * 3 / 9) / 5)
    assert math.isclose(sum(p.values()), 1.0)


def test_witten_bell_applies_each_context_length_of_a_state():
    # "x y" is followed by z once; contexts "y" and "x y" share one automaton state (both seen
    # once, followed by z), so that state contributes two interpolation levels
    index = SuffixIndex()
    index.add_all(["xyz"])
    vocab = ("x", "y", "z")
    state, matched = index.match("xy")
    got = witten_bell_distribution(index, state, matched, max_context=2, vocabulary=vocab)
    p = {w: 1 / 3 for w in vocab}
    p = {w: (c + 3 * p[w]) / (3 + 3) for w, c in zip(vocab, (1, 1, 1))}  # unigram: each once
    for _ in range(2):  # "y" then "x y": c = 1, N1+ = 1 -> lambda = 1/2
        p = {w: ((w == "z") + 1 * p[w]) / 2 for w in vocab}
    assert got == pytest.approx(p)


def test_routine_stay_probability_by_hand():
    # "eat" runs last 2, 2 and 3 steps; days are long enough that every run end is observed
    days = [("x", "eat", "eat", "y"), ("x", "eat", "eat", "y"), ("x", "eat", "eat", "eat", "y")]
    m = RoutineModel(shrinkage=1.0, step_minutes=1).fit(days)
    # level (eat,): 7 eat steps with a next step, 4 stayed -> (4 + 2 * 0.5) / (7 + 2) = 5/9
    # level (eat, d=1): seen 3, stayed 3 -> (3 + 1 * 5/9) / 4 = 8/9
    # level (eat, 1, hour 0): the same 3 -> (3 + 8/9) / 4 = 35/36
    assert m.stay_probability("eat", 1, 2) == pytest.approx(35 / 36)
    # d=2: seen 3, stayed 1 -> (1 + 5/9) / 4 = 7/18; with hour: (1 + 7/18) / 4 = 25/72
    assert m.stay_probability("eat", 2, 3) == pytest.approx(25 / 72)


def test_routine_probabilities_sum_to_one_and_scan_matches(households):
    days = [d.activities for d in households["C"].train]
    m = RoutineModel(order=3, time_weight=1.0).fit(days)
    test = households["C"].test[0].activities
    scanned = m.scan_proba(test)
    for t in range(len(test)):
        assert math.isclose(sum(scanned[t].values()), 1.0)
        assert scanned[t] == m.predict_proba(test[:t])  # the scan tracks the run match incrementally: the same bits
    assert m.predict_proba(test[:50])[test[49]] > 0  # staying is always possible


def test_object_distribution_mixes_over_the_activity_belief():
    om = ObjectModel().fit([("eat", ("bowl",)), ("eat", ("cup",)), ("read", ("book",))])
    ctx = lambda a: ()  # noqa: E731
    got = object_distribution(om, "eat", {"eat": 0.6, "read": 0.4}, ctx, marginal=True)
    assert got == pytest.approx({"bowl": 0.3, "cup": 0.3, "book": 0.4})
    assert object_distribution(om, "eat", {"eat": 0.6, "read": 0.4}, ctx, marginal=False) == {"bowl": 0.5, "cup": 0.5}
