"""The online assistant without HTTP: day roll-over, gaps, partial rows."""

import datetime as dt

import pytest

from globe.assembly import fit_household
from globe.data.records import Household
from globe.errors import DataError
from globe.reasoning.choice import ObjectChooser
from globe.service.assistant import Observation, OnlineAssistant, build_assistant, fill_unknown


@pytest.fixture()
def assistant(households, config):
    h = households["A"]
    fitted = fit_household(h, config)
    return OnlineAssistant(h, fitted.activity, ObjectChooser(fitted.objects), max_gap_steps=6)


def at(minute, day=0):
    return dt.datetime(2026, 3, 2) + dt.timedelta(days=day, minutes=minute)


def test_a_whole_day_including_midnight_is_one_day(assistant, households):
    day, objects = households["A"].test[0], assistant.household.objects
    for t in range(len(day)):
        assistant.observe(Observation(at(day.minutes[t]), day.activities[t], dict(zip(objects, day.locations[t]))))
    live = assistant.current_day()
    assert live.minutes == day.minutes and live.activities == day.activities and live.locations == day.locations
    assistant.observe(Observation(at(360, 1), "wake_up", {}))  # 06:00 next day: roll over and learn
    assert assistant.days_learned == len(households["A"].train) + 1 and assistant.stats()["steps_today"] == 1


def test_short_gaps_repeat_the_last_step_and_long_gaps_restart(assistant):
    learned = assistant.days_learned
    assistant.observe(Observation(at(360), "wake_up", {}))
    assistant.observe(Observation(at(400), "breakfast", {"bowl": "table#114"}))  # 3 steps missing
    day = assistant.current_day()
    assert day.minutes == (360, 370, 380, 390, 400)
    assert day.activities == ("wake_up",) * 4 + ("breakfast",)
    assert dict(zip(assistant.household.objects, day.locations[-1]))["bowl"] == "table#114"
    assistant.observe(Observation(at(600), "reading", {}))  # 19 steps missing > max_gap_steps
    assert assistant.current_day().minutes == (600,) and assistant.days_learned == learned + 1


def test_validation_names_the_field(assistant):
    assistant.observe(Observation(at(360), "wake_up", {}))
    with pytest.raises(DataError) as err:
        assistant.validate(Observation(at(350), "idle", {}))
    assert err.value.field == "time"
    with pytest.raises(DataError) as err:
        assistant.validate(Observation(at(370), "idle", {"bowl": "roof#1"}))
    assert err.value.field == "locations.bowl"


def test_prediction_has_an_action_decision(assistant, households):
    day, objects = households["A"].test[1], assistant.household.objects
    for t in range(30):
        assistant.observe(Observation(at(day.minutes[t]), day.activities[t], dict(zip(objects, day.locations[t]))))
    p = assistant.predict()
    assert p.activity is not None and 0 < p.activity_probability <= 1
    # without a fetch policy: fetch the chosen object when its probability reaches the threshold
    assert p.act == (p.object is not None and p.object_probability >= assistant.action_threshold)
    assert p.fetch_object == (p.object if p.act else None)


def test_fetch_policy_and_filter_in_the_assembled_assistant(households):
    """The assembled assistant decides fetches by expected value and reads days with missing
    labels through the activity filter: fetches have a usefulness probability above the cost
    threshold, and hiding labels changes the belief without breaking the prediction."""
    from dataclasses import replace

    from globe.config import GlobeConfig

    h = households["A"]
    cfg = GlobeConfig().with_overrides({"llm.backend": "none"})
    day = h.test[0]
    full = build_assistant(replace(h, train=h.train[:20]), cfg, None)
    hidden = build_assistant(replace(h, train=h.train[:20]), cfg, None)
    threshold = full.fetch_policy.threshold
    fetched, differs = [], 0
    for t in range(60):
        row = dict(zip(h.objects, day.locations[t]))
        full.observe(Observation(at(day.minutes[t]), day.activities[t], row))
        hidden.observe(Observation(at(day.minutes[t]), day.activities[t] if t % 3 == 0 else None, row))
        p, q = full.predict(), hidden.predict()
        if p.act:
            fetched.append(p)
        differs += p.activity_probability != q.activity_probability
        assert q.activity is not None and 0 < q.activity_probability <= 1
    assert fetched and all(p.fetch_probability > threshold and p.fetch_object for p in fetched)
    assert differs > 0  # the filter really ran on the hidden steps


