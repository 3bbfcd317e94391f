"""A household's session without HTTP: the clock, the step, the filter, the fetch rule, learning."""

from __future__ import annotations

import datetime as dt
from dataclasses import replace

import numpy as np
import pytest

from globe.config import Deployment, GlobeConfig
from globe.data.records import Household
from globe.errors import ConfigError, DataError, UnknownLabelError
from globe.evaluation.online import day_observations, replay
from globe.inference.activity_filter import as_dicts
from globe.session import Observation, build_session
from globe.session.grid import DayGrid
from tests.simulated import IN_USE, clock_home, weekly_home

CFG = GlobeConfig().with_overrides({"llm.backend": "none"})
MONDAY = dt.date(2026, 3, 2)


def at(minute: int, day: int = 0) -> dt.datetime:
    return dt.datetime.combine(MONDAY, dt.time()) + dt.timedelta(days=day, minutes=minute)


def session_of(h: Household, learn: bool = False, **kw):
    return build_session(h, CFG, Deployment.configured(CFG, "ngram"), None, learn=learn, **kw)


def feed(session, h: Household, day, rows=None, visible=None, date=MONDAY):
    records, _ = replay(session, [(day.name, t, obs) for t, obs in day_observations(h, day, date, rows=rows,
                                                                                     visible=visible)])
    return records


@pytest.fixture(scope="module")
def home(households):
    h = households["A"]
    return replace(h, train=h.train[:20])


def test_the_grid_is_the_households_own():
    """HOMER+'s days run from 06:00 in 10-minute steps to 24:00: 00:30 still belongs to the day
    before; a configured step that disagrees is an error at build time, not a re-slicing."""
    h = weekly_home(10, 1)
    s = session_of(h)
    assert s.grid == DayGrid(10, 360, 109)
    assert s.grid.place(at(18 * 60)) == (MONDAY.isoformat(), 72)
    assert s.grid.place(at(24 * 60 + 30)) == (MONDAY.isoformat(), 111)
    with pytest.raises(ConfigError, match="step_minutes = 5"):
        build_session(h, CFG.with_overrides({"service.step_minutes": 5}), Deployment.configured(CFG), None)
    with pytest.raises(ConfigError, match="day_start_minute"):
        build_session(h, CFG.with_overrides({"service.day_start_minute": 0}), Deployment.configured(CFG), None)
    cold = build_session(replace(h, train=()), CFG.with_overrides({"service.step_minutes": 5}),
                         Deployment.configured(CFG), None)
    assert cold.grid.step_minutes == 5 and cold.grid.day_start_minute == 360


def test_a_day_starts_on_the_clock_not_where_the_robot_starts(home):
    """One observation at 18:00 is step 72 (the service once made it step 0, the model's 06:00
    answer): the belief is the filter's over 72 steps nobody saw and the label at 72."""
    s = session_of(home)
    day = home.test[0]
    label = day.activities[72]
    s.observe(Observation(at(18 * 60), label, {}))
    d = s.decide()
    assert (d.day, d.step) == (MONDAY.isoformat(), 73)
    flt = s._filter
    expected = flt.update(flt.start(1, weekdays=[0]), 72, [label], [None])
    assert s.belief() == as_dicts(flt.predictive(expected), flt.labels)[0]
    morning = s.activity_model.predict_proba((label,))  # what the day's first step would say
    assert s.belief() != morning


def test_a_whole_day_from_its_start_is_the_models_own_prediction(home):
    """Every row of a test day observed: each step's belief is the activity model's
    ``scan_proba`` (what Table I scores), and 24:00 belongs to the same day."""
    s = session_of(home)
    day = home.test[0]
    scan = s.activity_model.scan_proba(day.activities)
    records = feed(s, home, day)
    assert [r.decision.step for r in records] == list(range(1, len(day) + 1))
    beliefs = []
    s2 = session_of(home)
    for _, obs in day_observations(home, day, MONDAY):
        s2.observe(obs)
        beliefs.append(s2.belief())
    assert beliefs[:-1] == scan[1:]
    assert s2.day == MONDAY.isoformat() and s2.step == len(day) - 1


