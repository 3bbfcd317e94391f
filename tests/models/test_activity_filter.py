"""The activity filter: a toy HMM computed by hand, exactness with every label visible, merging."""

from __future__ import annotations

import copy
import math

import pytest

from globe.data.records import Day
from globe.models.activity import ActivityModel
from globe.models.activity_filter import (
    ActivityFilter,
    MovementEmission,
    dynamics_for,
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


# -- the compiled step (globe.models._filter_core) against the Python one, to the bit ------------

def _compiled_or_skip():
    from globe.models import activity_filter

    if activity_filter._native is None:
        pytest.skip("globe.models._filter_core was not compiled in this install")
    return activity_filter


def _both(monkeypatch, model, emission, **kwargs):
    """The same filter twice: the Python implementation and the compiled step (checked to be the
    one each runs, so that the comparison cannot compare Python with itself)."""
    activity_filter = _compiled_or_skip()
    monkeypatch.setattr(activity_filter, "COMPILED", False)
    python = ActivityFilter(model, emission, **kwargs)
    monkeypatch.setattr(activity_filter, "COMPILED", True)
    compiled = ActivityFilter(model, emission, **kwargs)
    assert python._state is None and compiled._state is not None
    return python, compiled


def _hyps(flt):
    return [(h.weight, h.history, h.cursor) for h in flt.hypotheses()]


def _trace(flt, day, visible, objects, peek_every=1):
    """Everything the filter shows over ``day``: each step's predictive and, after the update, its
    posterior and hypotheses (dicts as item lists: their order counts), with a shallow-copy peek
    at the step's movements first (which must leave the filter as it was)."""
    flt.reset()
    moved = moved_objects(day, objects)
    out: list = [_hyps(flt), list(flt.posterior().items())]
    for t in range(len(day)):
        out.append(list(flt.predictive().items()))
        if t % peek_every == 0:
            before = _hyps(flt)
            peek = copy.copy(flt)
            peek.update(t, None, moved[t])
            out += [list(peek.posterior().items()), list(peek.predictive().items()), _hyps(peek)]
            assert _hyps(flt) == before
        flt.update(t, day.activities[t] if visible[t] else None, moved[t])
        out += [list(flt.posterior().items()), _hyps(flt)]
    return out


def _assert_same(python, compiled, day, visible, objects, peek_every=1):
    want, got = _trace(python, day, visible, objects, peek_every), _trace(compiled, day, visible, objects, peek_every)
    assert python._state is None and compiled._state is not None  # each still on its own path
    assert len(got) == len(want)
    for i, (g, w) in enumerate(zip(got, want)):
        assert g == w, f"{day.name}: first difference at record {i}"


def _routine_models(h, config):
    from globe import assembly

    out = []
    for order, time_weight in ((3, 1.0), (2, 0.0)):
        models = config.models.model_copy(update={"activity_estimator": "routine", "routine_order": order,
                                                  "routine_time_weight": time_weight})
        out.append(assembly.fit_household(h, config.model_copy(update={"models": models})).activity)
    return out


@pytest.mark.parametrize("name", ["A", "B", "C"])
def test_compiled_step_gives_the_python_filters_numbers_on_homer_days(households, config, seed, monkeypatch, name):
    """Routine models (with and without the time-of-day prior), each movement evidence setting the
    missing-label stage searches and none (one day each), 0 / 25 / 50 / 100 % of labels visible,
    peeks: every predictive, posterior and hypothesis is exactly the Python filter's (== on floats,
    dicts in order)."""
    import random

    from globe import assembly
    from globe.evaluation.missing_labels import filter_candidates

    h = households[name]
    models = _routine_models(h, config)
    base = assembly.movement_emission(config.filter, previous_share=0.5, weight=1.0).fit(h.train, h.objects)
    emissions = [None] + [base.with_params(**params) for params in filter_candidates(config.filter)]
    rng = random.Random(seed)
    days = rng.sample(list(h.test), 7) + rng.sample(list(h.train), len(emissions) - 7)
    for i, day in enumerate(days):
        model, emission = models[i % 2], emissions[(i + seed) % len(emissions)]
        fraction = (0.0, 0.25, 0.5, 1.0)[i % 4]
        visible = label_mask(len(day), fraction, (seed, i))
        python, compiled = _both(monkeypatch, model, emission, max_hypotheses=config.filter.max_hypotheses,
                                 min_weight=config.filter.min_weight)
        _assert_same(python, compiled, day, visible, h.objects, peek_every=1 + i % 3)


def test_compiled_step_gives_the_python_filters_numbers_for_ngram_and_persistence(households, seed, monkeypatch):
    """The n-gram (longest context; Witten-Bell with the time-of-day prior) and persistence models,
    whose state is their cursor, with and without movement evidence."""
    h = households["A"]
    days = [d.activities for d in h.train]
    emission = MovementEmission(previous_share=1.0, boundary=True, switch=True, weight=0.5).fit(h.train, h.objects)
    models = [ActivityModel().fit(days), ActivityModel(estimator="witten_bell", max_order=3, time_weight=1.0).fit(days),
              PersistenceModel().fit(days)]
    for i, model in enumerate(models):
        for j, em in enumerate((None, emission)):
            day = h.test[(i + j + seed) % len(h.test)]
            python, compiled = _both(monkeypatch, model, em, max_hypotheses=16)
            _assert_same(python, compiled, day, label_mask(len(day), (0.0, 0.5)[j], (seed, i)), h.objects, peek_every=4)


class _OtherEmission:
    """Movement evidence of another kind (a test double): the compiled step leaves it to Python."""

    def log_likelihood(self, previous, current, moved):
        return -0.5 * len(moved) if current == previous else -1.0

    def upper_bound(self, activities, moved):
        return 0.0


def test_compiled_step_gives_the_python_filters_numbers_at_the_edges(households, monkeypatch):
    """Impossible and unknown labels (the "nothing kept" branch), skipped steps, a reset half-way,
    one hypothesis only, no pruning, and an emission the compiled step does not know put in
    half-way (it goes on in Python from the compiled state)."""
    h = households["B"]
    model = RoutineModel(order=2).fit([d.activities for d in h.train])
    emission = MovementEmission(previous_share=0.5, weight=0.5, boundary=True).fit(h.train, h.objects)
    day = h.test[1]
    moved = moved_objects(day, h.objects)
    rare = min(model.classes_, key=lambda a: model.frequency_[a])
    for kwargs in ({"max_hypotheses": 1}, {"max_hypotheses": 200, "min_weight": 0.0}, {}):
        python, compiled = _both(monkeypatch, model, emission, **kwargs)
        records: list[list] = [[], []]
        for flt, rec in zip((python, compiled), records):
            for t in (0, 1, 5, 6, 9, 20, 21, 40):  # gaps: skipped steps carry no evidence
                label = {5: rare, 6: "never-seen", 21: rare}.get(t)
                flt.update(t, label, moved[t] if t % 2 else None)
                rec += [list(flt.predictive().items()), list(flt.posterior().items()), _hyps(flt)]
                if t == 9:
                    flt.reset()
                    rec.append(_hyps(flt))
            flt.emission = _OtherEmission()  # type: ignore[assignment]
            flt.update(41, None, {"cup"})
            rec += [list(flt.predictive().items()), list(flt.posterior().items()), _hyps(flt)]
        assert records[0] == records[1]
        assert compiled._state is None  # left for Python at step 41


def test_compiled_beliefs_and_references_are_the_python_ones(households, config, monkeypatch):
    """What the missing-label evaluation reads through the filter: filtered_beliefs (predictive and
    nowcast, peeking with copy.copy) and filtered_references (prefixes of peeked hypotheses)."""
    from globe import assembly
    from globe.evaluation.missing_labels import FilterSetup, day_mask, filtered_references
    from globe.evaluation.tuning import Selection

    activity_filter = _compiled_or_skip()
    h = households["C"]
    (model, _), emission = _routine_models(h, config), assembly.movement_emission(
        config.filter, previous_share=1.0, weight=0.5, boundary=True, switch=True).fit(h.train, h.objects)
    setup = FilterSetup(h, config.models, model, emission, None, Selection({}), 0.0)
    out = []
    for compiled in (False, True):
        monkeypatch.setattr(activity_filter, "COMPILED", compiled)
        runs = []
        for fraction, day in zip((0.0, 0.5), h.test[:2]):
            mask = day_mask(config.filter, h.name, day, fraction)
            flt = assembly.activity_filter(model, emission, config.filter)
            assert (flt._state is not None) == compiled
            predictive, now = filtered_beliefs(flt, day, mask, h.objects, nowcast=True)
            refs = filtered_references(setup, config.filter, day, mask, 6, 1, 102, stride=3)
            runs.append(([list(d.items()) for d in predictive], [list(d.items()) for d in now or []], refs))
        out.append(runs)
    assert out[0] == out[1]


def test_compiled_step_chooses_the_same_movement_evidence(households, config, monkeypatch):
    """The missing-label stage's search over movement evidence (CV on training days, no labels):
    the same scores, to the bit, for candidates of every kind."""
    from globe.evaluation.missing_labels import filter_candidates, score_filter_candidates

    activity_filter = _compiled_or_skip()
    h = households["A"]
    models = config.models.model_copy(update={"activity_estimator": "routine", "object_marginal": True})
    candidates = [c for c in filter_candidates(config.filter) if c["weight"] == 0.5][1::3]  # previous_share 0, 0.5, 1
    assert {c["previous_share"] for c in candidates} == {0.0, 0.5, 1.0} and any(c["switch"] for c in candidates)
    scores = []
    for compiled in (False, True):
        monkeypatch.setattr(activity_filter, "COMPILED", compiled)
        scores.append(score_filter_candidates(h, config, models, candidates).scores)
    assert scores[0] == scores[1] and len(scores[0]) == len(candidates) >= 3


def test_a_full_compiled_core_is_replaced_for_new_filters_only(households, monkeypatch):
    """A core numbers states for as long as filters may hold them; past _CORE_STATES the next filter
    gets a fresh one, and a filter still on the old one goes on with the same numbers (its
    movement evidence in the old core's numbers)."""
    activity_filter = _compiled_or_skip()
    h = households["A"]
    model = RoutineModel(order=3).fit([d.activities for d in h.train])
    emission = MovementEmission(previous_share=0.5, boundary=True, switch=True).fit(h.train, h.objects)
    day = h.test[0]
    moved = moved_objects(day, h.objects)
    python, old = _both(monkeypatch, model, emission)
    for t in range(30):  # no movements seen yet: the old filter has not needed its evidence
        python.update(t, None, None)
        old.update(t, None, None)
    monkeypatch.setattr(activity_filter, "_CORE_STATES", 1)
    new = ActivityFilter(model, emission)
    assert new._state.core is not old._state.core
    for t in range(30, len(day)):
        new.update(t - 30, None, moved[t - 30])  # both cores in use, one emission
        python.update(t, None, moved[t])
        old.update(t, None, moved[t])
        assert _hyps(old) == _hyps(python)
    _assert_same(python, new, day, [False] * len(day), h.objects, peek_every=5)


def test_the_compiled_core_checks_what_it_is_given(households):
    """Bad input is an error, never a bad read: steps out of order, labels that are not str,
    evidence of another core, a distribution that is not a dict, a missing history, a step already
    under way on the same core, a core not initialised."""
    activity_filter = _compiled_or_skip()
    native = activity_filter._native
    h = households["A"]
    model = RoutineModel(order=2).fit([d.activities for d in h.train[:20]])
    em = MovementEmission().fit(h.train[:20], h.objects)
    flt = ActivityFilter(model, em)
    state, dyn = flt._state, flt._dynamics
    with pytest.raises(ValueError, match="step"):
        state.advance(dyn, 3, None, None, None, 1e-4, 32, None)
    with pytest.raises(ValueError, match="max_hypotheses"):
        state.advance(dyn, 0, None, None, None, 1e-4, 0, None)
    with pytest.raises(TypeError, match="str"):
        state.advance(dyn, 0, 7, None, None, 1e-4, 32, None)
    with pytest.raises(TypeError):
        state.advance(dyn, 0, None, "not evidence", frozenset(), 1e-4, 32, em)
    elsewhere = ActivityFilter(RoutineModel(order=3).fit([("a", "b")]))
    other = activity_filter._compiled_evidence(em, elsewhere._dynamics, elsewhere._state.core, model.classes_)
    with pytest.raises(ValueError, match="another core"):
        state.advance(dyn, 0, None, other, frozenset(), 1e-4, 32, em)
    with pytest.raises(IndexError):
        state.cursor(dyn, 1)
    with pytest.raises(ValueError):
        native.Core(5, 1, print, print)
    with pytest.raises(TypeError):
        native.Core.__new__(native.Core).root(dyn)
    bad = native.Core(native.OPAQUE, 0, lambda *args: ["a"], lambda dyn, key, step, a: a)
    with pytest.raises(TypeError, match="dict"):
        bad.root(dynamics_for(PersistenceModel().fit([("a", "b")]))).predictive(dyn)

    def reenter(dyn_, key, step, beam, index):
        beam.advance(dyn_, step, None, None, None, 1e-4, 32, None)  # the same core, mid-step

    core = native.Core(native.OPAQUE, 0, reenter, lambda dyn, key, step, a: a)
    pdyn = dynamics_for(PersistenceModel().fit([("a", "b")]))
    with pytest.raises(RuntimeError, match="under way"):
        core.root(pdyn).advance(pdyn, 0, None, None, None, 1e-4, 32, None)


_HASH_SEED_SCRIPT = """
import random, sys
from globe.data.records import Day
from globe.models import activity_filter
from globe.models.activity import ActivityModel
from globe.models.activity_filter import ActivityFilter, MovementEmission, moved_objects

activity_filter.COMPILED = sys.argv[1] == "compiled"
rng = random.Random(7)
objects = tuple(f"object_{i:02d}" for i in range(12))
acts = ["cook", "eat", "wash", "read"]

def day(name, n=60):
    a = [rng.choice(acts) for _ in range(n)]
    places, now = [], ["shelf"] * len(objects)
    for _ in range(n):
        for j in rng.sample(range(len(objects)), rng.choice([0, 0, 1, 3, 4, 5])):  # several at once
            now[j] = rng.choice(["shelf", "table", "sink", "counter"])
        places.append(tuple(now))
    return Day(name, tuple(range(360, 360 + 10 * n, 10)), tuple(a), tuple(places))

train = [day(f"train/{i:03d}") for i in range(20)]
test = day("test/000")
em = MovementEmission(previous_share=0.5).fit(train, objects)
flt = ActivityFilter(ActivityModel().fit([d.activities for d in train]), em)
moved = moved_objects(test, objects)
for t in range(len(test)):
    flt.update(t, None, moved[t])
    print(repr(sorted(flt.posterior().items())))
print(repr([em.log_likelihood("cook", "eat", m) for m in moved]))
"""


@pytest.mark.parametrize("path", ["python", "compiled"])
def test_beliefs_do_not_depend_on_the_hash_seed(path):
    """Several objects moving at once: their terms are summed in name order, not in the set's
    (which follows PYTHONHASHSEED), so another process gets the same numbers to the bit."""
    import os
    import subprocess
    import sys

    if path == "compiled":
        _compiled_or_skip()
    outputs = set()
    for seed in ("0", "1", "2", "3"):
        run = subprocess.run([sys.executable, "-c", _HASH_SEED_SCRIPT, path], capture_output=True, text=True,
                             env=dict(os.environ, PYTHONHASHSEED=seed), check=True)
        assert run.stdout.count("\n") > 60
        outputs.add(run.stdout)
    assert len(outputs) == 1
