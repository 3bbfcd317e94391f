"""The forecaster against hand computation and every path enumerated on a toy home, and its
invariants on HOMER+."""

from __future__ import annotations

from typing import Sequence

import numpy as np
import pytest

from globe import assembly
from globe.data.records import Day
from globe.inference.forecast import Forecaster
from globe.inference.movements import MovementModel, durations, moved_in_run
from globe.models.base import ActivityModelBase
from tests.helpers import enumerate_paths

OBJECTS = ("cup", "book")


def toy_day(name: str, acts: Sequence[str], cup: Sequence[str], book: Sequence[str]) -> Day:
    return Day(name, tuple(range(0, 10 * len(acts), 10)), tuple(acts), tuple(zip(cup, book)))


# Day 1: the cup goes to the table when b starts. Day 2: the same, then the book goes to the sink
# on b's second step. Movements at step u belong to the activity at u-1.
TOY_DAYS = (
    toy_day("train/000", "aabb", ["shelf", "shelf", "shelf", "table"], ["shelf"] * 4),
    toy_day("train/001", "abbb", ["shelf", "shelf", "table", "table"], ["shelf", "shelf", "shelf", "sink"]),
)


class ChainModel(ActivityModelBase):
    """Test double: after a, a with 0.6 and b with 0.4; after b, always b."""

    def partial_fit(self, days, weekdays=None):
        self.training_data_ = list(days)
        self.frequency_ = {"a": 1, "b": 1}
        return self

    def predict_proba(self, history):
        return {"a": 0.6, "b": 0.4} if history[-1] == "a" else {"b": 1.0}


def toy_forecaster() -> Forecaster:
    movements = MovementModel(hazard_shrinkage=1e-9, destination_shrinkage=1e-9).fit(TOY_DAYS, OBJECTS)
    return Forecaster(ChainModel().fit([]), movements, min_path_probability=0.0, max_paths=1000)


def test_durations_count_steps_since_the_run_began():
    assert durations(list("aabbba")).tolist() == [0, 1, 0, 1, 2, 0]
    assert durations(np.array([3, 3, 1, 1, 1, 3])).tolist() == [0, 1, 0, 1, 2, 0]
    assert durations([]).tolist() == []
    assert durations(list("aabbbaa"), day_starts=[0, 4, 7]).tolist() == [0, 1, 0, 1, 0, 0, 1]


def test_nothing_is_counted_across_days():
    """All days are counted at once: the step from one day's last row to the next day's first
    is not a transition (day 1 ends with the cup on the table, day 2 starts with it on the
    shelf; a one-step day between them has no transition at all)."""
    one_step = toy_day("train/009", "b", ["sink"], ["sink"])
    alone = toy_forecaster().movements
    mv = MovementModel(hazard_shrinkage=1e-9, destination_shrinkage=1e-9)
    mv.fit((TOY_DAYS[0], one_step, TOY_DAYS[1]), OBJECTS)
    for place in ("table", "sink"):  # the cup only ever went to the table (the object-level backoff)
        idx, _ = mv.destination("b", 0, mv.location_index(place))
        assert [mv.locations_[i] for i in idx] == ([] if place == "table" else ["table"])
    for a in ("a", "b"):
        for d in range(3):
            shelf, shelf_alone = (np.array([m.location_index("shelf")] * 2) for m in (mv, alone))
            assert mv.hazards(a, d, shelf) == pytest.approx(alone.hazards(a, d, shelf_alone))


def test_hazards_and_destinations_are_the_counted_rates():
    mv = toy_forecaster().movements
    shelf = np.array([mv.location_index("shelf")] * 2)
    assert mv.hazards("b", 0, shelf) == pytest.approx([1.0, 0.0], abs=1e-6)  # cup 2/2, book 0/2
    # book 1/1; the cup was never on the shelf on b's second step: backs off to (b, cup, shelf) = 2/2
    assert mv.hazards("b", 1, shelf) == pytest.approx([1.0, 1.0], abs=1e-6)
    assert mv.hazards("a", 0, shelf) == pytest.approx([0.0, 0.0], abs=1e-6)
    idx, p = mv.destination("b", 0, mv.location_index("shelf"))
    assert [mv.locations_[i] for i in idx] == ["table"] and p == pytest.approx([1.0])
    idx, p = mv.destination("b", 1, mv.location_index("shelf"))
    assert [mv.locations_[i] for i in idx] == ["sink"]


