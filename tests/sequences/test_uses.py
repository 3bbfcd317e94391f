"""A use is the person taking an object: a return from a use place is never learnt or scored as one.

The simulated clock home puts each object in ``in_use#4`` for the step of its use and home again
the step after, as the importers do; HOMER+ has no use place and keeps every relocation.
"""

from __future__ import annotations

from globe import assembly
from globe.config import Deployment, GlobeConfig
from globe.data.records import Day, is_use_place
from globe.evaluation.lookahead import forecast_days
from globe.evaluation.online import day_observations, replay
from globe.evaluation.relocation import RelocationCounts, relocation_counts, true_first_locations
from globe.sequences.movements import extract_movements, moved_objects, moved_steps
from globe.sequences.runs import activity_runs
from globe.session import build_session
from tests.simulated import IN_USE, clock_home

CFG = GlobeConfig().with_overrides({"llm.backend": "none"})
OBJECTS = ("kettle", "cup")


def _day(rows: list[tuple[str, str]]) -> Day:
    n = len(rows)
    return Day("d", tuple(360 + 10 * t for t in range(n)), ("cook",) * n, tuple(rows))


def _departures(day: Day, objects: tuple[str, ...]) -> int:
    """Moves into a use place, counted straight from the rows."""
    return sum(a != b and is_use_place(a) for t in range(1, len(day)) for b, a in zip(day.locations[t - 1],
                                                                                       day.locations[t]))


def test_a_return_from_a_use_place_is_no_use_but_every_other_move_is():
    day = _day([("counter#3", "shelf#5"), (IN_USE, "table#6"), ("counter#3", "table#6"), ("counter#3", "shelf#5"),
                (IN_USE, "shelf#5"), (IN_USE, "shelf#5"), ("counter#3", "shelf#5")])
    assert moved_steps(day, OBJECTS) == [(1, ("kettle", "cup")), (3, ("cup",)), (4, ("kettle",))]
    assert [(e.step, e.obj, e.target) for e in extract_movements(day, OBJECTS)] == [
        (1, "kettle", IN_USE), (1, "cup", "table#6"), (3, "cup", "shelf#5"), (4, "kettle", IN_USE)]
    assert moved_objects(day, OBJECTS)[2] == frozenset() and moved_objects(day, OBJECTS)[6] == frozenset()
    # HOMER+'s rule: without use places, moving back is a relocation like any other
    assert not is_use_place("in_use_table#7") and is_use_place("in_use#12") and not is_use_place("kitchen#2")


def test_the_object_model_counts_one_use_per_taking_on_a_home_whose_uses_return():
    h = clock_home(days=12, test=2)
    for day in h.train:
        events = [e for run in activity_runs(day, h.objects) for e in run.events]
        assert len(events) == _departures(day, h.objects) > 0
        assert all(is_use_place(e.target) for e in events)


def test_lookahead_leaves_out_objects_in_use_at_the_reference_step():
    """The vectorised scorer and hand counting agree under the rule, and no pair is an object in
    use at r: a step after a use, the only 'change' left is the return, which is not scored."""
    h = clock_home(days=20, test=2)
    fc = assembly.forecaster(h, CFG, models=CFG.models.model_copy(update={"activity_estimator": "persistence"})
                             ).forecaster
    day = h.test[0]
    in_use_at = [r for r in range(1, len(day) - 7) if any(map(is_use_place, day.locations[r]))]
    assert in_use_at, "the simulated day must have uses"
    first, last = in_use_at[0] - 3, in_use_at[0] + 3
    run = forecast_days(fc, [day], 4, first=first, last=last)
    for s in range(4):
        total = RelocationCounts()
        for r in range(first, last + 1):
            where, p = fc.forecast(day.activities[:r], day.locations[: r + 1], 3).first_location(s)
            predicted = [w if q >= 0.2 and q > 0 and not is_use_place(here) else None
                         for w, q, here in zip(where, p, day.locations[r])]
            true = true_first_locations(day.locations, r, s)
            assert all(t is None for t, here in zip(true, day.locations[r]) if is_use_place(here))
            total = total + relocation_counts(true, predicted)
        assert run.pairs[s].counts(0.2) == total


def test_served_and_scored_uses_are_the_same_departures():
    """The session (what the service does) counts the same uses as the rows: one per taking."""
    import datetime as dt

    h = clock_home(days=12, test=2)
    session = build_session(h, CFG, Deployment.configured(CFG, "ngram"), None)
    day = h.test[0]
    replay(session, [(day.name, t, obs) for t, obs in day_observations(h, day, dt.date(2026, 3, 2))])
    assert session.fetch_report().used_objects == _departures(day, h.objects) > 0
