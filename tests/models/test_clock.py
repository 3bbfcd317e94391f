"""The clock model: the next activity from the current one and the time slot, shrunk by hand."""

import numpy as np
import pytest

from globe.inference.paths import ActivityPaths
from globe.models.baselines import PersistenceModel
from globe.models.clock import ClockModel

# Two slots of 20 minutes on a 10-minute grid: steps 0-1 are slot 0, steps 2-3 slot 1.
DAYS = [("sleep", "sleep", "eat", "work"), ("sleep", "eat", "eat", "work"), ("sleep", "sleep", "eat", "eat")]


def by_hand(previous: str, slot: int, k: float) -> dict[str, float]:
    labels = ("eat", "sleep", "work")
    counts = {"eat": 5, "sleep": 5, "work": 2}
    unigram = {b: (counts[b] + 1) / (12 + 3) for b in labels}
    pairs = {("sleep", "sleep"): {0: 2}, ("sleep", "eat"): {0: 1, 1: 2}, ("eat", "work"): {1: 2},
             ("eat", "eat"): {1: 2}}
    row = {b: sum(pairs.get((previous, b), {}).values()) for b in labels}
    bigram = {b: (row[b] + k * unigram[b]) / (sum(row.values()) + k) for b in labels}
    here = {b: pairs.get((previous, b), {}).get(slot, 0) for b in labels}
    return {b: (here[b] + k * bigram[b]) / (sum(here.values()) + k) for b in labels}


@pytest.mark.parametrize("history, previous, slot", [(("sleep",), "sleep", 0), (("sleep", "sleep"), "sleep", 1),
                                                      (("sleep", "eat", "eat"), "eat", 1)])
def test_next_step_is_the_shrunk_slot_bigram(history, previous, slot):
    model = ClockModel(slot_minutes=20, shrinkage=2.0).fit(DAYS)
    got = model.predict_proba(history)
    want = by_hand(previous, slot, 2.0)
    assert got.keys() == want.keys()
    for b in want:
        assert got[b] == pytest.approx(want[b])
    assert sum(got.values()) == pytest.approx(1.0)


def test_no_probability_is_zero_or_one_and_the_first_step_follows_the_days_starts():
    model = ClockModel(slot_minutes=20, shrinkage=2.0).fit(DAYS)
    first = model.predict_proba(())
    assert max(first, key=first.get) == "sleep"
    for t in range(4):
        for dist in model.scan_proba(DAYS[0])[: t + 1]:
            assert all(0.0 < p < 1.0 for p in dist.values())


