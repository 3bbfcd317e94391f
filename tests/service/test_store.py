"""The store: a database written by the previous schema (2) migrates and replays; training days
are stored compactly and read back identically."""

import datetime as dt
import json
import threading
import time
from dataclasses import asdict

from globe.config import GlobeConfig
from globe.errors import StoreError
from globe.service.registry import Registry
from globe.service.schema import APPLICATION_ID, SCHEMA_VERSION
from globe.service.store import Store
from tests.helpers import database_at_schema


def test_a_schema_2_database_migrates_and_replays(tmp_path, households):
    h = households["B"]
    path = tmp_path / "old.sqlite3"
    db = database_at_schema(path, 2)
    created = (dt.datetime.now(dt.timezone.utc) - dt.timedelta(days=30)).isoformat()
    nodes = json.dumps([asdict(n) for n in h.nodes])
    db.execute("INSERT INTO households VALUES (?, ?, ?, ?)", ("B", nodes, json.dumps(h.objects), created))
    for i, d in enumerate(h.train[:3]):
        db.execute("INSERT INTO training_days VALUES (?, ?, ?)", ("B", i, json.dumps(asdict(d))))
    base = dt.datetime.now() - dt.timedelta(days=10)
    day = h.test[0]
    for t in range(12):  # naive times, as schema 2 stored them
        time = (base.replace(hour=0, minute=0) + dt.timedelta(minutes=day.minutes[t])).isoformat()
        locations = json.dumps(dict(zip(h.objects, day.locations[t])))
        db.execute("INSERT INTO observations (household, time, activity, locations, received_at) "
                   "VALUES (?, ?, ?, ?, ?)",
                   ("B", time, day.activities[t], locations, dt.datetime.now(dt.timezone.utc).isoformat()))
    db.close()
    store = Store(path)
    assert store.version == SCHEMA_VERSION
    assert store._db.execute("PRAGMA application_id").fetchone()[0] == APPLICATION_ID
    registry = Registry(store, GlobeConfig(), None)
    registry.load_all()
    stats = registry.stats("B")
    assert stats.days_learned == 3 and stats.observations == 12 and stats.quarantined == 0
    assert registry.get("B").new_activities == "learn"  # it accepted any activity before: it still does
    assert store.household("B").timezone == "UTC"
    store.close()


def test_training_days_are_stored_compressed_and_read_back(tmp_path, households):
    from globe.data.csv_logs import format_day
    from globe.service.client import household_payload
    from globe.service.upload import household_from, parse_nodes

    h = households["A"]
    payload = household_payload(h)
    texts = [format_day(d, h.objects) for d in h.train]
    store = Store(tmp_path / "s.sqlite3")
    store.add_household(household_from("A", parse_nodes(payload["nodes"]), texts), "Europe/Paris", texts)
    assert [d.text for d in store.training_days("A")] == texts
    store.close()  # checkpoints the write-ahead log into the file
    assert (tmp_path / "s.sqlite3").stat().st_size < sum(map(len, texts)) / 4


def test_day_encoding_shared_by_threads_gives_the_blobs_of_encode_days(households):
    """Two threads take the days of one DayEncoding between them (the registry's helper and the
    thread that counts the models, once it is done): every blob is encode_days', each day
    compressed once; a stopped encoding takes no more days."""
    import threading

    from globe.data.csv_logs import format_day
    from globe.service.stored_days import DayEncoding

    texts = [format_day(d, households["B"].objects) for d in households["B"].train]
    shared = DayEncoding(texts)
    helper = threading.Thread(target=shared.run)
    helper.start()
    shared.run()
    helper.join()
    assert shared.blobs == Store.encode_days(texts)
    stopped = DayEncoding(texts)
    stopped.stop()
    stopped.run()
    assert stopped.blobs == [b""] * len(texts)


