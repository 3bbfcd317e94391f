"""The activity filter: a toy HMM computed by hand, exactness with every label visible, merging."""

from __future__ import annotations

import math

import pytest

from globe.data.records import Day
from globe.models.activity import ActivityModel
from globe.models.activity_filter import (
    ActivityFilter,
    MovementEmission,
    filtered_beliefs,
    filtered_scan,
    label_mask,
    moved_objects,
)
from globe.models.baselines import PersistenceModel
from globe.models.routine import RoutineModel
from globe.sequences.movements import moved_steps


class ToyMarkov:
    """A first-order Markov chain over two activities (a test double of an activity model)."""

    classes_ = ("a", "b")
    first = {"a": 0.6, "b": 0.4}
    trans = {"a": {"a": 0.7, "b": 0.3}, "b": {"a": 0.2, "b": 0.8}}

    def predict_proba(self, history):
        return dict(self.first) if not history else dict(self.trans[history[-1]])


class ToyEmission:
    """P(cup moved | the activity at the step): 0.9 under a, 0.2 under b (test double)."""

    p_cup = {"a": 0.9, "b": 0.2}

    def log_likelihood(self, previous, current, moved):
        p = self.p_cup[current]
        return math.log(p if "cup" in moved else 1 - p)

    def upper_bound(self, activities, moved):
        return max(self.log_likelihood(None, a, moved) for a in ("a", "b"))


def _close(dist, expected):
    assert set(dist) == set(expected)
    for k, v in expected.items():
        assert dist[k] == pytest.approx(v, abs=1e-12)


def test_filter_matches_a_toy_hmm_computed_by_hand():
    flt = ActivityFilter(ToyMarkov(), ToyEmission(), max_hypotheses=1000, min_weight=0.0)  # type: ignore[arg-type]
    _close(flt.predictive(), {"a": 0.6, "b": 0.4})
    flt.update(0, None, None)  # nothing seen at all
    _close(flt.posterior(), {"a": 0.6, "b": 0.4})
    # P(a1) = 0.6 * (0.7, 0.3) + 0.4 * (0.2, 0.8) = (0.5, 0.5)
    _close(flt.predictive(), {"a": 0.5, "b": 0.5})
    flt.update(1, None, {"cup"})  # posterior of a1 proportional to (0.5 * 0.9, 0.5 * 0.2) = (9/11, 2/11)
    _close(flt.posterior(), {"a": 9 / 11, "b": 2 / 11})
    _close(flt.predictive(), {"a": 6.7 / 11, "b": 4.3 / 11})
    flt.update(2, "b", {"cup"})  # a visible label pins the state, whatever moved
    _close(flt.posterior(), {"b": 1.0})
    _close(flt.predictive(), {"a": 0.2, "b": 0.8})
    flt.update(3, None, set())  # nothing moved: proportional to (0.2 * 0.1, 0.8 * 0.8)
    _close(flt.posterior(), {"a": 1 / 33, "b": 32 / 33})
    _close(flt.predictive(), {"a": 7.1 / 33, "b": 25.9 / 33})


def test_skipped_steps_carry_no_evidence_and_steps_must_increase():
    gap, explicit = ActivityFilter(ToyMarkov(), ToyEmission()), ActivityFilter(ToyMarkov(), ToyEmission())  # type: ignore[arg-type]
    gap.update(0, "a", None)
    gap.update(3, None, {"cup"})
    explicit.update(0, "a", None)
    explicit.update(1, None, None)
    explicit.update(2, None, None)
    explicit.update(3, None, {"cup"})
    _close(gap.predictive(), explicit.predictive())
    with pytest.raises(ValueError):
        gap.update(3, None, None)


def test_an_impossible_label_still_pins_the_state():
    flt = ActivityFilter(PersistenceModel().fit([("a", "a", "b")]))
    flt.update(0, "a", None)
    flt.update(1, "b", None)  # persistence gives "b" probability 0 after "a"
    _close(flt.posterior(), {"b": 1.0})
    _close(flt.predictive(), {"b": 1.0})


def _toy_days() -> list[tuple[str, ...]]:
    return [("s", "s", "e", "e", "w", "w", "s"), ("s", "e", "e", "w", "s", "s", "s"), ("s", "s", "s", "e", "w", "w", "w"),
            ("e", "e", "s", "w", "w", "e", "s")]