def test_destination_never_is_the_current_place():
    mv = toy_forecaster().movements
    for a in ("a", "b"):
        for j in range(2):
            for loc in ("shelf", "table", "sink"):
                idx, p = mv.destination(a, j, mv.location_index(loc))
                assert mv.location_index(loc) not in idx.tolist()
                if len(p):
                    assert p.sum() == pytest.approx(1.0)


def test_destination_rows_in_one_batch_are_the_destinations_one_by_one():
    mv = MovementModel(destination_shrinkage=0.5).fit(TOY_DAYS, OBJECTS)
    targets, real, position = mv.target_table()
    na, nl = len(mv.activities_), len(mv.locations_)
    acts = np.repeat(np.arange(na), nl * nl)
    sources = np.stack([np.tile(np.repeat(np.arange(nl), nl), na), np.tile(np.arange(nl), na * nl)], axis=1)
    rows = mv.destination_rows(acts, sources)  # every (activity, cup's place, book's place) at once
    for g, (a, places) in enumerate(zip(acts, sources)):
        for j, source in enumerate(places):
            idx, p = mv.destination(mv.activities_[a], j, int(source))
            expected = np.zeros(targets.shape[1])
            expected[position[j, idx]] = p
            np.testing.assert_array_equal(rows[g, j], expected)
            assert not rows[g, j][~real[j]].any()


def test_forward_pass_matches_hand_computation():
    """History a (step 0), locations known at steps 0 and 1, a_1 unknown. Paths: aa 0.36,
    ab 0.24, bb 0.40. The cup leaves the shelf at step 2 when a_1 = b (0.4), else at step 3 when
    a_2 = b starts (0.24); the book leaves at step 3 on b's second step (path bb, 0.4)."""
    f = toy_forecaster()
    paths = f.paths(("a",), 2)
    assert [path for _, path in paths] == [("b", "b"), ("a", "a"), ("a", "b")]
    assert [p for p, _ in paths] == pytest.approx([0.4, 0.36, 0.24])
    fc = f.forecast(("a",), [("shelf", "shelf"), ("shelf", "shelf")], horizon=1)
    assert fc.start == 1
    assert fc.activity[0] == pytest.approx({"a": 0.6, "b": 0.4})
    assert fc.activity[1] == pytest.approx({"a": 0.36, "b": 0.64})
    assert fc.departure[0] == pytest.approx([0.4, 0.0], abs=1e-6)
    assert fc.departure[1] == pytest.approx([0.24, 0.4], abs=1e-6)
    assert fc.change_probability(1) == pytest.approx([0.64, 0.4], abs=1e-6)
    where, p = fc.first_location(1)
    assert where == ["table", "sink"] and p == pytest.approx([0.64, 0.4], abs=1e-6)
    where0, p0 = fc.first_location(0)
    assert where0[0] == "table" and p0 == pytest.approx([0.4, 0.0], abs=1e-6)


def test_a_known_current_activity_is_not_propagated():
    """With a_1 = b known, the cup leaves at step 2 for sure, and the activity at step 1 is b."""
    f = toy_forecaster()
    fc = f.forecast(("a", "b"), [("shelf", "shelf"), ("shelf", "shelf")], horizon=1)
    assert fc.activity[0] == {"b": 1.0}
    assert fc.departure[0] == pytest.approx([1.0, 0.0], abs=1e-6)
    assert fc.useful_probability(1, 2) == pytest.approx([1.0, 1.0], abs=1e-6)  # the book: b's second step
    assert fc.likely_target(1, 2) == ["table", "sink"]


def test_inconsistent_lengths_are_refused():
    with pytest.raises(ValueError, match="locations"):
        toy_forecaster().forecast(("a", "a", "a"), [("shelf", "shelf")], horizon=1)


