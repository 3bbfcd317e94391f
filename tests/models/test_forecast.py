"""The forecaster against hand computation on a toy home, and its invariants on HOMER+."""

from __future__ import annotations

from typing import Sequence

import numpy as np
import pytest

from globe import assembly
from globe.data.records import Day
from globe.models.base import ActivityModelBase
from globe.models.forecast import Forecaster, MovementModel, durations, moved_in_run

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

    def partial_fit(self, days):
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
    mv = MovementModel(hazard_shrinkage=1e-9, destination_shrinkage=1e-9).fit((TOY_DAYS[0], one_step, TOY_DAYS[1]), OBJECTS)
    for place in ("table", "sink"):  # the cup only ever went to the table (the object-level backoff)
        idx, _ = mv.destination("b", 0, mv.location_index(place))
        assert [mv.locations_[i] for i in idx] == ([] if place == "table" else ["table"])
    for a in ("a", "b"):
        for d in range(3):
            shelf = np.array([mv.location_index("shelf")] * 2)
            assert mv.hazards(a, d, shelf) == pytest.approx(alone.hazards(a, d, np.array([alone.location_index("shelf")] * 2)))


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
    assert pooled.forecast(("a", "a"), [("shelf", "shelf")] * 2, horizon=0).departure[0] == pytest.approx([0.5, 0.5], abs=1e-6)


def test_memos_follow_the_models_when_they_learn():
    """An online assistant adds days to the models; forecasts must not come from stale memos."""
    f = toy_forecaster()
    before = f.forecast(("a",), [("shelf", "shelf"), ("shelf", "shelf")], horizon=0).departure.copy()
    extra = toy_day("train/002", "abbb", ["shelf", "shelf", "shelf", "shelf"], ["shelf"] * 4)  # b moves nothing
    f.movements.fit(TOY_DAYS + (extra,) * 4, OBJECTS)
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
                assert [n for n, pp in zip(names, prob) if pp > 0] == [batch.locations[x] for x, pp in zip(where[q, s], p[q, s]) if pp > 0]


def test_shared_memos_do_not_keep_a_model_alive():
    """The registries of activity paths and dynamics are keyed weakly by the model: once nothing
    else holds a fitted model (a cross-validation fold's), it and its memos are freed."""
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
        mv = MovementModel(hazard_shrinkage=1e-12, duration_cap=cap, run_end=run_end, run_memory=run_memory).fit(days, objects)
        seen, moved, dest = _counted_one_by_one(days, objects, cap, run_end, run_memory)
        for (a, d, e, m, j, place), n in seen.items():
            pair = int(np.searchsorted(mv._pairs, j * len(mv.locations_) + mv.location_index(place)))
            assert mv.hazard_[mv.activity_index(a), d, int(e), int(m), pair] == pytest.approx(moved[(a, d, e, m, j, place)] / n,
                                                                                               rel=1e-9, abs=1e-9)
        got = [((mv.activities_[key[0]], key[1], mv.locations_[key[2]]), [(mv.locations_[x], n) for x, n in c.items()])
               for key, c in mv._dest.items() if len(key) == 3]
        assert got == [(k, list(c.items())) for k, c in dest.items()]


# -- the compiled forecaster (globe.models._forecast_core) against the numpy one, to the bit -------

from contextlib import contextmanager  # noqa: E402

from globe.models import forecast as forecast_module  # noqa: E402
from globe.models.forecast import Forecasts, TreeLevel, first_locations  # noqa: E402

compiled_only = pytest.mark.skipif(forecast_module._native is None,
                                   reason="globe.models._forecast_core was not compiled in this install")
SETTINGS = ((False, False, False), (True, False, False), (True, False, True), (True, True, False), (True, True, True))


@contextmanager
def forecaster_path(compiled: bool):
    """Run the compiled forecaster, or the numpy and Python one (the reference)."""
    before = forecast_module.COMPILED
    forecast_module.COMPILED = compiled
    try:
        yield
    finally:
        forecast_module.COMPILED = before


def same_bits(x: np.ndarray, y: np.ndarray) -> bool:
    x, y = np.asarray(x), np.asarray(y)
    return x.dtype == y.dtype and x.shape == y.shape and x.tobytes() == y.tobytes()