def test_observations_inside_one_step_update_it(assistant):
    assistant.observe(Observation(at(360), "wake_up", {}))
    for second in range(1, 50):  # 49 more observations within the same ten minutes
        assistant.observe(Observation(at(360) + dt.timedelta(seconds=10 * second), None, {"bowl": "table#114"}))
    assistant.observe(Observation(at(365), "breakfast", {}))
    day = assistant.current_day()
    assert day.minutes == (360,) and day.activities == ("breakfast",)
    assert dict(zip(assistant.household.objects, day.locations[0]))["bowl"] == "table#114"
    assert assistant.observations == 51
    assistant.observe(Observation(at(371), None, {}))  # next step, unknown activity: carried forward
    today = assistant.current_day()
    assert today.minutes == (360, 370) and today.activities == ("breakfast", "breakfast")


def test_unknown_activities_are_filled_from_known_ones():
    assert fill_unknown([None, "a", None, None, "b", None]) == ["a", "a", "a", "a", "b", "b"]
    assert fill_unknown([None, None]) is None and fill_unknown([]) is None


def test_a_household_without_days_learns_from_scratch(households, config):
    h = households["B"]
    empty = Household(h.name, h.nodes, h.objects, (), (), "upload")
    fitted = fit_household(empty, config)
    a = OnlineAssistant(empty, fitted.activity, ObjectChooser(fitted.objects))
    assert a.predict().status == "learning" and not a.predict().act
    day = h.test[0]
    for t in range(len(day)):
        a.observe(Observation(at(day.minutes[t]), day.activities[t], dict(zip(h.objects, day.locations[t]))))
        p = a.predict()
        assert p.status == "learning" and p.act is False and p.activity is None
    a.observe(Observation(at(360, 1), day.activities[0], {}))  # the next morning: the first day is learned
    p = a.predict()
    assert a.days_learned == 1 and p.status == "ready" and p.activity in set(day.activities)


def test_policy_makes_no_fetch_without_a_basis_today(households):
    """Found by the API fuzzer: before any observation today, or when no step has a label yet,
    the policy has nothing to forecast from: no fetch, and no error."""
    from dataclasses import replace

    from globe.config import GlobeConfig

    h = households["A"]
    a = build_assistant(replace(h, train=h.train[:5]), GlobeConfig().with_overrides({"llm.backend": "none"}), None)
    assert a.fetch_policy is not None
    assert not a.predict().act
    a.observe(Observation(at(360), None, dict(zip(h.objects, h.test[0].locations[0]))))
    p = a.predict()
    assert not p.act and p.fetch_object is None and p.status == "ready"


def test_the_assistant_predicts_from_the_day_of_the_week_it_is_in():
    """With a clock model that tells weekends apart, what follows breakfast on a Saturday is what
    the training Saturdays did (relax), on a Monday what the weekdays did (work), with every label
    seen and with labels missing (the filter starts from the day's type too); the day it learns
    keeps its date."""
    from globe.config import GlobeConfig
    from tests.simulated import weekly_home

    h = weekly_home(29, 1, 1)
    cfg = GlobeConfig().with_overrides({"llm.backend": "none", "models.activity_estimator": "clock",
                                        "models.clock_day_types": "weekend", "service.fetch_decision": "threshold"})
    saturday, monday = dt.datetime(2026, 3, 7), dt.datetime(2026, 3, 9)
    for hide in (False, True):
        nexts = {}
        for start in (saturday, monday):
            a = build_assistant(h, cfg, None)
            for minute in range(360, 450, 10):  # asleep until 07:00, then breakfast until 07:20
                label = "sleeping" if minute < 420 else "breakfast"
                a.observe(Observation(start + dt.timedelta(minutes=minute), None if hide and minute == 390 else label,
                                      {}))
            belief = a.activity_belief()
            nexts[start.weekday()] = max(sorted(set(belief) - {"breakfast"}), key=belief.get)
        assert nexts == {5: "relax", 0: "work"}
    a.observe(Observation(monday + dt.timedelta(days=1, minutes=360), "sleeping", {}))
    assert a.activity_model.weekdays_[-1] == 0