def test_forecasts_on_homer_are_distributions(households, config):
    h = households["A"]
    routine = config.models.model_copy(update={"activity_estimator": "routine"})
    fitted = assembly.forecaster(h, config, models=routine)
    assert fitted.train_s > 0
    day = h.test[0]
    for r in (1, 30, 60, 102):
        fc = fitted.forecaster.forecast(day.activities[:r], day.locations[: r + 1], horizon=5)
        for dist in fc.activity:
            assert sum(dist.values()) == pytest.approx(1.0)
        change = fc.change_probability(5)
        assert np.all(change >= -1e-12) and np.all(change <= 1 + 1e-9)
        assert np.all(fc.destination.sum(axis=2) <= fc.departure + 1e-9)
        assert np.all(np.diff([fc.change_probability(s) for s in range(6)], axis=0) >= -1e-12)  # grows with s


def test_run_end_hazards_tell_put_away_moves_apart():
    """The cup is put away when a ends (day 1) and stays when a goes on (day 2): with the run-end
    feature the two hazards are 1 and 0; without it both are the pooled 1/2."""
    days = (toy_day("train/000", "aab", ["shelf", "shelf", "table"], ["shelf"] * 3),
            toy_day("train/001", "aaa", ["shelf"] * 3, ["shelf"] * 3))
    with_end = MovementModel(hazard_shrinkage=1e-9, run_end=True).fit(days, OBJECTS)
    shelf = np.array([with_end.location_index("shelf")] * 2)
    assert with_end.hazards("a", 1, shelf, ends=True)[0] == pytest.approx(1.0, abs=1e-6)
    assert with_end.hazards("a", 1, shelf, ends=False)[0] == pytest.approx(0.0, abs=1e-6)
    without = MovementModel(hazard_shrinkage=1e-9, run_end=False).fit(days, OBJECTS)
    assert without.hazards("a", 1, shelf, ends=True)[0] == pytest.approx(0.5, abs=1e-6)
    assert without.hazards("a", 1, shelf, ends=False)[0] == pytest.approx(0.5, abs=1e-6)


def test_run_next_hazards_tell_apart_what_the_next_activity_takes_out():
    """a ends twice: the cup comes out when b starts, the book when c starts (both credited to
    a, whose interval it was). With ``run_next`` the run-end hazard knows which one starts;
    without it both objects get the pooled 1/2; an unseen switch keeps the run-end hazard."""
    days = (toy_day("train/000", "aab", ["shelf", "shelf", "table"], ["shelf"] * 3),
            toy_day("train/001", "aac", ["shelf"] * 3, ["shelf", "shelf", "table"]))
    mv = MovementModel(hazard_shrinkage=1e-9, run_end=True, run_next=True).fit(days, OBJECTS)
    shelf = np.array([mv.location_index("shelf")] * 2)
    assert mv.hazards("a", 1, shelf, ends=True, next_activity="b") == pytest.approx([1.0, 0.0], abs=1e-6)
    assert mv.hazards("a", 1, shelf, ends=True, next_activity="c") == pytest.approx([0.0, 1.0], abs=1e-6)
    assert mv.hazards("a", 1, shelf, ends=True, next_activity="a") == pytest.approx([0.5, 0.5], abs=1e-6)
    assert mv.hazards("a", 1, shelf, ends=True) == pytest.approx([0.5, 0.5], abs=1e-6)
    plain = MovementModel(hazard_shrinkage=1e-9, run_end=True).fit(days, OBJECTS)
    assert plain.hazards("a", 1, shelf, ends=True, next_activity="b") == pytest.approx([0.5, 0.5], abs=1e-6)

    class Next(ChainModel):  # after a: b with 0.3, c with 0.7
        def predict_proba(self, history):
            return {"b": 0.3, "c": 0.7} if history[-1] == "a" else {history[-1]: 1.0}

    fc = Forecaster(Next().fit([]), mv, min_path_probability=0.0, max_paths=1000)
    departure = fc.forecast(("a", "a"), [("shelf", "shelf")] * 2, horizon=0).departure
    assert departure[0] == pytest.approx([0.3, 0.7], abs=1e-6)  # each path's own switch
    pooled = Forecaster(Next().fit([]), plain, min_path_probability=0.0, max_paths=1000)
    departure = pooled.forecast(("a", "a"), [("shelf", "shelf")] * 2, horizon=0).departure
    assert departure[0] == pytest.approx([0.5, 0.5], abs=1e-6)


