"""Time policy, idempotent retries, deletion, poisoned rows, database checks, cold start and LLM
cache failures, over real loopback HTTP against the real server process and SQLite."""

import datetime as dt
import sqlite3
import subprocess
import sys

import httpx
import pytest

from globe.service.client import GlobeClient
from tests.service.conftest import at, fails, upload

pytestmark = pytest.mark.service
UTC = dt.timezone.utc


def test_time_policy(make_server, households):
    srv = make_server()  # the default clock-skew window: one day
    h = households["A"]
    now = dt.datetime.now(UTC).replace(microsecond=0)
    with srv.client() as c:
        upload(c, "A", h, timezone="Europe/Paris")
        fails(lambda: c.observe("A", dt.datetime(1, 1, 1), "idle", {}), 422, "time")
        fails(lambda: c.observe("A", dt.datetime(9999, 12, 31, 23), "idle", {}), 422, "time")
        fails(lambda: c.observe("A", now + dt.timedelta(days=2), "idle", {}), 422, "time")
        fails(lambda: c.observe("A", now - dt.timedelta(days=2), "idle", {}), 422, "time")
        assert c.stats("A")["observations"] == 0  # nothing was stored
        paris = dt.timezone(dt.timedelta(hours=1))  # Paris in November (CET)
        first = (now - dt.timedelta(hours=3)).astimezone(UTC)
        ack = c.observe("A", first, "reading", {})  # aware UTC: converted to Paris wall time
        wall = first.astimezone(paris).replace(tzinfo=None)
        assert ack["day"] == (wall - dt.timedelta(hours=6)).date().isoformat()
        # naive = Paris wall time; one second later is the same ten-minute step
        naive = wall + dt.timedelta(seconds=1)
        if (naive.minute // 10) == (wall.minute // 10):
            assert c.observe("A", naive, "reading", {})["step"] == ack["step"]
        later = first + dt.timedelta(minutes=30)  # may fall on the next day (it begins at 06:00 wall time)
        after = c.observe("A", later.astimezone(dt.timezone(dt.timedelta(hours=-5))), None, {})
        assert (after["day"], after["step"]) > (ack["day"], ack["step"])
        fails(lambda: c.observe("A", first, "reading", {}), 422, "time")  # not after the last one
        assert c.stats("A")["observations"] in (2, 3)
    srv.kill()
    srv.start()  # everything stored replays
    with srv.client() as c:
        s = c.stats("A")
        assert s["quarantined"] == 0 and s["observations"] in (2, 3) and s["timezone"] == "Europe/Paris"


def test_retries_with_an_id_are_idempotent_and_delete_forgets(server, households):
    h = households["B"]
    with server.client() as c:
        upload(c, "B", h)
        token = server.token("B")
        with GlobeClient(server.url, token=token) as robot:
            first = robot.observe("B", at(0, 400), "wake_up", {}, id="obs-1")
            again = robot.observe("B", at(0, 400), "wake_up", {}, id="obs-1")
            assert first["id"] == again["id"] == "obs-1" and not first["duplicate"] and again["duplicate"]
            assert (first["day"], first["step"]) == (again["day"], again["step"])
            robot.observe("B", at(0, 410), "breakfast", {}, id="obs-2")
            assert robot.observe("B", at(0, 400), "wake_up", {}, id="obs-1")["duplicate"]  # an old retry too
            assert robot.stats("B")["observations"] == 2
        c.delete_household("B")
        for call in (lambda: c.stats("B"), lambda: c.prediction("B"), lambda: c.observe("B", at(0, 420), "idle", {}),
                     lambda: c.delete_household("B"), lambda: c.export_model("B")):
            fails(call, 404)
        with GlobeClient(server.url, token=token) as robot:
            fails(lambda: robot.stats("B"), 401)  # its tokens went with it
        assert "B" not in c.households()
    db = sqlite3.connect(server.db)
    for table in ("observations", "training_days", "feedback", "tokens"):
        assert db.execute(f"SELECT COUNT(*) FROM {table} WHERE household = 'B'").fetchone()[0] == 0
    db.close()
    server.kill()
    server.start()
    with server.client() as c:
        assert c.households() == []
        upload(c, "B", h, days=False)  # the name is free again
        assert c.stats("B")["observations"] == 0


def test_a_poisoned_row_is_quarantined_and_the_rest_loads(server, households):
    h = households["C"]
    day = h.test[0]
    with server.client() as c:
        upload(c, "C", h)
        for t in range(20):
            c.observe("C", at(0, day.minutes[t]), day.activities[t], dict(zip(h.objects, day.locations[t])))
        before = c.prediction("C")
    server.kill()
    db = sqlite3.connect(server.db)
    row = db.execute("SELECT time FROM observations ORDER BY id DESC LIMIT 1").fetchone()[0]
    poison = [("0001-01-01T00:00:00", "idle", "{}"), ("9999-12-31T23:00:00", "idle", "{}"),
              ("not a time", "idle", "{}"), (row, "idle", "{}"), ("2099-01-01T00:00:00", "idle", "[not json"),
              ("2099-01-01T00:00:00", "idle", '{"book": "roof#1"}'), ("2099-01-01T00:00:00", "x" * 100_000, "{}")]
    db.executemany("INSERT INTO observations (household, time, activity, locations, received_at) "
                   "VALUES ('C', ?, ?, ?, ?)",
                   [(t, a, loc, dt.datetime.now(UTC).isoformat()) for t, a, loc in poison])
    db.commit()
    db.close()
    server.start()
    with server.client() as c:
        s = c.stats("C")
        assert s["quarantined"] == len(poison) and s["observations"] == 20
        after = c.prediction("C")
        assert (after.activity, after.object) == (before.activity, before.object)
        c.observe("C", at(0, day.minutes[20]), day.activities[20], {})  # and it goes on
    server.kill()
    server.start()  # quarantined rows are never replayed again
    with server.client() as c:
        assert c.stats("C")["observations"] == 21 and c.stats("C")["quarantined"] == len(poison)


def test_foreign_and_newer_databases_are_refused(tmp_path):
    from globe.errors import StoreError
    from globe.service.schema import APPLICATION_ID, SCHEMA_VERSION
    from globe.service.store import Store

    text = tmp_path / "notes.sqlite3"
    text.write_text("my shopping list\n" * 100)
    other = tmp_path / "other.sqlite3"
    db = sqlite3.connect(other)
    db.execute("CREATE TABLE photos (id INTEGER)")
    db.commit()
    db.close()
    newer = tmp_path / "newer.sqlite3"
    db = sqlite3.connect(newer)
    db.execute(f"PRAGMA application_id = {APPLICATION_ID}")
    db.execute(f"PRAGMA user_version = {SCHEMA_VERSION + 1}")
    db.execute("CREATE TABLE households (name TEXT)")
    db.commit()
    db.close()
    for path, message in ((text, "not a GLOBE database"), (other, "not a GLOBE database"),
                          (newer, f"schema version {SCHEMA_VERSION + 1} is newer")):
        with pytest.raises(StoreError, match=message):
            Store(path)
    assert text.read_text().startswith("my shopping list")
    assert sqlite3.connect(other).execute("SELECT name FROM sqlite_master").fetchall() == [("photos",)]
    r = subprocess.run([sys.executable, "-m", "globe", "serve", "--db", str(newer), "--port", "1"], capture_output=True,
                       text=True, timeout=120, env={"GLOBE_LLM__BACKEND": "none", "PATH": "/usr/bin"})
    assert r.returncode == 1 and "is newer than this GLOBE" in r.stderr and "Traceback" not in r.stderr


def test_a_database_deleted_while_running_refuses_writes(server, households):
    with server.client() as c:
        upload(c, "A", households["A"], days=False)
        c.observe("A", at(0, 400), "idle", {})
        server.db.unlink()
        health = httpx.get(server.url + "/health").json()
        assert health["status"] == "degraded" and "disappeared" in health["database"]
        err = fails(lambda: c.observe("A", at(0, 410), "idle", {}), 503)
        assert "disappeared" in err.detail
        fails(lambda: upload(c, "B", households["B"], days=False), 503)
        assert c.stats("A")["observations"] == 1  # reads still answer; nothing was acknowledged unsaved


def test_cold_start_to_a_first_useful_prediction(server, households):
    h = households["A"]
    with server.client() as c:
        info = upload(c, "A", h, days=False)
        assert info["days_learned"] == 0
        p = c.prediction("A")
        assert (p.status, p.act, p.days_learned) == ("learning", False, 0)
        for d_index, day in enumerate(h.train[:2]):
            useful = 0
            for t in range(len(day)):
                c.observe("A", at(d_index, day.minutes[t]), day.activities[t], dict(zip(h.objects, day.locations[t])))
                p = c.prediction("A")
                if d_index == 0:
                    assert p.status == "learning" and not p.act
                else:
                    assert p.status == "ready" and p.activity is not None
                    useful += p.object is not None
            assert p.days_learned == d_index
        assert useful > 0  # after one observed day the robot gets object suggestions
        exported = c.export_model("A")
        assert len(exported["activity"]["data"]) == 1  # exactly the first observed day was learned


def test_llm_cache_failures_fall_back_to_the_ngram(tmp_path, fitted, households, caplog):
    """A locked, then corrupt, answer cache never fails a prediction of the real gate with the
    real embedded model: each falls back to the n-gram choice, counted with its reason."""
    from globe.assembly import object_chooser
    from globe.config import GateConfig, LLMConfig
    from globe.errors import LLMCacheError
    from globe.reasoning.backends.embedded import EmbeddedBackend
    from globe.reasoning.cache import AnswerCache
    from globe.reasoning.choice import run_context

    path = tmp_path / "cache" / "llm-answers.sqlite3"
    path.parent.mkdir()
    lock = sqlite3.connect(path, isolation_level=None)
    lock.execute("PRAGMA locking_mode=EXCLUSIVE")
    lock.execute("BEGIN EXCLUSIVE")
    lock.execute("CREATE TABLE held (x)")
    backend = EmbeddedBackend(n_threads=1, cache=AnswerCache(path))
    gate = object_chooser(fitted["A"].objects, GateConfig(threshold=1.0), backend, marginal=False)
    model = fitted["A"].objects
    activity = next(a for a in model.indexes_ if len([o for o, p in model.predict_proba(a).items() if p > 0.1]) >= 2)
    choice = gate.choose_given(activity, None, run_context(None, ()))
    assert choice.asked and choice.fallback == LLMCacheError.__name__ and choice.obj == choice.ngram_choice
    assert backend.cache.errors["locked"] >= 1
    lock.execute("ROLLBACK")
    lock.close()
    path.write_bytes(b"\x00garbage" * 512)  # damaged under the open cache
    fresh = AnswerCache(path)
    assert fresh.set_aside and fresh.set_aside[0].exists() and len(fresh) == 0 and "set aside" in caplog.text
    assert LLMConfig().cache_dir is not None


def test_households_beyond_the_memory_bound_are_rebuilt_on_demand(make_server, households):
    srv = make_server({"GLOBE_SERVICE__MAX_CLOCK_SKEW": "P400D", "GLOBE_SERVICE__MAX_BUILT_HOUSEHOLDS": "1"})
    with srv.client() as c:
        for name in "AB":
            upload(c, name, households[name])
        for t in range(6):  # alternate: each request evicts the other household
            for name in "AB":
                day = households[name].test[0]
                c.observe(name, at(0, day.minutes[t]), day.activities[t],
                          dict(zip(households[name].objects, day.locations[t])))
        for name in "AB":
            assert c.stats(name)["observations"] == 6 and c.stats(name)["steps_today"] == 6
        assert httpx.get(srv.url + "/health").json()["built"] == 1


def test_a_home_without_objects_is_served_activity_predictions(server, tmp_path):
    """A home with no movable node (what ``globe data import home-assistant`` writes without
    ``--objects``) is created over HTTP, and after an observation its prediction and its dashboard
    page answer with the next activity and nothing to fetch (both were a 500, the fetch forecast
    ran its kernels on no object)."""
    from globe.data.csv_logs import load_household
    from globe.service.client import household_payload
    from tests.corpus.homes import activity_only

    activity_only(tmp_path / "data", train=6)
    home = load_household(tmp_path / "data", "Q")
    assert home.objects == ()
    with server.client() as c:
        payload = household_payload(home)
        assert c.create_household("Q", payload["nodes"], payload["days"], timezone="UTC")["objects"] == []
        c.set_shadow("Q", False)
        for minute, activity in ((360, "sleeping"), (370, "breakfast"), (380, "breakfast")):
            c.observe("Q", at(0, minute), activity, {})
            p = c.prediction("Q")
            assert p.status == "ready" and p.activity is not None and 0 < p.activity_probability <= 1
            assert p.fetches == [] and p.act is False and p.object is None
    from tests.service.dashboard_helpers import csrf_of

    with httpx.Client(base_url=server.url, timeout=30) as browser:
        form = browser.get("/dashboard/login")
        logged = browser.post("/dashboard/login", data={"csrf": csrf_of(form.text), "token": server.admin},
                              headers={"Origin": server.url})
        assert logged.status_code == 303, logged.text[:300]
        for page in ("/dashboard/households/Q", "/dashboard/households/Q/live", "/dashboard/households/Q/settings"):
            answer = browser.get(page)
            assert answer.status_code == 200, (page, answer.text[:300])


def test_a_database_cut_short_while_running_is_degraded_health(server, households):
    """The database file truncated in place (a full disk's recovery, a careless copy) left /health
    at ok: the writes that came after were acknowledged into a file that could not hold them."""
    import time

    with server.client() as c:
        upload(c, "A", households["A"], days=False)
        c.observe("A", at(0, 400), "idle", {})
    server.stop()  # the log is copied into the file
    server.start()
    with open(server.db, "r+b") as fh:
        fh.truncate(server.db.stat().st_size // 2)
    deadline = time.time() + 10
    while "cut short" not in (health := httpx.get(server.url + "/health").json())["database"]:
        assert time.time() < deadline and health["status"] == "degraded", health  # reads fail meanwhile
        time.sleep(0.2)
    assert health["status"] == "degraded" and "truncated" in health["database"], health
