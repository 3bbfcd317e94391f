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