def test_memos_follow_the_models_when_they_learn():
    """An online assistant adds days to the models; forecasts must not come from stale memos."""
    f = toy_forecaster()
    before = f.forecast(("a",), [("shelf", "shelf"), ("shelf", "shelf")], horizon=0).departure.copy()
    extra = toy_day("train/002", "abbb", ["shelf", "shelf", "shelf", "shelf"], ["shelf"] * 4)  # b moves nothing
    f.movements.partial_fit((extra,) * 4, OBJECTS)
    after = f.forecast(("a",), [("shelf", "shelf"), ("shelf", "shelf")], horizon=0).departure
    assert after[0, 0] < before[0, 0]  # the cup now leaves with b only 2 times in 6


def test_moved_in_run_resets_when_a_run_begins():
    # movement steps u = 1..4 belong to the activity at u-1; runs begin at steps 0 and 2
    dur = np.array([0, 1, 0, 1, 2])
    change = np.array([[True, False], [False, False], [False, True], [True, False]])
    # u=1: nothing earlier; u=2: object 0 moved at u=1 (same run); u=3: new run; u=4: object 1 moved at u=3
    assert moved_in_run(dur, change).tolist() == [[0, 0], [1, 0], [0, 0], [0, 1]]


def test_run_memory_hazards_follow_what_came_out():
    """The cup comes out at a's first step and goes back at its last; the book never moves. With
    run memory, the put-away hazard is read for objects that came out in this run only."""
    days = (toy_day("train/000", "aaab", ["shelf", "table", "table", "shelf"], ["shelf"] * 4),
            toy_day("train/001", "aaab", ["table", "table", "table", "table"], ["shelf"] * 4))
    mv = MovementModel(hazard_shrinkage=1e-9, run_end=True, run_memory=True).fit(days, OBJECTS)
    table = np.array([mv.location_index("table")] * 2)
    came_out = np.array([True, False])
    assert mv.hazards("a", 2, table, ends=True, moved=came_out)[0] == pytest.approx(1.0, abs=1e-6)
    assert mv.hazards("a", 2, table, ends=True, moved=~came_out)[0] == pytest.approx(0.0, abs=1e-6)
    pooled = MovementModel(hazard_shrinkage=1e-9, run_end=True, run_memory=False).fit(days, OBJECTS)
    assert pooled.hazards("a", 2, table, ends=True, moved=came_out)[0] == pytest.approx(0.5, abs=1e-6)


def test_beam_cut_to_max_paths_keeps_the_most_probable_and_renormalises():
    """max_paths = 2: after two steps aa 0.36, ab 0.24, bb 0.40 are cut to bb and aa, renormalised."""
    movements = MovementModel(hazard_shrinkage=1e-9, destination_shrinkage=1e-9).fit(TOY_DAYS, OBJECTS)
    f = Forecaster(ChainModel().fit([]), movements, min_path_probability=0.0, max_paths=2)
    paths = f.paths(("a",), 2)
    assert [path for _, path in paths] == [("b", "b"), ("a", "a")]
    assert [p for p, _ in paths] == pytest.approx([0.4 / 0.76, 0.36 / 0.76])


