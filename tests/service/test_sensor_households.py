"""A household created with its ambient sensors: it keeps them (and its recogniser's settings)
through a restart, takes sensor events with its observations, refuses unknown sensors by field,
and predicts the recognised activity where no label comes."""

from __future__ import annotations

import datetime as dt

import pytest

from globe.data.sensors import format_events
from globe.service.client import household_payload
from globe.service.schema import SCHEMA_VERSION
from globe.service.store import Store
from tests.service.dashboard_helpers import BASE, app_client, tokens
from tests.simulated_sensors import sensor_home

pytestmark = pytest.mark.service
STEP = 10


@pytest.fixture(scope="module")
def home():
    return sensor_home(days=6, test=2, step=STEP)


def create_body(home, name: str = "S") -> dict:
    h, sensors = home
    payload = household_payload(h)
    rows = [{"sensor": s.name, "type": s.type, "room": s.room, "object": s.object} for s in sensors.sensors]
    events = [format_events(sensors.of(d.name), sensors.sensors) for d in h.train]
    return {"name": name, "timezone": "UTC", **payload, "sensors": rows, "events": events}


def observations(home, day, date: dt.datetime, steps: int) -> list[dict]:
    """The first ``steps`` steps of ``day`` on ``date``, each with the activations that begin in it."""
    _, sensors = home
    found = sensors.of(day.name)
    out = []
    for t in range(steps):
        lo, hi = day.minutes[t] * 60, (day.minutes[t] + STEP) * 60
        events = [{"sensor": sensors.sensors[i].name, "start": (date + dt.timedelta(seconds=a)).isoformat(),
                   "end": (date + dt.timedelta(seconds=b)).isoformat()}
                  for i, a, b in zip(found.sensor.tolist(), found.start.tolist(), found.end.tolist()) if lo <= a < hi]
        out.append({"time": (date + dt.timedelta(minutes=day.minutes[t])).isoformat(), "sensors": events})
    return out


def test_a_household_with_sensors_recognises_and_keeps_them_through_a_restart(tmp_path, home):
    db = tmp_path / "globe.sqlite3"
    admin, _ = tokens(db)
    h, _ = home
    steps = observations(home, h.test[0], BASE, 40)
    with app_client(db, admin) as c:
        created = c.post("/households", json=create_body(home))
        assert created.status_code == 201, created.text
        assert created.json()["sensors"] == 16
        bad = c.post("/households/S/observations", json={**steps[0], "sensors": [
            {"sensor": "M_kitchen", "start": steps[0]["time"]}, {"sensor": "nope", "start": steps[0]["time"]}]})
        assert 400 <= bad.status_code < 500 and bad.json()["field"] == "sensors[1].sensor", bad.text
        before = []
        for obs in steps:
            r = c.post("/households/S/observations", json=obs)
            assert r.status_code == 201, r.text
            before.append(c.get("/households/S/prediction").json())
        right = sum(p["recognised"]["activity"] == a for p, a in zip(before, h.test[0].activities))
        assert right >= 0.6 * len(steps)
        assert before[-1]["recognised_steps"] == len(steps) and before[-1]["labelled_steps"] == 0
        exported = c.get("/households/S/export").json()
        assert exported["sensors"] and all(e is not None for e in exported["events"])
        assert any(o["sensors"] for o in exported["observations"])
    with app_client(db, admin) as c:  # a restart: rebuilt from the database, observations replayed
        again = c.get("/households/S/prediction").json()
        assert again == before[-1]
    store = Store(db)
    assert store.version == SCHEMA_VERSION and "recognition" in store.settings("S")
    store.close()


def test_events_without_sensors_and_malformed_sensors_are_refused_by_field(tmp_path, home):
    db = tmp_path / "globe.sqlite3"
    admin, _ = tokens(db)
    body = create_body(home, "T")
    with app_client(db, admin) as c:
        r = c.post("/households", json={**body, "sensors": None})
        assert r.status_code == 400 or r.status_code == 422
        assert r.json()["field"] == "events"
        rows = [dict(s) for s in body["sensors"]]
        rows[2]["sensor"] = rows[1]["sensor"]
        r = c.post("/households", json={**body, "sensors": rows})
        assert r.json()["field"] == "sensors[2].sensor", r.text
        r = c.post("/households", json={**body, "events": ["sensor,start,end\nnope,1,2\n"]})
        assert r.json()["field"] == "events[0].sensor", r.text


def test_the_service_recognises_what_the_evaluation_shows_the_models(tmp_path, home):
    """Served = scored: a household created over HTTP with its sensors, a test day observed step by
    step with its sensor activations and no label, recognises at each step the activity that
    ``globe evaluate --activities recognised`` shows the models at that step (same deployment,
    same recogniser settings chosen on the training days, same online filter)."""
    from dataclasses import replace

    from globe.evaluation.recognised import recognise_test_days
    from tests.service.dashboard_helpers import config

    db = tmp_path / "globe.sqlite3"
    admin, _ = tokens(db)
    h, sensors = home
    day = h.test[0]
    scored = recognise_test_days(replace(h, test=(day,)), sensors, STEP, config=config(db)).household.test[0].observed
    served = []
    with app_client(db, admin) as c:
        assert c.post("/households", json=create_body(home)).status_code == 201
        for obs in observations(home, day, BASE, 40):
            assert c.post("/households/S/observations", json=obs).status_code == 201
            served.append(c.get("/households/S/prediction").json()["recognised"]["activity"])
    assert served == list(scored[:40])
    assert sum(a == b for a, b in zip(served, day.activities)) >= 0.6 * len(served)  # and it recognises
