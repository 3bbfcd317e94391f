"""What is stored stays usable: damaged rows, observations ahead of the clock, the repeated hour
when clocks go back, reused ids, one rule for activity labels and household names; over real
loopback HTTP against the real server process and SQLite."""

import datetime as dt
import sqlite3
import time
import unicodedata
import zlib
from zoneinfo import ZoneInfo

import httpx
import pytest

from globe.service.client import household_payload
from tests.service.conftest import at, fails, upload

pytestmark = pytest.mark.service
UTC = dt.timezone.utc


def test_a_household_that_cannot_be_built_is_failed_yet_deletable_and_exportable(server, households):
    h = households["A"]
    with server.client() as c:
        for name in ("badmap", "badzone", "fine"):
            upload(c, name, h, days=False)
    server.kill()
    db = sqlite3.connect(server.db)
    db.execute("UPDATE households SET nodes = '[not json' WHERE name = 'badmap'")
    db.execute("UPDATE households SET timezone = 'Mars/Olympus' WHERE name = 'badzone'")
    db.commit()
    db.close()
    server.start()
    with server.client() as c:
        for name, reason in (("badmap", "stored map of household 'badmap' is damaged"),
                             ("badzone", "unknown IANA time zone 'Mars/Olympus'")):
            calls = (lambda n: c.stats(n), lambda n: c.prediction(n), lambda n: c.export_model(n),
                     lambda n: c.observe(n, at(0, 400), "idle", {}), lambda n: c.feedback(n, h.objects[0], True))
            for call in calls:
                err = fails(lambda: call(name), 503)  # noqa: B023 - called at once
                assert reason in err.detail and "cannot be built" in err.detail, err.detail
        health = httpx.get(server.url + "/health").json()
        assert health["status"] == "degraded" and health["failed"] == ["badmap", "badzone"]
        exported = c._call("GET", "/households/badmap/export")
        assert exported["nodes"] == "[not json" and exported["timezone"] == "UTC" and exported["days"] == []
        c.delete_household("badmap")
        c.delete_household("badzone")
        fails(lambda: c.stats("badmap"), 404)
        assert c.households() == ["fine"]
        assert httpx.get(server.url + "/health").json()["status"] == "ok"
        assert c.observe("fine", at(0, 400), "idle", {})["duplicate"] is False  # the others were never affected


def test_training_days_set_aside_are_counted(server, households):
    h = households["B"]
    payload = household_payload(h)
    with server.client() as c:
        c.create_household("B", payload["nodes"], payload["days"][:3], timezone="UTC")
        assert c.stats("B")["training_days_set_aside"] == 0
    server.kill()
    db = sqlite3.connect(server.db)
    db.execute("UPDATE training_days SET day = ? WHERE household = 'B' AND position = 1",
               (zlib.compress(b"minute,activity\n360,idle\n"),))  # no longer this map's columns
    db.commit()
    db.close()
    server.start()
    with server.client() as c:
        s = c.stats("B")
        assert (s["days_learned"], s["training_days_set_aside"]) == (2, 1)


HELD = dt.timedelta(seconds=20)


def test_an_observation_far_ahead_of_the_clock_is_held_not_a_lock(make_server, households):
    """One glitched clock (an observation 23 h 50 min ahead, inside the one-day skew) must not
    refuse every real observation until the clock passes it: it is stored and acknowledged as
    pending, and applied once the clock is within service.max_ahead of it; nothing is lost. The
    server reads the real clock: ``HELD`` leaves a restart on a loaded machine time to finish
    before the first held observation falls due."""
    srv = make_server({"GLOBE_SERVICE__MAX_AHEAD": "PT2S"})  # default skew: one day
    h = households["A"]
    with srv.client() as c:
        upload(c, "A", h)
        now = dt.datetime.now(UTC)
        assert c.observe("A", now, "reading", {})["pending"] is False
        glitch = c.observe("A", now + dt.timedelta(hours=23, minutes=50), "sleep", {}, id="glitch")
        soon = c.observe("A", now + HELD, "reading", {})
        assert glitch["pending"] and soon["pending"]
        assert c.observe("A", now + dt.timedelta(seconds=1), "reading", {})["pending"] is False  # real time goes on
        s = c.stats("A")
        assert (s["observations"], s["pending"]) == (2, 2)
        fails(lambda: c.observe("A", now + HELD, "reading", {}), 422, "time")  # that time is held
        assert c.observe("A", now + dt.timedelta(hours=23, minutes=50), "sleep", {}, id="glitch")["duplicate"]
    srv.kill()
    srv.start()  # held observations stay held across a restart
    with srv.client() as c:
        s = c.stats("A")
        assert (s["observations"], s["pending"], s["quarantined"]) == (2, 2, 0)
        time.sleep(max(0.0, (now + HELD - dt.timedelta(seconds=1.8) - dt.datetime.now(UTC)).total_seconds()))
        s = c.stats("A")  # the clock is now within two seconds of the first held one: applied
        assert (s["observations"], s["pending"]) == (3, 1)
        fails(lambda: c.observe("A", now + HELD - dt.timedelta(seconds=1), "reading", {}), 422, "time")
        later = c.observe("A", now + HELD + dt.timedelta(seconds=1), "reading", {})
        assert later["duplicate"] is False  # and it goes on
    db = sqlite3.connect(srv.db)
    assert db.execute("SELECT COUNT(*) FROM observations WHERE quarantined = 0").fetchone()[0] == 5
    db.close()