@pytest.mark.parametrize("estimator", ["routine", "longest"])
@pytest.mark.parametrize("memory", [False, True])
def test_a_batch_of_forecasts_is_each_forecast_alone(households, config, estimator, memory):
    """forecast_many over many histories gives exactly the numbers of one forecast at a time,
    whether the activity at m is known or not."""
    h = households["B"]
    models = config.models.model_copy(update={"activity_estimator": estimator})
    batch_fc = assembly.forecaster(h, config, models=models, run_end=True, run_memory=memory).forecaster
    day = h.test[1]
    for known in (0, 1):
        queries = [(day.activities[: r + known], day.locations[: r + 1]) for r in range(0, 60, 3)]
        batch = batch_fc.forecast_many(queries, 5)
        alone = assembly.forecaster(h, config, models=models, run_end=True, run_memory=memory).forecaster
        for q, (acts, locs) in enumerate(queries):
            one = alone.forecast(acts, locs, 5)
            assert np.array_equal(batch[q].departure, one.departure)
            assert np.array_equal(batch[q].destination, one.destination)
            assert batch[q].activity == one.activity
        where, p = batch.first_locations(6)
        for q in (0, len(queries) - 1):
            for s in range(6):
                names, prob = batch[q].first_location(s)
                assert np.array_equal(prob, p[q, s])
                batched = [batch.locations[x] for x, pp in zip(where[q, s], p[q, s]) if pp > 0]
                assert [n for n, pp in zip(names, prob) if pp > 0] == batched


def test_shared_memos_do_not_keep_a_model_alive():
    """Nothing registers a model for good: once nothing else holds a fitted model (a
    cross-validation fold's), it and its state space are freed."""
    import gc
    import weakref

    movements = MovementModel().fit(TOY_DAYS, OBJECTS)
    model = ChainModel().fit([])
    f = Forecaster(model, movements)
    f.forecast(("a",), [("shelf", "shelf"), ("shelf", "shelf")], horizon=1)
    ref = weakref.ref(model)
    del f, model
    gc.collect()
    assert ref() is None


def _counted_one_by_one(days: Sequence[Day], objects: Sequence[str], cap: int, run_end: bool, run_memory: bool):
    """Reference counts, one transition and one object at a time: cell -> (steps seen, moves),
    and (activity, object, source) -> destinations in the order the moves happen."""
    from collections import Counter

    seen: Counter = Counter()
    moved: Counter = Counter()
    dest: dict = {}
    for day in days:
        acts, rows = day.activities, day.locations
        start, came_out = 0, set()
        for u in range(1, len(day)):
            if u - 1 > 0 and acts[u - 1] != acts[u - 2]:  # a run begins at u - 1
                start, came_out = u - 1, set()
            a, d = acts[u - 1], min(u - 1 - start, cap - 1)
            e = bool(run_end and acts[u] != a)
            now = set()
            for j in range(len(objects)):
                cell = (a, d, e, run_memory and j in came_out, j, rows[u - 1][j])
                seen[cell] += 1
                if rows[u][j] != rows[u - 1][j]:
                    moved[cell] += 1
                    dest.setdefault((a, j, rows[u - 1][j]), Counter())[rows[u][j]] += 1
                    now.add(j)
            came_out |= now
    return seen, moved, dest


@pytest.mark.parametrize("run_end,run_memory", [(False, False), (True, False), (True, True)])
def test_counts_are_those_of_every_transition_and_object(run_end, run_memory):
    """The fit counts what stays once per distinct (cell, row of places) and looks only into the
    transitions whose row changes; on random days the hazard of every cell seen is the one-by-one
    count's rate (shrinkage next to nothing) and every destination count the same, in the order
    the moves happened."""
    import random

    rng = random.Random(7)
    for _ in range(25):
        objects = tuple(f"o{i}" for i in range(rng.randint(1, 4)))
        places = [f"p{i}" for i in range(rng.randint(1, 4))]
        days = []
        for k in range(rng.randint(1, 4)):
            row, rows, acts = tuple(rng.choice(places) for _ in objects), [], []
            for _ in range(rng.randint(1, 14)):
                if rng.random() < 0.4:
                    row = tuple(rng.choice(places) if rng.random() < 0.5 else p for p in row)
                rows.append(row)
                acts.append(rng.choice("abc"))
            days.append(Day(f"d{k}", tuple(range(len(acts))), tuple(acts), tuple(rows)))
        cap = rng.choice((2, 8))
        mv = MovementModel(hazard_shrinkage=1e-12, duration_cap=cap, run_end=run_end,
                           run_memory=run_memory).fit(days, objects)
        seen, moved, dest = _counted_one_by_one(days, objects, cap, run_end, run_memory)
        for (a, d, e, m, j, place), n in seen.items():
            pair = int(np.searchsorted(mv.pairs_, j * len(mv.locations_) + mv.location_index(place)))
            rate = moved[(a, d, e, m, j, place)] / n
            assert mv.hazard_[mv.activity_index(a), d, int(e), int(m), pair] == pytest.approx(rate, rel=1e-9, abs=1e-9)
        got = [((mv.activities_[key[0]], key[1], mv.locations_[key[2]]), [(mv.locations_[x], n) for x, n in c.items()])
               for key, c in mv.destinations_.items() if len(key) == 3]
        assert got == [(k, list(c.items())) for k, c in dest.items()]


