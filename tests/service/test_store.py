"""The store: a database written by the previous schema (2) migrates and replays; training days
are stored compactly and read back identically."""

import datetime as dt
import json
from dataclasses import asdict

from globe.config import GlobeConfig
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
    a = registry.get("B")
    assert a.days_learned == 3 and a.observations == 12 and a.quarantined == 0
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
    from globe.service.store import DayEncoding

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