def test_routine_state_merging_is_exact():
    """Merging histories by (last runs, current run start) gives the same beliefs as keeping
    every history apart (the generic dynamics), with no pruning."""
    model = RoutineModel(order=2).fit(_toy_days())

    class Opaque:  # the same model seen only through predict_proba: no merging
        classes_ = model.classes_

        def predict_proba(self, history):
            return model.predict_proba(history)

    day = ("s", "s", "e", "w", "w", "s")
    for visible in ([False] * 6, [True, False, False, True, False, False]):
        merged, plain = ActivityFilter(model, max_hypotheses=10_000, min_weight=0.0), ActivityFilter(
            Opaque(), max_hypotheses=10_000, min_weight=0.0)
        for t, a in enumerate(day):
            _close(merged.predictive(), plain.predictive())
            merged.update(t, a if visible[t] else None, None)
            plain.update(t, a if visible[t] else None, None)
        assert len(merged.hypotheses()) < len(plain.hypotheses())


def test_every_label_visible_gives_exactly_scan_proba(households):
    h = households["A"]
    days = [d.activities for d in h.train]
    emission = MovementEmission(previous_share=0.5).fit(h.train, h.objects)
    for model in (RoutineModel().fit(days), ActivityModel().fit(days), ActivityModel(estimator="witten_bell", max_order=3,
                                                                                      time_weight=1.0).fit(days)):
        for day in h.test[:2]:
            got = filtered_scan(model, emission, day, [True] * len(day), h.objects)
            want = model.scan_proba(day.activities)
            assert len(got) == len(want)
            for g, w in zip(got, want):
                assert set(g) <= set(w)
                for a, p in w.items():
                    assert g.get(a, 0.0) == pytest.approx(p, abs=1e-12)


def test_beliefs_are_distributions_without_labels(households):
    h = households["B"]
    model = RoutineModel().fit([d.activities for d in h.train])
    emission = MovementEmission(previous_share=0.5, weight=0.5).fit(h.train, h.objects)
    day = h.test[0]
    flt = ActivityFilter(model, emission, max_hypotheses=16)
    predictive, now = filtered_beliefs(flt, day, label_mask(len(day), 0.25, (1, 2)), h.objects, nowcast=True)
    assert now is not None and len(predictive) == len(now) == len(day)
    for dist in predictive + now:
        assert sum(dist.values()) == pytest.approx(1.0, abs=1e-9)
        assert all(p >= 0 for p in dist.values())
    assert 0 < len(flt.hypotheses()) <= 16
    assert sum(hyp.weight for hyp in flt.hypotheses()) == pytest.approx(1.0)


def _day(name, activities, cup, plate):
    return Day(name, tuple(range(360, 360 + 10 * len(activities), 10)), tuple(activities),
               tuple((c, p) for c, p in zip(cup, plate)))