def test_movement_model_partial_fit_equals_fit():
    whole = MovementModel(run_end=True, run_memory=True, run_next=True).fit(TOY_DAYS, OBJECTS)
    parts = MovementModel(run_end=True, run_memory=True, run_next=True).fit(TOY_DAYS[:1], OBJECTS).partial_fit(
        TOY_DAYS[1:], OBJECTS)
    np.testing.assert_array_equal(whole.hazard_, parts.hazard_)
    assert whole.destinations_ == parts.destinations_
    one_by_one = MovementModel(run_end=True, run_memory=True, run_next=True).fit(TOY_DAYS[:1], OBJECTS)
    for day in TOY_DAYS[1:]:
        one_by_one.partial_fit([day], OBJECTS)
    np.testing.assert_array_equal(whole.hazard_, one_by_one.hazard_)
    assert whole.destinations_ == one_by_one.destinations_ and list(one_by_one.training_data_) == list(TOY_DAYS)
    with pytest.raises(ValueError, match="object columns"):
        parts.partial_fit(TOY_DAYS, ("cup",))


class TreeModel(ActivityModelBase):
    """Test double: three activities, each next step depending on the last two (a second-order
    chain, so paths do not merge), every probability a few bits long."""

    def partial_fit(self, days, weekdays=None):
        self.training_data_ = list(days)
        self.frequency_ = {"a": 3, "b": 2, "c": 1}
        self.classes_ = ("a", "b", "c")
        return self

    def predict_proba(self, history):
        if len(history) < 2 or history[-1] != history[-2]:
            return {"a": 0.5, "b": 0.25, "c": 0.25}
        return {history[-1]: 0.625, "a" if history[-1] != "a" else "b": 0.375}


def _brute_force(model, mv: MovementModel, history, places, horizon: int):
    """Every path of activities at steps m..m+horizon+1 enumerated, with each object's first
    departure and destination along it: the forecast by definition (movements at u belong to the
    activity at u-1, read at the object's place until it first leaves)."""
    m = len(places) - 1
    nj = len(mv.objects_)
    departure = np.zeros((horizon + 1, nj))
    destination = np.zeros((horizon + 1, nj, len(mv.locations_)))
    activity = [dict() for _ in range(horizon + 1)]
    sources = np.array([mv.location_index(x) for x in places[m]])

    for weight, path in enumerate_paths(model, history, horizon + 2 - (len(history) - m)):
        full = tuple(history) + path
        survive = np.ones(nj)
        for k in range(horizon + 1):
            u = m + 1 + k
            act = full[u - 1]
            run = 0
            while u - 2 - run >= 0 and full[u - 2 - run] == act:
                run += 1
            h = mv.hazards(act, run, sources, ends=full[u] != act, next_activity=full[u])
            leave = weight * survive * h
            departure[k] += leave
            for j in range(nj):
                idx, p = mv.destination(act, j, int(sources[j]))
                destination[k, j, idx] += leave[j] * p
            survive = survive * (1 - h)
        for k in range(horizon + 1):
            activity[k][full[m + k]] = activity[k].get(full[m + k], 0.0) + weight
    return departure, destination, activity