def test_steps_nobody_observed_stay_unknown(home):
    """An hour's gap: the steps in it have no label and are not looked at; the first step after
    it shows no movement to the filter, and its one-step prediction is not scored."""
    s = session_of(home)
    day = home.test[1]
    rows = [t for t in range(0, 30) if not 10 <= t < 16]
    feed(s, home, day, rows=rows)
    assert [s.observed(t) for t in range(9, 17)] == [True] + [False] * 6 + [True]
    assert all(s.observed_activity(t) is None for t in range(10, 16))
    assert not s.uses()[16]
    assert 16 not in s.step_predictions and 17 in s.step_predictions


def test_observations_inside_one_step_update_it(home):
    s = session_of(home)
    s.observe(Observation(at(360), "wake_up", {}))
    for second in range(1, 50):  # 49 more observations within the same ten minutes
        s.observe(Observation(at(360) + dt.timedelta(seconds=10 * second), None, {"bowl": "table#114"}))
    s.observe(Observation(at(365), "brushing_teeth", {}))
    day = s.current_day()
    assert day.minutes == (360,) and day.activities == ("brushing_teeth",)
    assert dict(zip(home.objects, day.locations[0]))["bowl"] == "table#114"
    assert s.observations == 51


def test_validation_names_the_field_and_the_label_rule(home):
    s = session_of(home)
    s.observe(Observation(at(360), "wake_up", {}))
    with pytest.raises(DataError) as err:
        s.validate(Observation(at(350), "wake_up", {}))
    assert err.value.field == "time"
    with pytest.raises(DataError) as err:
        s.validate(Observation(at(370), "wake_up", {"bowl": "roof#1"}))
    assert err.value.field == "locations.bowl"
    with pytest.raises(UnknownLabelError, match="variant of the known 'wake_up'"):
        s.validate(Observation(at(370), "Wake Up", {}))
    with pytest.raises(UnknownLabelError, match="known: .*brushing_teeth"):
        s.validate(Observation(at(370), "juggling", {}))
    learner = session_of(home, new_activities="learn")
    learner.validate(Observation(at(370), "juggling", {}))


def test_a_household_without_days_learns_from_scratch(households):
    h = households["B"]
    empty = Household(h.name, h.nodes, h.objects, (), (), "upload")
    s = session_of(empty, learn=True)
    assert s.decide().status == "learning" and s.new_activities == "learn"
    day = h.test[0]
    for r in feed(s, h, day):
        assert r.decision.status == "learning" and not r.decision.fetches and r.decision.activity is None
    s.observe(Observation(at(360, 1), day.activities[0], {}))  # the next morning: the first day is learned
    d = s.decide()
    assert s.days_learned == 1 and d.status == "ready" and d.activity in set(day.activities)


def test_a_day_seen_for_less_than_half_teaches_nothing(home):
    s = session_of(home, learn=True)
    day = home.test[0]
    feed(s, home, day, rows=range(80, len(day)))  # from 19:20: under half of the day labelled
    s.observe(Observation(at(360, 1), day.activities[0], {}))
    assert s.days_learned == len(home.train)
    s.observe(Observation(at(360, 1) + dt.timedelta(minutes=10), day.activities[1], {}))
    feed(s, home, home.test[1], rows=range(2, len(day)), visible=lambda t: t % 3 != 0, date=MONDAY + dt.timedelta(1))
    s.observe(Observation(at(360, 2), day.activities[0], {}))
    assert s.days_learned == len(home.train) + 1
    learned = s.activity_model.training_data_[-1]
    assert len(learned) == len(day) and None not in learned  # unknown steps: the filter's most probable history


def test_fetches_follow_one_rule(home):
    """At most max_fetches_per_step, each with positive expected value, never one waiting for its
    use, none at the day's last step; asking again before the next observation decides nothing new."""
    s = session_of(home)
    records = feed(s, home, home.test[2])
    threshold, most = s.policy.threshold, s.policy.max_fetches_per_step
    made = [c for r in records for c in r.decision.fetches]
    assert made and all(c.probability > threshold for c in made)
    assert all(len(r.decision.fetches) <= most for r in records)
    assert not records[-1].decision.fetches  # the last step of the day
    assert s.decide() is records[-1].decision
    fetched = {t: objs for t, objs in s.fetched_today.items()}
    for t, objs in fetched.items():  # nothing fetched again while it waits for its use
        for u in range(t + 1, min(t + s.policy.window_steps, len(home.test[2]))):
            used_between = any(o in s.uses()[v] for o in objs for v in range(t + 1, u + 1))
            assert used_between or not set(objs) & set(fetched.get(u, ()))