def test_movement_emission_counts_by_hand():
    d1 = _day("train/000", ["x", "x", "y", "y"], ["t", "t", "s", "s"], ["t", "t", "t", "f"])
    d2 = _day("train/001", ["y", "y", "x"], ["s", "t", "t"], ["f", "f", "f"])
    assert moved_objects(d1, ("cup", "plate")) == [frozenset(), frozenset(), {"cup"}, {"plate"}]
    em = MovementEmission(smoothing=1.0, previous_share=1.0).fit([d1, d2], ("cup", "plate"))
    # 5 transitions: cup moved twice, plate once -> overall rates (2+1)/(5+2), (1+1)/(5+2)
    assert em.rate_ == pytest.approx({"cup": 3 / 7, "plate": 2 / 7})
    # credited to the earlier activity: x at steps (x->x, x->y), y at (y->y, y->y, y->x);
    # cup moved under x once (x->y), under y once (y->y of day 2)
    assert em.probability("x", "cup", 0) == pytest.approx((1 + 3 / 7) / (2 + 1))
    assert em.probability("y", "plate", 0) == pytest.approx((1 + 2 / 7) / (3 + 1))
    nothing = math.log(1 - em.probability("x", "cup", 0)) + math.log(1 - em.probability("x", "plate", 0))
    assert em.log_likelihood("x", "y", frozenset()) == pytest.approx(nothing)
    edge = MovementEmission(smoothing=1.0, previous_share=1.0, boundary=True).fit([d1, d2], ("cup", "plate"))
    # x -> y happened once (day 1, step 2) and the cup moved then: shrunk towards the rate above
    base = (1 + 3 / 7) / (2 + 1)
    assert edge.probability("x", "cup", 0, changed=True) == pytest.approx((1 + base) / (1 + 1))
    assert edge.probability("x", "cup", 0, changed=False) == pytest.approx((0 + base) / (1 + 1))
    assert edge.log_likelihood("x", "y", frozenset({"cup"})) == pytest.approx(
        math.log(edge.probability("x", "cup", 0, True)) + math.log(1 - edge.probability("x", "plate", 0, True)))
    both = MovementEmission(previous_share=0.5, weight=0.5).fit([d1, d2], ("cup", "plate"))
    mix = 0.5 * math.exp(both.part_log_likelihood(0, "x", frozenset({"cup"}))) + 0.5 * math.exp(
        both.part_log_likelihood(1, "y", frozenset({"cup"})))
    assert both.log_likelihood("x", "y", frozenset({"cup"})) == pytest.approx(0.5 * math.log(mix))
    assert both.upper_bound(("x", "y"), frozenset({"cup"})) >= both.log_likelihood("x", "y", frozenset({"cup"}))


def test_switch_emission_tells_apart_what_the_next_activity_takes_out():
    """x ends twice: the cup moves when y starts, the plate when z starts. With ``switch`` the
    part credited to x knows which activity starts (shrunk towards x's change rate); a switch
    never seen keeps that rate, and the upper bound still bounds every likelihood."""
    d1 = _day("train/000", ["x", "x", "y"], ["t", "t", "s"], ["t", "t", "t"])
    d2 = _day("train/001", ["x", "x", "z"], ["t", "t", "t"], ["t", "t", "f"])
    objects = ("cup", "plate")
    plain = MovementEmission(smoothing=1.0, previous_share=1.0, boundary=True).fit([d1, d2], objects)
    em = MovementEmission(smoothing=1.0, previous_share=1.0, boundary=True, switch=True).fit([d1, d2], objects)
    changed = plain.probability("x", "cup", 0, changed=True)  # x -> y and x -> z: the cup moved once in 2
    assert em.probability("x", "cup", 0, True, "y") == pytest.approx((1 + changed) / (1 + 1))
    assert em.probability("x", "cup", 0, True, "z") == pytest.approx((0 + changed) / (1 + 1))
    assert em.probability("x", "cup", 0, True, "w") != em.probability("x", "cup", 0, True, "y")
    cup = frozenset({"cup"})
    assert em.log_likelihood("x", "y", cup) > plain.log_likelihood("x", "y", cup) > em.log_likelihood("x", "z", cup)
    assert em.log_likelihood("x", "w", cup) == pytest.approx(plain.log_likelihood("x", "w", cup))  # never seen
    assert em.log_likelihood("x", "x", cup) == pytest.approx(plain.log_likelihood("x", "x", cup))  # no change
    off = MovementEmission(smoothing=1.0, previous_share=1.0, boundary=True).fit([d1, d2], objects).with_params(switch=True)
    assert off.log_likelihood("x", "y", cup) == pytest.approx(em.log_likelihood("x", "y", cup))  # counted either way
    for moved in (frozenset(), cup, frozenset(objects)):
        top = em.upper_bound(("x", "y", "z"), moved)
        assert all(top >= em.log_likelihood(a, b, moved) - 1e-12 for a in "xyz" for b in "xyz")


def test_label_masks_are_seeded_sized_and_nested():
    masks = {f: label_mask(109, f, (0, 7, 9)) for f in (0.0, 0.25, 0.5, 0.75, 1.0)}
    assert [sum(m) for m in masks.values()] == [0, 27, 54, 82, 109]
    for lo, hi in ((0.25, 0.5), (0.5, 0.75)):
        assert all(h or not lo_ for lo_, h in zip(masks[lo], masks[hi]))
    assert label_mask(109, 0.5, (0, 7, 9)) == masks[0.5]
    assert label_mask(109, 0.5, (0, 7, 10)) != masks[0.5]