def assert_same_forecasts(a: Forecasts, b: Forecasts) -> None:
    """Every number of two batches of forecasts, to the bit: the activity paths' levels (local ids
    numbered in the same order too), the departures and destinations, the first new places."""
    assert a.trees.names == b.trees.names and len(a.trees.levels) == len(b.trees.levels)
    for k, (la, lb) in enumerate(zip(a.trees.levels, b.trees.levels)):
        for name in TreeLevel.__slots__:
            assert same_bits(getattr(la, name), getattr(lb, name)), f"level {k}: {name}"
    for name in ("start", "departure", "destination", "targets", "real"):
        assert same_bits(getattr(a, name), getattr(b, name)), name
    steps = a.departure.shape[1]
    for horizons in (1, steps):
        for x, y in zip(a.first_locations(horizons), b.first_locations(horizons)):
            assert same_bits(x, y)


def fresh_forecasters(h, config, models, **kwargs):
    """Forecasters of every movement setting over one freshly fitted activity model (no memo
    shared with another path), as cross-validation makes them."""
    la = config.lookahead
    activity = assembly.activity_model(models).fit([d.activities for d in h.train])
    options = {"min_path_probability": la.min_path_probability, "max_paths": la.max_paths, **kwargs}
    return lambda setting: Forecaster(activity, assembly.movement_model(la, *setting).fit(h.train, h.objects), **options)


def both_paths(factory, queries, horizon: int, settings=SETTINGS) -> None:
    """Forecast ``queries`` with every movement setting on each path (``factory()``: fresh models
    per path; later settings reuse the first one's activity paths, as cross-validation does)
    and compare."""
    out: dict[bool, list[Forecasts]] = {}
    for compiled in (False, True):
        with forecaster_path(compiled):
            make, trees, runs = factory(), None, []
            for setting in settings:
                fc = make(setting)
                if trees is None:
                    trees = fc.trees([tuple(a) for a, _ in queries], [len(loc) - 1 for _, loc in queries], horizon)
                runs.append(fc.forecast_many(queries, horizon, trees=trees))
            out[compiled] = runs
    for ref, fast in zip(out[False], out[True]):
        assert_same_forecasts(ref, fast)


@compiled_only
@pytest.mark.parametrize("name", ["A", "B", "C"])
@pytest.mark.parametrize("estimator", ["routine", "longest", "persistence"])
def test_compiled_forecasts_are_the_reference_on_homer(households, config, name, estimator):
    """Real queries of two test days (the activity at m unknown, as the lookahead asks, and known,
    as the fetch policy asks), every movement setting: the same bits on both paths."""
    h = households[name]
    models = config.models.model_copy(update={"activity_estimator": estimator})
    for known in (0, 1):
        queries = [(day.activities[: r + known], day.locations[: r + 1]) for day in h.test[:2] for r in range(1, 100, 4)]
        both_paths(lambda: fresh_forecasters(h, config, models), queries, 5)


@compiled_only
def test_compiled_forecasts_are_the_reference_on_filtered_histories(households, config):
    """The missing-label lookahead forecasts from the filter's most probable histories (several per
    reference step, unlike the true one): the same bits on both paths."""
    from globe.evaluation.missing_labels import FilterSetup, day_mask, filtered_references
    from globe.evaluation.tuning import Selection

    h = households["A"]
    models = config.models.model_copy(update={"activity_estimator": "routine"})
    fc = config.filter
    evidence = {"boundary": fc.emission_boundary, "previous_share": fc.emission_previous_share, "weight": fc.emission_weight,
                "switch": fc.emission_switch}
    activity = assembly.activity_model(models).fit([d.activities for d in h.train])
    emission = assembly.movement_emission(fc, **evidence).fit(h.train, h.objects)
    setup = FilterSetup(h, models, activity, emission, None, Selection(evidence), 0.0)
    queries = []
    for day in h.test[:2]:
        for r, mix in filtered_references(setup, fc, day, day_mask(fc, h.name, day, 0.25), 6, 1, 102, 2):
            queries += [(prefix, day.locations[: r + 1]) for prefix, _ in mix]
    assert len({q[0] for q in queries}) > len(queries) // 2  # mostly distinct histories
    both_paths(lambda: fresh_forecasters(h, config, models), queries, 5, SETTINGS[2:])