@pytest.mark.parametrize("known", [0, 1])
@pytest.mark.parametrize("run_next", [False, True])
def test_forecast_is_every_path_enumerated_without_pruning(known, run_next):
    """With no pruning the forward pass holds every path with its exact probability, and the
    forecast's departures, destinations and activities are the sums over them."""
    days = TOY_DAYS + (
        toy_day("train/002", "abca", ["shelf", "table", "table", "shelf"], ["shelf", "shelf", "sink", "sink"]),
        toy_day("train/003", "bbcc", ["table", "shelf", "shelf", "shelf"], ["sink", "sink", "sink", "shelf"]))
    mv = MovementModel(hazard_shrinkage=0.5, destination_shrinkage=0.5, run_end=True,
                       run_next=run_next).fit(days, OBJECTS)
    model = TreeModel().fit([])
    f = Forecaster(model, mv, min_path_probability=0.0, max_paths=100_000)
    history = ("a", "a", "b", "b")[: 3 + known]
    places = [("shelf", "shelf"), ("shelf", "sink"), ("table", "sink"), ("table", "sink")][:4]
    fc = f.forecast(history, places, horizon=2)
    departure, destination, activity = _brute_force(model, mv, history, places, 2)
    np.testing.assert_allclose(fc.departure, departure, atol=1e-12)
    np.testing.assert_allclose(fc.destination, destination, atol=1e-12)
    for got, want in zip(fc.activity, activity):
        assert got == pytest.approx(want, abs=1e-12)
    every = {path: p for p, path in enumerate_paths(model, history, 3)}
    assert {path: p for p, path in f.paths(history, 3)} == pytest.approx(every, abs=1e-15)


def test_pruned_paths_are_the_most_probable_ties_broken_by_name():
    """max_paths cuts among equally probable paths by name, whatever the last bits of the sums."""
    f = Forecaster(TreeModel().fit([]), MovementModel().fit(TOY_DAYS, OBJECTS), min_path_probability=0.0, max_paths=4)
    paths = f.paths(("c", "a"), 2)  # after (c, a): a 0.5, b 0.25, c 0.25 -> aa .3125, ab .1875 and 7 of .0625
    assert [path for _, path in paths] == [("a", "a"), ("a", "b"), ("b", "a"), ("c", "a")]
    assert sum(p for p, _ in paths) == pytest.approx(1.0)


@pytest.mark.parametrize("head", [False, True])
def test_a_known_path_forecasts_as_a_model_sure_of_it(households, config, head):
    """The oracle's forecast (:func:`forecast_known`) along the path a model is sure of equals that
    model's forecast, to the bit: persistence on HOMER+, every movement setting on."""
    from globe.inference.forecast import forecast_known

    h = households["A"]
    models = config.models.model_copy(update={"activity_estimator": "persistence"})
    fc = assembly.forecaster(h, config, models=models, run_end=True, run_memory=True, run_next=True).forecaster
    day, horizon = h.test[0], 5
    refs = range(5, len(day) - horizon - 2, 7)
    queries = [(day.activities[: r + int(head)], day.locations[: r + 1]) for r in refs]
    futures = [[acts[-1]] * (horizon + 2) for acts, _ in queries]
    theirs = fc.forecast_many(queries, horizon)
    mine = forecast_known(fc.movements, queries, futures, horizon)
    assert np.array_equal(mine.departure, theirs.departure)
    assert np.array_equal(mine.destination, theirs.destination)
    assert mine.departure[:, 0].sum() > 0


def test_a_known_path_is_followed_and_padded_at_the_day_end():
    """Told what comes next, the forecast follows it: the cup goes to the table in b's first step
    (a departure at step u belongs to the activity at u - 1)."""
    from globe.inference.forecast import forecast_known

    mv = MovementModel(run_end=True).fit(TOY_DAYS, OBJECTS)
    query = (("a",), (("shelf", "shelf"),))
    now_b = forecast_known(mv, [query], [("a", "b")], 2)  # padded: b, b, b after a
    stays_a = forecast_known(mv, [query], [("a", "a", "a", "a")], 2)
    assert now_b.departure[0, 1, 0] > 0.5 > stays_a.departure[0, 1, 0]
    assert now_b.trees.activity(0) == ({"a": 1.0}, {"b": 1.0}, {"b": 1.0})
    with pytest.raises(ValueError, match="no activity ahead"):
        forecast_known(mv, [query], [()], 2)
