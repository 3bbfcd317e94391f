"""The service over real loopback HTTP against the real server process and SQLite."""

import datetime as dt
import threading
import time

import pytest

from globe.models.activity import ActivityModel
from globe.models.io import model_from_dict
from globe.models.objects import ObjectModel
from globe.sequences.runs import activity_runs
from globe.service.client import ServiceError, household_payload
from globe.service.robot import SimulatedRobot, replay_days
from tests.service.conftest import BASE, at, upload

pytestmark = pytest.mark.service


def post_day(client, name, household, day, index, steps=None):
    for t in range(steps if steps is not None else len(day)):
        client.observe(name, at(index, day.minutes[t]), day.activities[t],
                       dict(zip(household.objects, day.locations[t])))


@pytest.fixture()
def client(server):
    with server.client() as c:
        yield c


def test_incremental_learning_equals_batch_training(client, households):
    h = households["B"]
    upload(client, "B", h)
    post_day(client, "B", h, h.test[0], 0)
    post_day(client, "B", h, h.test[1], 1)
    post_day(client, "B", h, h.test[2], 2, steps=3)  # the first steps of day 3 close day 2
    assert client.stats("B")["days_learned"] == len(h.train) + 2
    exported = client.export_model("B")
    online_act, online_obj = model_from_dict(exported["activity"]), model_from_dict(exported["objects"])
    days = list(h.train) + [h.test[0], h.test[1]]
    batch_act = ActivityModel().fit([d.activities for d in days])
    batch_obj = ObjectModel().fit([(r.activity, r.objects) for d in days for r in activity_runs(d, h.objects)])
    assert online_act.training_data_ == batch_act.training_data_
    for t in (1, 20, 60, 100):
        history = h.test[3].activities[:t]
        assert online_act.predict_proba(history) == batch_act.predict_proba(history)
    for activity in batch_obj.indexes_:
        assert online_obj.predict_proba(activity, ()) == batch_obj.predict_proba(activity, ())


def test_state_survives_a_killed_server(server, households):
    h = households["A"]
    with server.client() as c:
        upload(c, "A", h)
        post_day(c, "A", h, h.test[0], 0)
        post_day(c, "A", h, h.test[1], 1, steps=40)
        # the prediction first: a fetch it decides is recorded and scored (the stats then include it)
        before_pred, before_stats = c.prediction("A"), c.stats("A")
    server.kill()  # SIGKILL: no shutdown hook runs
    server.start()
    with server.client() as c:
        after_pred, after_stats = c.prediction("A"), c.stats("A")
        assert after_stats == before_stats
        assert (after_pred.activity, after_pred.object, after_pred.object_probability) == (
            before_pred.activity, before_pred.object, before_pred.object_probability)
        with pytest.raises(ServiceError, match="is not after the last observation"):
            post_day(c, "A", h, h.test[1], 1, steps=1)  # already acknowledged before the kill
        day = h.test[1]
        for t in range(40, len(day)):  # the robot goes on where it stopped
            c.observe("A", at(1, day.minutes[t]), day.activities[t], dict(zip(h.objects, day.locations[t])))
        assert c.stats("A")["observations"] == 2 * 109
    assert after_stats["observations"] == 109 + 40


def test_bad_input_gets_4xx_naming_the_field_and_changes_nothing(client, households):
    h = households["C"]
    upload(client, "C", h)
    post_day(client, "C", h, h.test[0], 0, steps=10)
    before, pred = client.stats("C"), client.prediction("C")
    cases = [
        (lambda: client.observe("nobody", at(0, 500), "idle", {}), 404, None),
        (lambda: client._call("POST", "/households/C/observations",
                              json={"time": "yesterday-ish", "activity": "idle"}), 422, "time"),
        (lambda: client.observe("C", at(0, 300), "idle", {}), 422, "time"),  # before the last observation
        (lambda: client.observe("C", at(0, 600), "idle", {"book": "attic#1"}), 422, "locations.book"),
        (lambda: client.observe("C", at(0, 600), "idle", {"spaceship": "kitchen#1"}), 422, "locations.spaceship"),
        (lambda: client._call("POST", "/households/C/observations",
                              json={"time": at(0, 600).isoformat(), "activity": " "}), 422, "activity"),
        (lambda: upload(client, "C", h), 409, "name"),
        (lambda: client._call("POST", "/households", json={"name": "D", "nodes": household_payload(h)["nodes"],
                                                                "source": "/etc"}), 422, "source"),  # no server paths
    ]
    for call, status, field in cases:
        with pytest.raises(ServiceError) as err:
            call()
        assert err.value.status == status, err.value
        if field:
            assert err.value.field == field, err.value
    assert client.stats("C") == before
    assert client.prediction("C").object == pred.object