@compiled_only
@pytest.mark.parametrize("update,options", [
    ({"routine_order": 1, "routine_time_weight": 0.0}, {}),  # one run label; no time of day (step-free memo)
    ({"routine_order": 4}, {"max_paths": 2, "min_path_probability": 0.0}),  # every beam cut to its most likely
    ({}, {"min_path_probability": 0.6}),  # mostly nothing above the floor: the most probable extension
    ({}, {"memo_size": 40}),  # the compiled states start over between forecasts
])
def test_compiled_forecasts_are_the_reference_at_the_edges(households, config, update, options):
    """Other orders, pruning and memo sizes; a day start (no activity, one row of places), a
    history with an activity never seen in training, horizon 0 and 1."""
    h = households["B"]
    models = config.models.model_copy(update={"activity_estimator": "routine", **update})
    day = h.test[0]
    odd = tuple(day.activities[:20]) + ("<never seen>",) * 3
    for known in (0, 1):
        queries = [(day.activities[: r + known], day.locations[: r + 1]) for r in (0, 1, 2, 30, 60)]
        queries += [(odd[: 23 - 1 + known], day.locations[:23])]
        for horizon in (0, 1, 5):
            both_paths(lambda: fresh_forecasters(h, config, models, **options), queries, horizon, SETTINGS[-1:])


@compiled_only
def test_compiled_paths_are_the_reference(households, config):
    """:meth:`Forecaster.paths` (one history) on both paths, and one forecaster switching paths
    between batches (the names and memos they share stay consistent)."""
    h = households["C"]
    models = config.models.model_copy(update={"activity_estimator": "routine"})
    day = h.test[1]
    out = {}
    for compiled in (False, True):
        with forecaster_path(compiled):
            fc = fresh_forecasters(h, config, models)((True, True, True))
            out[compiled] = [fc.paths(day.activities[:r], 6) for r in (0, 5, 40, 80)]
    assert out[False] == out[True] and all(len(p) > 1 for p in out[True][1:])
    fc = fresh_forecasters(h, config, models)((True, True, True))
    queries = [(day.activities[:r], day.locations[: r + 1]) for r in range(1, 90, 7)]
    runs = []
    for compiled in (True, False, True, False):
        with forecaster_path(compiled):
            runs.append(fc.forecast_many(queries[len(runs):], 5))
            runs[-1] = (runs[-1], fc.forecast_many(queries[len(runs) - 1:], 5))[1]
    with forecaster_path(False):
        alone = fresh_forecasters(h, config, models)((True, True, True))
        for k, run in enumerate(runs):
            assert_same_forecasts(alone.forecast_many(queries[k:], 5), run)


class TieModel(ChainModel):
    """Test double with ties: after a, a and b with 0.4 each (the larger name, b, is the most
    probable), c with 0.2; after b or c, b or c with 0.5 each."""

    def predict_proba(self, history):
        return {"a": 0.4, "b": 0.4, "c": 0.2} if history[-1] == "a" else {"c": 0.5, "b": 0.5}


class SilentModel(ChainModel):
    """Test double with nothing to say after b (the activity then stays)."""

    def predict_proba(self, history):
        return {"a": 0.5, "b": 0.5} if history[-1] == "a" else {}


@compiled_only
@pytest.mark.parametrize("model", [ChainModel, TieModel, SilentModel])
def test_compiled_toy_forecasts_are_the_reference(model):
    """Toy homes (models with their own predict_proba: the compiled pass asks them per new state)
    on both paths, with and without pruning (with a floor of 0.5 only the most probable
    extension survives, and ties go to the larger name)."""
    for max_paths, floor in ((1000, 0.0), (2, 0.0), (1000, 0.5)):
        out = {}
        for compiled in (False, True):
            with forecaster_path(compiled):
                mv = MovementModel(hazard_shrinkage=1e-9, destination_shrinkage=1e-9).fit(TOY_DAYS, OBJECTS)
                f = Forecaster(model().fit([]), mv, min_path_probability=floor, max_paths=max_paths)
                out[compiled] = f.forecast_many([(("a",) * n, [("shelf", "shelf")] * (n + 1)) for n in range(1, 5)], 3)
        assert_same_forecasts(out[False], out[True])