def test_training_days_keep_their_dates_through_a_restart_and_an_export(tmp_path):
    """Days uploaded with dates are counted by their weekday, and so again when the household is
    rebuilt from the database; the export carries the dates; a date list of another length is
    refused by name."""
    import pytest

    from globe.errors import DataError
    from globe.service.client import household_payload
    from tests.simulated import weekly_home

    h = weekly_home(22, 1, 2)
    payload = household_payload(h)
    dates = [dt.date.fromisoformat(d) for d in payload["dates"]]
    assert len(dates) == len(h.train) and dates[0] == dt.date(2024, 1, 1)
    cfg = GlobeConfig().with_overrides({"models.activity_estimator": "clock", "models.clock_day_types": "weekend",
                                        "llm.backend": "none"})
    store = Store(tmp_path / "dated.sqlite3")
    registry = Registry(store, cfg, None)
    registry.create_uploaded("W", "UTC", payload["nodes"], payload["days"], dates)
    registry.create_uploaded("U", "UTC", payload["nodes"], payload["days"])
    want = [d.weekday() for d in dates]
    assert registry.get("W").activity_model.weekdays_ == want
    assert registry.get("U").activity_model.weekdays_ == [None] * len(dates)
    with pytest.raises(DataError) as err:
        registry.create_uploaded("X", "UTC", payload["nodes"], payload["days"], dates[:-1])
    assert err.value.field == "dates"
    assert store.export_household("W")["dates"] == payload["dates"] == [d.date for d in store.training_days("W")]
    store.close()
    store = Store(tmp_path / "dated.sqlite3")
    again = Registry(store, cfg, None)
    again.load_all()
    assert again.get("W").activity_model.weekdays_ == want
    store.close()


def _bare_household(store: Store, name: str) -> None:
    store._transaction("add", [("INSERT INTO households (name, nodes, objects, created_at) VALUES (?, '[]', '[]', '')",
                                (name,))])


def test_concurrent_writes_are_each_committed_once_with_their_own_row_ids(tmp_path):
    store = Store(tmp_path / "g.sqlite3")
    for i in range(8):
        _bare_household(store, f"h{i}")
    returned: list[int] = []
    lock = threading.Lock()

    def write(i: int) -> None:
        ids = [store.add_feedback(f"h{i}", f"o{k}", k % 2 == 0) for k in range(40)]
        with lock:
            returned.extend(ids)

    threads = [threading.Thread(target=write, args=(i,)) for i in range(8)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    rows = store._read("SELECT id, household, object FROM feedback")
    assert len(rows) == 320 and sorted(returned) == sorted(r[0] for r in rows)
    assert {(h, o) for _, h, o in rows} == {(f"h{i}", f"o{k}") for i in range(8) for k in range(40)}


def _queued_together(store: Store, calls: dict) -> dict[str, object]:
    """Run ``calls`` in threads while a commit is under way, so that they are committed together;
    what each returned or raised."""
    outcome: dict[str, object] = {}

    def run(key: str, call) -> None:
        try:
            outcome[key] = call()
        except StoreError as err:
            outcome[key] = err

    with store._queued:
        store._committing = True
    threads = [threading.Thread(target=run, args=item) for item in calls.items()]
    for th in threads:
        th.start()
    deadline = time.monotonic() + 10
    while len(store._queue) < len(calls) and time.monotonic() < deadline:
        time.sleep(0.005)
    assert len(store._queue) == len(calls)
    with store._queued:
        store._committing = False
        store._queued.notify_all()
    for th in threads:
        th.join()
    return outcome


def test_a_failing_write_queued_with_others_fails_alone(tmp_path):
    """Writes queued behind a commit are committed together; one that breaks a constraint, or
    holds a value SQLite cannot take, is retried alone and fails, and the others are committed."""
    store = Store(tmp_path / "g.sqlite3")
    store.add_token("t1", "hash-1", None, admin=True)
    _bare_household(store, "h")
    outcome = _queued_together(store, {
        "same id": lambda: store.add_token("t1", "hash-2", None, admin=True),
        "feedback": lambda: store.add_feedback("h", "cup", True),
        "too large": lambda: store.add_fetch("h", "2026-01-01", 2**64, "cup", None, None, False),
        "shadow": lambda: store.set_shadow("h", False),
        "new token": lambda: store.add_token("t2", "hash-3", None, admin=False)})
    assert isinstance(outcome["same id"], StoreError) and "store the token" in str(outcome["same id"])
    assert isinstance(outcome["too large"], StoreError) and "store the fetch decision" in str(outcome["too large"])
    assert outcome["shadow"] == 0  # an UPDATE adds no row: not the feedback's row id
    feedback = store._read("SELECT id FROM feedback")
    assert feedback == [(outcome["feedback"],)]
    assert [t.id for t in store.tokens()] == ["t1", "t2"] and store.problem() is None
    assert store._read("SELECT shadow FROM households") == [(0,)] and not store._db.in_transaction
