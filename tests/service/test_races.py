"""Concurrency: whatever the interleaving of create, delete, observe, predict and eviction, the
households the service holds are the database's, over real loopback HTTP."""

import datetime as dt
import sqlite3
import threading
import time

import httpx
import pytest

from globe.service.client import ServiceError, household_payload

pytestmark = pytest.mark.service


def test_create_delete_observe_and_eviction_leave_the_registry_equal_to_the_database(make_server, households):
    """Two admins create and delete one household while three robots observe and predict it and a
    fourth keeps another household busy (one built household at most: every switch evicts).
    Afterwards the name behaves as the database says: no household stuck as 409 for create and
    503 for everything else, and /health is ok."""
    srv = make_server({"GLOBE_SERVICE__MAX_BUILT_HOUSEHOLDS": "1"})
    h = households["A"]
    payload = household_payload(h)
    nodes, days = payload["nodes"], payload["days"][:2]
    obj, place = h.objects[0], h.nodes[0].node
    with srv.client() as c:
        c.create_household("other", nodes, days, timezone="UTC")
    stop = threading.Event()
    unexpected: list[str] = []

    def admin() -> None:
        with srv.client() as c:
            while not stop.is_set():
                for call in (lambda: c.create_household("X", nodes, days, timezone="UTC"),
                             lambda: c.delete_household("X")):
                    try:
                        call()
                    except ServiceError as err:
                        if err.status not in (404, 409):
                            unexpected.append(str(err))

    def robot(name: str) -> None:
        with srv.client() as c:
            while not stop.is_set():
                now = dt.datetime.now(dt.timezone.utc)
                for call in (lambda t=now: c.observe(name, t, "idle", {obj: place}), lambda: c.prediction(name)):
                    try:
                        call()
                    except ServiceError as err:
                        if err.status not in (404, 422):  # gone, or not after another robot's observation
                            unexpected.append(str(err))

    threads = [threading.Thread(target=admin) for _ in range(2)]
    threads += [threading.Thread(target=robot, args=("X",)) for _ in range(3)]
    threads += [threading.Thread(target=robot, args=("other",))]
    for th in threads:
        th.start()
    time.sleep(4)
    stop.set()
    for th in threads:
        th.join()
    assert unexpected == []
    db = sqlite3.connect(srv.db)
    stored = {r[0] for r in db.execute("SELECT name FROM households")}
    db.close()
    with srv.client() as c:
        assert set(c.households()) == stored
        if "X" in stored:
            c.prediction("X")
            c.delete_household("X")
        with pytest.raises(ServiceError) as err:
            c.prediction("X")
        assert err.value.status == 404
        c.create_household("X", nodes, days, timezone="UTC")
        assert c.observe("X", dt.datetime.now(dt.timezone.utc), "idle", {obj: place})["duplicate"] is False
        health = httpx.get(srv.url + "/health").json()
        assert health["status"] == "ok" and health["failed"] == [], health
