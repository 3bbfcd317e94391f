"""The baselines every model must clear, counted by hand: the time-of-day mode, hour + activity
one step ahead (the Table I question), the object baseline (the most frequent use given the hour
and the activity, backing off to the activity, then to every use) and its horizon version."""

from __future__ import annotations

import numpy as np
import pytest

from globe.data.records import Day
from globe.models.baselines import HourActivityAhead, HourActivityBaseline, HourActivityObjects, TimeOfDayBaseline, mode


def day(name: str, acts: str, start: int = 420) -> Day:
    minutes = tuple(range(start, start + 10 * len(acts), 10))
    return Day(name, minutes, tuple(acts), tuple(() for _ in acts))


def test_time_of_day_is_the_share_of_days_at_each_step():
    model = TimeOfDayBaseline().fit([day("d0", "AAB"), day("d1", "ABB"), day("d2", "ABC")])
    assert model.at(1) == {"A": 1 / 3, "B": 2 / 3}
    assert model.at(5) == {}  # past the training days' last step: nothing known
    scanned = model.scan_proba(tuple("XYZ"))  # whatever happened so far
    assert [model.top(d) for d in scanned] == ["A", "B", "B"]
    assert model.top({"B": 0.5, "A": 0.5}) == "A" == mode({"B": 0.5, "A": 0.5})  # ties: the first name


def test_hour_activity_one_step_ahead_reads_the_clock_of_the_day():
    # at 07:xx A is followed by B; at 09:xx by C: the hour, not the activity alone, tells which
    train = [day(f"m{i}", "AB", 420) for i in range(3)] + [day(f"e{i}", "AC", 540) for i in range(3)]
    model = HourActivityBaseline(1).fit(train)
    morning, evening = model.scan_day(day("t0", "AA", 420)), model.scan_day(day("t1", "AA", 540))
    assert model.top(morning[1]) == "B" and model.top(evening[1]) == "C"
    assert morning[0] == {"A": 1.0}  # the first step: the training days' first activities
    assert sum(morning[1].values()) == pytest.approx(1.0)


def test_object_baseline_backs_off_from_the_hour_to_the_activity_to_every_use():
    runs = [("meal", ("kettle",), (420,))] * 3 + [("meal", ("microwave",), (1140,))] * 2 \
        + [("work", ("laptop",), (600,))]
    model = HourActivityObjects().fit(runs)
    assert model.predict("meal", minute=425) == "kettle" and model.predict("meal", minute=1150) == "microwave"
    assert model.predict("meal", minute=800) == "kettle"  # an unseen hour: the activity's most frequent
    assert model.predict("meal") == "kettle"  # no clock given: the activity's level
    assert model.predict("sleep", minute=420) == "kettle"  # an unseen activity: every use's most frequent
    dist = model.predict_proba("meal", (), 1150)
    assert sum(dist.values()) == pytest.approx(1.0) and dist["laptop"] > 0  # nothing of training gets 0
    assert model.candidates("meal") == ("kettle", "microwave") and model.recent_runs("meal", 3) == ()


def test_object_baseline_ties_go_to_the_coarser_level():
    model = HourActivityObjects().fit([("meal", ("kettle", "fridge"), (420, 420)), ("meal", ("fridge",), (1140,))])
    assert model.predict("meal", minute=420) == "fridge"  # 1:1 at 07:xx, fridge ahead over the activity


def test_last_uses_read_step_by_step_are_minutes_since_use_of_the_day_so_far():
    """A session reads each object's minutes since its last use at every step of a growing day
    (:class:`LastUses` folds the final steps once); each read equals the whole day's pass, the step
    under way read afresh (its uses may still change), a new day's list starting over."""
    import numpy as np

    from globe.models.baselines import LastUses, minutes_since_use

    objects = ("kettle", "fridge", "cup")
    rng = np.random.default_rng(1)
    minute = lambda s: 360 + 10 * s  # noqa: E731
    last = LastUses({o: i for i, o in enumerate(objects)})
    for _day in range(2):
        uses: list[frozenset[str]] = []
        for t in range(40):
            uses.append(frozenset(o for o in objects if rng.random() < 0.1))
            for _again in range(2):  # the step under way observed twice, its uses changed
                used = np.array([[o in u for o in objects] for u in uses], dtype=bool)
                want = minutes_since_use(used, [minute(s) for s in range(t + 1)])[-1]
                assert last.since(uses, t, minute).tolist() == want.tolist()
                uses[t] = frozenset(o for o in objects if rng.random() < 0.1)


def test_ahead_counts_the_share_of_references_with_the_event_and_backs_off():
    ahead = HourActivityAhead(("kettle", "fridge"), 2, shrinkage=1e-9)
    events = np.array([[[True, False], [True, True]], [[False, False], [True, False]]])
    ahead.add(["meal", "meal"], [420, 430], events)
    ahead.add(["work"], [600], np.zeros((1, 2, 2), dtype=bool))
    p = ahead.proba("meal", 425)
    assert p[0] == pytest.approx([0.5, 0.0]) and p[1] == pytest.approx([1.0, 0.5])
    assert ahead.proba("work", 900)[1] == pytest.approx([0.0, 0.0], abs=1e-6)  # the activity's level at an unseen hour
    assert ahead.proba("sleep", 0)[1] == pytest.approx([2 / 3, 1 / 3])  # an unseen activity: every reference


def test_the_clock_aware_object_model_backs_off_and_tells_day_types_and_pauses_apart():
    """P(a use within the window) of the clock-aware model: the day type and the time since the
    last use are levels under (activity, hour), each shrunk towards the one above; undated days and
    a model without the clock read the hour and the activity alone, as the baseline does."""
    import numpy as np

    from globe.models.baselines import minutes_since_use, since_band

    used = np.array([[False], [True], [False], [False]])
    since = minutes_since_use(used, [600, 610, 640, 800])
    assert since[:, 0].tolist() == [-1.0, 0.0, 30.0, 190.0]
    assert since_band(since)[:, 0].tolist() == [0, 1, 2, 3]
    weekday, weekend = np.ones((4, 1, 1), bool), np.zeros((4, 1, 1), bool)
    acts, minutes, fresh = ["relax"] * 4, [900] * 4, np.full((4, 1), -1.0)
    clock = HourActivityAhead(["kettle"], 1, clock=True)
    clock.add(acts, minutes, weekday, weekday=0, since=fresh).add(acts, minutes, weekend, weekday=6, since=fresh)
    plain = HourActivityAhead(["kettle"], 1).add(acts, minutes, weekday).add(acts, minutes, weekend)
    assert plain.proba("relax", 900)[0, 0] == pytest.approx(0.5)
    assert clock.proba("relax", 900)[0, 0] == pytest.approx(0.5)  # undated: the hour and the activity
    monday, sunday = clock.proba("relax", 900, 0, fresh[0])[0, 0], clock.proba("relax", 900, 6, fresh[0])[0, 0]
    assert monday > 0.9 and sunday < 0.1
    # a pause never seen (just used) leaves the day type's estimate as it is
    assert clock.proba("relax", 900, 0, np.array([5.0]))[0, 0] == pytest.approx(clock.proba("relax", 900, 0)[0, 0])