def test_a_live_fetch_precision_counts_only_fetches_whose_window_settled(home):
    """Fed part of a day, the fetches still waiting inside their window are left out of the live
    report (neither right nor wrong yet); the whole report counts them."""
    s = session_of(home)
    day = home.test[2]
    for cut in range(10, len(day.minutes), 5):
        s = session_of(home)
        feed(s, home, day, rows=range(cut))
        whole, settled = s.fetch_report(), s.fetch_report(settled_only=True)
        if whole.fetches > settled.fetches:
            break
    else:
        pytest.fail("no cut of the day leaves a fetch waiting")
    assert settled.useful_fetches == whole.useful_fetches and settled.fetches < whole.fetches
    assert settled.fetches >= settled.useful_fetches


def test_no_fetch_touches_an_object_in_use_or_just_put_back():
    """A home whose sensors put an object in use while it is on: the policy would fetch what the
    person holds (its departure, the return, is all but certain), the rule never does."""
    h = clock_home(40, 3, seed=3)
    s = session_of(h)
    worth, touched = 0, 0
    for i, day in enumerate(h.test):
        for r in feed(s, h, day, date=MONDAY + dt.timedelta(days=i)):
            d = r.decision
            alone = d.left_alone
            worth += sum(c.obj in alone and c.probability > s.policy.threshold for c in d.candidates)
            touched += sum(c.obj in alone for c in d.fetches)
            places = dict(zip(h.objects, day.locations[r.row]))
            assert {o for o, p in places.items() if p == IN_USE} <= alone
    assert worth > 0 and touched == 0


def test_forecasts_mix_the_filters_histories_when_labels_are_missing(home):
    """With a label hidden the forecast mixes the filter's most probable histories (weights
    summing to 1); with every label seen it is the forecaster's own, to the bit."""
    day = home.test[3]
    full, hidden = session_of(home), session_of(home)
    feed(full, home, day, rows=range(40))
    feed(hidden, home, day, rows=range(40), visible=lambda t: t % 4 == 0)
    f = full.forecast(5)
    own = full.policy.forecaster.forecast(day.activities[:40], day.locations[:40], 5, MONDAY.weekday())
    assert np.array_equal(f.departure, own.departure) and np.array_equal(f.destination, own.destination)
    g = hidden.forecast(5)
    found = hidden._filter.top_histories(hidden._filtered(), hidden.forecast_hypotheses)
    assert len(found) > 1 and sum(h.weight for h in found) == pytest.approx(1.0)
    assert not np.array_equal(g.departure, f.departure)


def test_the_session_predicts_from_the_day_of_the_week_it_is_in():
    """With a clock model that tells weekends apart, what follows breakfast on a Saturday is what
    the training Saturdays did (relax), on a Monday what the weekdays did (work), with every label
    seen and with labels missing (the filter starts from the day's type too); the day it learns
    keeps its date."""
    h = weekly_home(29, 1, 1)
    cfg = CFG.with_overrides({"models.activity_estimator": "clock", "models.clock_day_types": "weekend"})
    dep = Deployment.configured(cfg)
    saturday, monday = dt.datetime(2026, 3, 7), dt.datetime(2026, 3, 9)
    for hide in (False, True):
        nexts = {}
        for start in (saturday, monday):
            s = build_session(h, cfg, dep, None)
            for minute in range(360, 450, 10):  # asleep until 07:00, then breakfast until 07:20
                label = "sleeping" if minute < 420 else "breakfast"
                s.observe(Observation(start + dt.timedelta(minutes=minute), None if hide and minute == 390 else label,
                                      {}))
            belief = s.belief()
            nexts[start.weekday()] = max(sorted(set(belief) - {"breakfast"}), key=belief.get)
        assert nexts == {5: "relax", 0: "work"}
    s.observe(Observation(monday + dt.timedelta(days=1, minutes=360), "sleeping", {}))
    assert s.activity_model.weekdays_[-1] == 0
