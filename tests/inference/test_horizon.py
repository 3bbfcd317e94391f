"""Activity marginals and the next different activity against brute-force enumeration of every
path the model allows (predict_proba, step by step: the exact answer, no beam)."""

import numpy as np
import pytest

from globe.inference.horizon import activity_marginals, next_different
from globe.models.activity import ActivityModel
from globe.models.clock import ClockModel
from globe.models.routine import RoutineModel
from globe.models.state_space import state_space
from tests.helpers import enumerate_paths

DAYS = [("sleep", "sleep", "eat", "work", "work", "eat"), ("sleep", "eat", "eat", "work", "tv", "tv"),
        ("sleep", "sleep", "eat", "eat", "tv", "work")]


MODELS = [lambda: ClockModel(slot_minutes=20, shrinkage=2.0), lambda: RoutineModel(order=2),
          lambda: ActivityModel(estimator="witten_bell", max_order=3)]


@pytest.mark.parametrize("make", MODELS, ids=["clock", "routine", "witten_bell"])
def test_marginals_are_the_sums_over_enumerated_paths(make):
    model = make().fit(DAYS)
    space = state_space(model)
    histories = [("sleep",), ("sleep", "eat"), ("sleep", "sleep", "eat")]
    got = activity_marginals(space, np.array([space.state(h) for h in histories]), 3, floor=0.0, keep=10_000)
    for q, h in enumerate(histories):
        paths = enumerate_paths(model, h, 3)
        for j in range(3):
            want = np.zeros(len(space.labels))
            for p, path in paths:
                want[space.labels.index(path[j])] += p
            assert got[q, j] == pytest.approx(want, abs=1e-12)


@pytest.mark.parametrize("make", MODELS, ids=["clock", "routine", "witten_bell"])
def test_next_different_is_the_first_change_over_enumerated_paths(make):
    model = make().fit(DAYS)
    space = state_space(model)
    histories = [("sleep",), ("sleep", "eat"), ("sleep", "sleep", "eat", "work")]
    limits = np.array([4, 3, 2])
    current = np.array([space.code(h[-1]) for h in histories])
    got = next_different(space, np.array([space.state(h) for h in histories]), current, limits, floor=0.0, keep=10_000)
    for q, h in enumerate(histories):
        want = np.zeros(len(space.labels))
        for p, path in enumerate_paths(model, h, int(limits[q])):
            first = next((a for a in path if a != h[-1]), None)
            if first is not None:
                want[space.labels.index(first)] += p
        assert got[q] == pytest.approx(want, abs=1e-12)
        assert got[q].sum() <= 1.0 + 1e-12