def test_paths_over_the_clock_model_are_the_chain_marginals():
    """Forward with no pruning: P(activity at m + k) equals the matrix product of the slot tables."""
    model = ClockModel(slot_minutes=20, shrinkage=2.0).fit(DAYS)
    paths = ActivityPaths(model, min_path_probability=0.0, max_paths=10_000)
    trees = paths.trees(paths.roots([("sleep",)], [1]), 2)
    got = trees.activity_matrix()[0]
    labels = [trees.names[i] for i in range(len(trees.names))]
    p = np.array([1.0 if a == "sleep" else 0.0 for a in labels])
    for k in range(3):
        step = 1 + k  # predicting the activity at step 1 + k from the one before it
        table = np.array([[by_hand(a, step * 10 // 20, 2.0)[b] for b in labels] for a in labels])
        p = p @ table
        assert got[k] == pytest.approx(p)


@pytest.mark.parametrize("make", [lambda: ClockModel(slot_minutes=20, shrinkage=2.0), lambda: PersistenceModel()])
def test_a_whole_path_at_once_is_the_walk_one_step_at_a_time(make):
    """The clock and persistence spaces number a day's states in one go; the oracle is the
    generic walk (root, then the child after each activity), unseen labels included."""
    from globe.models.state_space import StateSpace

    space = make().fit(DAYS).states()
    for day in [*DAYS, ("sleep", "dance", "eat", "dance", "work"), ("eat",), ()]:
        assert np.array_equal(space.path(day), StateSpace.path(space, day))
        assert [space.labels[c] if c >= 0 else None for c in space.last(space.path(day)).tolist()] == \
            [None, *day[:-1]][: len(day)]


# DAYS[0] a Monday, DAYS[1] a Saturday, DAYS[2] a Sunday: under "weekend", type 1 and type 2.
WEEKDAYS = [0, 5, 6]


def typed_by_hand(previous: str | None, slot: int, k: float) -> dict[str, float]:
    """The weekend level (DAYS[1:]) shrunk to every day's row, by hand."""
    labels = ("eat", "sleep", "work")
    if previous is None:  # the first step: weekend starts are sleep, sleep
        counts = {"eat": 5, "sleep": 5, "work": 2}
        unigram = {b: (counts[b] + 1) / 15 for b in labels}
        below = {b: ((3 if b == "sleep" else 0) + k * unigram[b]) / (3 + k) for b in labels}
        here = {"eat": 0, "sleep": 2, "work": 0}
    else:
        below = by_hand(previous, slot, k)
        # the weekend days' pairs: (sleep, eat) slot 0; (eat, eat) slot 1; (eat, work) slot 1;
        # (sleep, sleep) slot 0; (sleep, eat) slot 1; (eat, eat) slot 1
        pairs = {("sleep", "eat"): {0: 1, 1: 1}, ("eat", "eat"): {1: 2}, ("eat", "work"): {1: 1},
                 ("sleep", "sleep"): {0: 1}}
        here = {b: pairs.get((previous, b), {}).get(slot, 0) for b in labels}
    return {b: (here[b] + k * below[b]) / (sum(here.values()) + k) for b in labels}


@pytest.mark.parametrize("history, previous, slot", [((), None, 0), (("sleep",), "sleep", 0),
                                                      (("sleep", "sleep"), "sleep", 1),
                                                      (("sleep", "eat", "eat"), "eat", 1)])
def test_a_day_type_is_its_own_counts_shrunk_to_every_days_slot(history, previous, slot):
    model = ClockModel(slot_minutes=20, shrinkage=2.0, day_types="weekend").fit(DAYS, WEEKDAYS)
    for weekday in (5, 6):
        got = model.predict_proba(history, weekday)
        want = typed_by_hand(previous, slot, 2.0)
        assert got == pytest.approx(want)
    if previous is not None:  # a day of no known date, and the model without day types: the level below
        assert model.predict_proba(history) == pytest.approx(by_hand(previous, slot, 2.0))
        assert ClockModel(slot_minutes=20, shrinkage=2.0).fit(DAYS, WEEKDAYS).predict_proba(history, 5) == \
            pytest.approx(by_hand(previous, slot, 2.0))


def test_the_day_type_travels_with_the_state_through_paths_and_the_filter():
    """Forward from a Saturday's root with no pruning: the marginals are the product of the
    weekend tables; the filter with every label visible gives the scan of that Saturday."""
    from globe.data.records import Day
    from globe.inference.activity_filter import ActivityFilter, filtered_beliefs

    model = ClockModel(slot_minutes=20, shrinkage=2.0, day_types="weekend").fit(DAYS, WEEKDAYS)
    paths = ActivityPaths(model, min_path_probability=0.0, max_paths=10_000)
    trees = paths.trees(paths.roots([("sleep",)], [1], [5]), 2)
    labels = [trees.names[i] for i in range(len(trees.names))]
    p = np.array([1.0 if a == "sleep" else 0.0 for a in labels])
    for k, got in enumerate(trees.activity_matrix()[0]):
        step = 1 + k
        p = p @ np.array([[typed_by_hand(a, step * 10 // 20, 2.0)[b] for b in labels] for a in labels])
        assert got == pytest.approx(p)
    one_step = {path[0]: p for p, path in paths.paths(("sleep",), 1, 5)}
    assert one_step == pytest.approx(model.predict_proba(("sleep",), 5))
    assert model.confidence(("sleep",), 5) == pytest.approx(max(one_step.values()))
    assert model.predict(("sleep",), 5) == max(one_step, key=one_step.get)
    day = Day("test/2024-01-06", (360, 370, 380, 390), DAYS[0], ((),) * 4)  # a Saturday
    rows, _ = filtered_beliefs(ActivityFilter(model), [day], [[True] * 4], ())
    scan = model.scan_proba(day.activities, day.weekday)
    space = model.states()
    assert rows is not None
    for t, row in enumerate(rows[0]):
        assert dict(zip(space.labels, row.tolist())) == pytest.approx({a: scan[t].get(a, 0.0) for a in space.labels})


def test_a_whole_path_with_a_day_type_is_the_walk_and_the_weekdays_are_saved_with_the_model():
    from globe.models.io import model_from_dict, model_to_dict
    from globe.models.state_space import StateSpace

    model = ClockModel(slot_minutes=20, shrinkage=2.0, day_types="weekday").fit(DAYS, WEEKDAYS)
    space = model.states()
    for weekday in (None, 0, 6):
        assert np.array_equal(space.path(DAYS[0], weekday), StateSpace.path(space, DAYS[0], weekday))
        assert [space.labels[c] for c in space.last(space.path(DAYS[0], weekday))[1:].tolist()] == list(DAYS[0][:-1])
    again = model_from_dict(model_to_dict(model))
    assert again.weekdays_ == WEEKDAYS
    assert again.scan_proba(DAYS[1], 5) == model.scan_proba(DAYS[1], 5) != model.scan_proba(DAYS[1])
    for wrong in ([0, 1], [0, 1, 7], [0, True, None]):
        with pytest.raises(ValueError, match="3 days but weekdays"):
            ClockModel().fit(DAYS, wrong)


def test_the_floor_keeps_every_transition_above_its_share_of_the_unigram():
    """After an activity seen hundreds of times, a transition never seen gets k P(b) / n from
    shrinkage alone; the floor puts it at no less than floor x the add-one unigram, the rows
    still sum to one, and floor 0 is the model as it was."""
    days = [["sleep"] * 60 + ["eat"] * 3 + ["work"] * 40 for _ in range(20)] + [["sleep"] * 50 + ["walk"] * 53]
    plain = ClockModel(shrinkage=2.0).fit(days)
    floored = plain.with_prediction_params(floor=0.01)
    history = ["sleep"] * 61 + ["eat"]  # eat -> walk was never seen
    p, q = plain.predict_proba(history), floored.predict_proba(history)
    counts = {a: sum(d.count(a) for d in days) for a in plain.classes_}
    unigram = (counts["walk"] + 1) / (sum(counts.values()) + len(counts))
    assert p["walk"] < 1e-3 and q["walk"] >= 0.01 * unigram - 1e-12
    assert abs(sum(q.values()) - 1) < 1e-9
    assert ClockModel(shrinkage=2.0, floor=0.0).fit(days).predict_proba(history) == p
    with pytest.raises(Exception, match="floor"):
        ClockModel(floor=1.0).fit(days)


def test_by_the_time_of_day_alone_every_current_activity_gets_the_slots_pooled_row():
    """``by_activity=False``: P(b | slot) = (n(. -> b, slot) + k P(b)) / (n(. -> ., slot) + k),
    by hand, whatever is under way; the first step is the model's as before; on a weekend day
    its own pooled counts shrink to that row. Its mode is the time-of-day baseline's."""
    k, labels = 2.0, ("eat", "sleep", "work")
    unigram = {"eat": 6 / 15, "sleep": 6 / 15, "work": 3 / 15}
    in_slot = {0: {"eat": 1, "sleep": 2, "work": 0}, 1: {"eat": 4, "sleep": 0, "work": 2}}  # pairs ending in the slot
    model = ClockModel(slot_minutes=20, shrinkage=k, by_activity=False).fit(DAYS)
    for history, slot in ((("sleep",), 0), (("eat",), 0), (("sleep", "sleep"), 1), (("work", "work", "work"), 1)):
        n = sum(in_slot[slot].values())
        want = {b: (in_slot[slot][b] + k * unigram[b]) / (n + k) for b in labels}
        assert model.predict_proba(history) == pytest.approx(want)
    plain = ClockModel(slot_minutes=20, shrinkage=k).fit(DAYS)
    assert model.predict_proba(()) == pytest.approx(plain.predict_proba(()))
    typed = ClockModel(slot_minutes=20, shrinkage=k, by_activity=False, day_types="weekend").fit(DAYS, WEEKDAYS)
    weekend = {"eat": 3, "sleep": 0, "work": 1}  # DAYS[1:]'s pairs ending in slot 1
    below = {b: (in_slot[1][b] + k * unigram[b]) / (6 + k) for b in labels}
    want = {b: (weekend[b] + k * below[b]) / (4 + k) for b in labels}
    for history in (("sleep", "sleep"), ("sleep", "eat", "eat")):
        assert typed.predict_proba(history, 6) == pytest.approx(want)
    assert plain.predict_proba(("sleep", "sleep")) != model.predict_proba(("sleep", "sleep"))