def last_autumn_change(zone: ZoneInfo) -> dt.date:
    """The most recent date (within a year) whose 02:30 occurs twice in ``zone``."""
    day = dt.date.today()
    for _ in range(400):
        day -= dt.timedelta(days=1)
        naive = dt.datetime.combine(day, dt.time(2, 30))
        if naive.replace(tzinfo=zone, fold=0).utcoffset() != naive.replace(tzinfo=zone, fold=1).utcoffset():
            return day
    raise AssertionError("no repeated hour in a year")


def test_naive_times_through_the_repeated_hour_are_accepted_in_order(server, households):
    """At the autumn change Paris lives 02:00-02:59 twice. A robot sending naive wall times sends
    that hour twice: the second pass is taken as the later occurrence, not refused."""
    paris = ZoneInfo("Europe/Paris")
    day = last_autumn_change(paris)
    first, second = dt.datetime.combine(day, dt.time(1, 40)), dt.datetime.combine(day, dt.time(2, 0))
    wall = [first + dt.timedelta(minutes=10 * k) for k in range(8)]  # 01:40 ... 02:50
    wall += [second + dt.timedelta(minutes=10 * k) for k in range(7)]  # 02:00 ... 03:00
    with server.client() as c:
        upload(c, "A", households["A"], timezone="Europe/Paris")
        for t in wall:
            c.observe("A", t, "sleep", {})
        assert c.stats("A")["observations"] == len(wall)
        err = fails(lambda: c.observe("A", dt.datetime.combine(day, dt.time(2, 30)), "sleep", {}), 422, "time")
        assert "UTC offset" in err.detail  # neither occurrence is after 03:00: the message says what to send
        stored = [o["time"] for o in c._call("GET", "/households/A/export")["observations"]]
    instants = [dt.datetime.fromisoformat(t).astimezone(UTC) for t in stored]
    assert instants == sorted(instants) and len(set(instants)) == len(wall)
    assert instants[-1] - instants[0] == dt.timedelta(hours=2, minutes=20)  # 01:40 CEST to 03:00 CET
    server.kill()
    server.start()
    with server.client() as c:
        assert (c.stats("A")["observations"], c.stats("A")["quarantined"]) == (len(wall), 0)


def test_an_id_reused_for_another_observation_is_a_conflict(server, households):
    with server.client() as c:
        upload(c, "A", households["A"], days=False)
        first = c.observe("A", at(0, 400), "reading", {}, id="o-1")
        assert c.observe("A", at(0, 400), "reading", {}, id="o-1") == {**first, "duplicate": True}
        for other in ((at(0, 410), "reading", {}), (at(0, 400), "cooking", {}),
                      (at(0, 400), "reading", {households["A"].objects[0]: households["A"].nodes[0].node})):
            fails(lambda o=other: c.observe("A", *o, id="o-1"), 409, "id")
        assert c.stats("A")["observations"] == 1


def test_one_activity_label_rule_for_observations_and_uploaded_days(server, households):
    """NFC and NFD spellings of one word are one activity; control characters, bidirectional
    overrides and invisible characters (a byte-order mark, a zero-width space: a label that looks
    like another) are refused, whether the label comes in an observation or in an uploaded day."""
    h = households["A"]
    composed, decomposed = "caf\u00e9", "cafe\u0301"
    assert unicodedata.normalize("NFC", decomposed) == composed and composed != decomposed
    with server.client() as c:
        upload(c, "A", h, days=False)
        c.observe("A", at(0, 400), decomposed, {})
        c.observe("A", at(0, 410), composed, {})
        for bad in ("idle\x07", "idle\u202e", "idle\u2066", "\t", "idle\x85", "\ufeffidle", "id\u200ble", "idle\u2060"):
            fails(lambda b=bad: c.observe("A", at(0, 420), b, {}), 422, "activity")
        activities = [o["activity"] for o in c._call("GET", "/households/A/export")["observations"]]
        assert activities == [composed, composed]
        payload = household_payload(h)
        day = payload["days"][0]
        lines = day.split("\n")
        for bad, accepted in (("idle\u202e", False), ("idle\u200b", False), (decomposed, True)):
            minute, _, rest = lines[1].split(",", 2)
            text = "\n".join([lines[0], f"{minute},{bad},{rest}", *lines[2:]])
            name = f"up-{accepted}"
            if accepted:
                c.create_household(name, payload["nodes"], [text], timezone="UTC")
                learned = c.export_model(name)["activity"]["data"][0]
                assert learned[0] == composed
            else:
                fails(lambda t=text, n=name: c.create_household(n, payload["nodes"], [t]), 422, "days[0].activity")


@pytest.mark.parametrize("name", [".", "..", "-x", "_x", "a/b", "", "x" * 65])
def test_household_names_clients_cannot_address_are_refused(server, households, name):
    with server.client() as c:
        fails(lambda: upload(c, name, households["A"], days=False), 422, "name")
        assert c.households() == []