@compiled_only
def test_compiled_first_locations_are_numpys():
    """Running sums over steps and the first largest target (NaN first), as np.cumsum and np.argmax."""
    rng = np.random.default_rng(3)
    destination = rng.choice([0.0, 0.25, 0.5, 1e-300, 0.1, 0.2], size=(40, 7, 5, 4))  # many ties
    destination[3, 2, 1, 2] = np.nan
    targets = rng.integers(0, 9, size=(5, 4))
    for horizons in (0, 1, 3, 7, 9):
        with forecaster_path(False):
            ref = first_locations(destination, targets, horizons)
        fast = first_locations(destination, targets, horizons)
        assert same_bits(ref[0], fast[0]) and same_bits(ref[1], fast[1])


@compiled_only
def test_the_compiled_forecaster_refuses_bad_inputs():
    """Every index the compiled loops read is checked first: a bad input raises, never reads
    out of bounds."""
    native = forecast_module._native
    nj, nq = 2, 1
    hazard = np.full(1 * 1 * 1 * 1 * 2, 0.5)
    empty = np.zeros(0)
    model = (hazard, np.full(nj, 0.1), np.zeros(0, dtype=np.int64), empty, empty, np.zeros((nq, nj), dtype=np.int64),
             np.ones((nq, nj), dtype=bool), np.zeros((nq, nj), dtype=bool))
    one = np.zeros(1, dtype=np.int64)
    nodes = (one, one, one, np.zeros(1, dtype=bool), np.zeros(1, dtype=bool), one, one, np.ones(1), one)
    args = [(1, 1, 1, 1, 2, nj, nq, 2), 2.0, model, nodes, np.ones((1, nj)), np.empty((1, nj)), np.zeros((1, nj)),
            np.zeros((nq, 2, nj)), 0]
    native.level(*args)  # well formed
    bad_cells = model[:5] + (np.full((nq, nj), 2, dtype=np.int64),) + model[6:]
    bad_parent = nodes[:6] + (np.array([1]),) + nodes[7:]
    bad_activity = nodes[:1] + (np.array([1]),) + nodes[2:]
    for k, value in ((2, bad_cells), (3, bad_parent), (3, bad_activity), (8, 2), (7, np.zeros((nq, 1, nj)))):
        with pytest.raises(ValueError):
            native.level(*[value if i == k else a for i, a in enumerate(args)])
    with pytest.raises(ValueError, match="float64"):
        native.level(*[nodes[:7] + (np.ones(1, dtype=np.float32),) + nodes[8:] if i == 3 else a for i, a in enumerate(args)])
    index = np.full(1 * nj * 3, -1, dtype=np.int64)  # no destination row filled in
    with pytest.raises(ValueError, match="not filled"):
        native.destinations((nq, 2, nj, 1, 3), np.ones((1, nj)), one, one, np.zeros((nq, nj), dtype=np.int64), index,
                            np.zeros((0, 1)), np.zeros((nq, 2, nj, 1)), 0)
    paths = native.Paths(native.ROUTINE, 2, False, {}, [], "<day>")
    with pytest.raises(ValueError, match="root"):
        paths.beams(np.array([5], dtype=np.int64), 1, 0.001, 4, lambda *a: 0.5, lambda *a: ({}, 0.0), lambda *a: {})
    with pytest.raises(ValueError):
        native.Paths(native.ROUTINE, 0, False, {}, [], "<day>")
    with pytest.raises(ZeroDivisionError):  # an error in the model's own code comes through
        roots = np.frombuffer(paths.roots([("a", "b")]), dtype=np.int64)
        paths.beams(roots, 1, 0.001, 4, lambda *a: 1 / 0, lambda *a: ({}, 0.0), lambda *a: {})