def test_concurrent_clients_are_serialised(server, households):
    hA, hB = households["A"], households["B"]
    with server.client() as c:
        upload(c, "A", hA)
        upload(c, "B", hB)
    day = hA.test[0]
    accepted, errors = [], []

    def worker(offset):
        with server.client() as c:
            for t in range(offset, len(day), 4):  # four clients interleave the steps of one day
                try:
                    c.observe("A", at(0, day.minutes[t]), day.activities[t], dict(zip(hA.objects, day.locations[t])))
                    accepted.append(t)
                except ServiceError as err:
                    errors.append(err)
                c.prediction("A")

    def household_b():
        with server.client() as c:
            post_day(c, "B", hB, hB.test[0], 0)

    threads = [threading.Thread(target=worker, args=(i,)) for i in range(4)] + [threading.Thread(target=household_b)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    assert all(e.status == 422 and e.field == "time" for e in errors)  # out-of-order arrivals only
    with server.client() as c:
        assert c.stats("A")["observations"] == len(accepted)
        assert c.stats("B")["observations"] == len(hB.test[0])
        assert c.stats("B")["steps_today"] == len(hB.test[0])


def test_simulated_robot_reports_assistance_metrics(client, households):
    h = households["A"]
    upload(client, "A", h)
    assert client.prediction("A").shadow  # a new household starts in shadow mode: the robot would never act
    client.set_shadow("A", False)
    report = replay_days(client, "A", h, h.test[:2], SimulatedRobot(),
                         dates=[BASE.date(), BASE.date() + dt.timedelta(days=1)])
    s = report.summary()
    assert s["steps"] == 2 * 109 and s["days"] == 2
    assert s["fetches"] > 0 and 0 < s["precision"] <= 1 and 0 < s["recall"] <= 1
    assert report.useful_fetches <= report.fetches
    assert s["latency_median_ms"] > 0
    assert client.stats("A")["days_learned"] == len(h.train) + 1


def test_no_acknowledged_observation_is_lost_when_killed_mid_stream(server, households):
    h = households["B"]
    day = h.test[4]
    with server.client() as c:
        upload(c, "B", h)
    acknowledged = []
    stop = threading.Event()

    def stream():
        with server.client(timeout_s=5) as c:
            for t in range(len(day)):
                if stop.is_set():
                    return
                try:
                    c.observe("B", at(0, day.minutes[t]), day.activities[t], dict(zip(h.objects, day.locations[t])))
                except Exception:  # the server died under us: this one was not acknowledged
                    return
                acknowledged.append(t)

    th = threading.Thread(target=stream)
    th.start()
    while len(acknowledged) < 30 and th.is_alive():
        time.sleep(0.005)
    assert len(acknowledged) >= 30
    server.kill()  # SIGKILL while requests are in flight
    stop.set()
    th.join()
    server.start()
    with server.client() as c:
        stored = c.stats("B")["observations"]
    assert len(acknowledged) <= stored <= len(acknowledged) + 1  # at most the one in flight, committed unacknowledged


def test_dated_days_reach_a_model_that_knows_the_day_of_the_week(make_server):
    """Training days uploaded with their dates: the exported model counted each by its weekday
    and loads back predicting the same (a Saturday after breakfast: relax, not work)."""
    from globe.service.client import household_payload
    from tests.simulated import weekly_home

    h = weekly_home(22, 1, 2)
    payload = household_payload(h)
    srv = make_server({"GLOBE_MODELS__ACTIVITY_ESTIMATOR": "clock", "GLOBE_MODELS__CLOCK_DAY_TYPES": "weekend"})
    with srv.client() as c:
        c.create_household("W", payload["nodes"], payload["days"], timezone="UTC", dates=payload["dates"])
        exported = c.export_model("W")["activity"]
    assert exported["weekdays"] == [d.calendar_date.weekday() for d in h.train]
    model = model_from_dict(exported)
    history = ("sleeping",) * 6 + ("breakfast",) * 3
    saturday = model.predict_proba(history, 5)
    assert max(set(saturday) - {"breakfast"}, key=saturday.get) == "relax"
    monday = model.predict_proba(history, 0)
    assert max(set(monday) - {"breakfast"}, key=monday.get) == "work"