def test_movement_emission_partial_fit_equals_fit():
    d1 = _day("train/000", ["x", "x", "y", "y"], ["t", "t", "s", "s"], ["t", "t", "t", "f"])
    d2 = _day("train/001", ["y", "y", "x"], ["s", "t", "t"], ["f", "f", "f"])
    whole = MovementEmission(previous_share=0.5).fit([d1, d2], ("cup", "plate"))
    parts = MovementEmission(previous_share=0.5).fit([d1], ("cup", "plate")).partial_fit([d2], ("cup", "plate"))
    for moved in (frozenset(), frozenset({"cup"}), frozenset({"cup", "plate"})):
        for prev, cur in (("x", "x"), ("x", "y"), ("y", "x")):
            assert parts.log_likelihood(prev, cur, moved) == pytest.approx(whole.log_likelihood(prev, cur, moved))
    given = MovementEmission(previous_share=0.5).fit([d1, d2], ("cup", "plate"),
                                                     [moved_steps(d1, ("cup", "plate")), moved_steps(d2, ("cup", "plate"))])
    assert (given.steps_, given.moves_, given.rate_) == (whole.steps_, whole.moves_, whole.rate_)
    with pytest.raises(ValueError, match="moved steps of 1 days for 2 days"):
        MovementEmission().fit([d1, d2], ("cup", "plate"), [moved_steps(d1, ("cup", "plate"))])


def test_online_filter_for_the_service_matches_the_offline_scan(households):
    """Observations without an activity, fed one step at a time (as the service would), give the
    same beliefs as the offline scan of the day with every label hidden."""
    from globe import assembly
    from globe.config import GlobeConfig

    h, config = households["C"], GlobeConfig()
    model = assembly.activity_model(config.models.model_copy(update={"activity_estimator": "routine"}))
    model.fit([d.activities for d in h.train])
    online = assembly.household_filter(h, config, model)
    day = h.test[0]
    offline, _ = filtered_beliefs(assembly.household_filter(h, config, model), day, [False] * len(day), h.objects)
    moved = moved_objects(day, h.objects)
    for t in range(len(day)):
        _close(online.predictive(), offline[t])
        online.update(t, None, moved[t])
    online.reset()
    _close(online.predictive(), model.predict_proba(()))


def test_routine_dynamics_give_the_models_own_distributions(households):
    """The filter's (and forecaster's) routine state, stepped run by run with its parts memoised,
    gives exactly RoutineModel.predict_proba of the whole history."""
    from globe.models.activity_filter import dynamics_for

    h = households["A"]
    model = RoutineModel(order=2, time_weight=1.0).fit([d.activities for d in h.train])
    dyn = dynamics_for(model)
    assert dynamics_for(model) is dyn  # shared by every filter over the model
    for day in h.test[:2]:
        cursor = dyn.start()
        for t, a in enumerate(day.activities):
            assert dyn.distribution(cursor, t) == model.predict_proba(day.activities[:t])
            cursor = dyn.advance(cursor, t, a)
    model.partial_fit([h.test[0].activities])  # learning makes a fresh one
    assert dynamics_for(model) is not dyn


@pytest.mark.parametrize("order", [1, 2, 3])
def test_routine_child_key_equals_the_key_of_the_advanced_history(households, order):
    """The routine dynamics compute a child's state from the parent's state alone; it must be
    the state of the extended history, for every activity that could come next."""
    from globe.models.activity_filter import dynamics_for

    h = households["A"]
    model = RoutineModel(order=order).fit([d.activities for d in h.train[:20]])
    dyn = dynamics_for(model)
    seen_new_run = seen_same_run = 0
    for day in h.test[:2]:
        cursor = dyn.start()
        for t, a in enumerate(day.activities[:40]):
            key = dyn.key(cursor)
            for b in model.classes_:
                assert dyn.child_key(cursor, key, t, b) == dyn.key(dyn.advance(cursor, t, b))
                same = t > 0 and b == day.activities[t - 1]
                seen_same_run += same
                seen_new_run += not same
            cursor = dyn.advance(cursor, t, a)
    assert seen_same_run and seen_new_run
