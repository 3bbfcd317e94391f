"""SQLite persistence of the service: households, their training days, every observation.

The schema is created and migrated here (``PRAGMA user_version``). Every accepted observation
is committed before the service replies; on start-up the service rebuilds each household by
re-counting its training days and replaying its observations, so a restart (or a kill in the
middle of a request) resumes with the same model state and no acknowledged observation lost.
"""

from __future__ import annotations

import datetime as dt
import json
import sqlite3
import threading
from dataclasses import asdict
from pathlib import Path
from typing import Iterator

from globe.data.records import Day, Household, Node
from globe.errors import StoreError

MIGRATIONS: list[str] = [
    # 1: the first schema
    """
    CREATE TABLE households (
        name TEXT PRIMARY KEY,
        nodes TEXT NOT NULL,
        objects TEXT NOT NULL,
        created_at TEXT NOT NULL
    );
    CREATE TABLE training_days (
        household TEXT NOT NULL REFERENCES households(name),
        position INTEGER NOT NULL,
        day TEXT NOT NULL,
        PRIMARY KEY (household, position)
    );
    CREATE TABLE observations (
        id INTEGER PRIMARY KEY AUTOINCREMENT,
        household TEXT NOT NULL REFERENCES households(name),
        time TEXT NOT NULL,
        activity TEXT NOT NULL,
        locations TEXT NOT NULL,
        received_at TEXT NOT NULL
    );
    CREATE INDEX observations_by_household ON observations(household, id);
    """,
    # 2: what the person said about fetched objects
    """
    CREATE TABLE feedback (
        id INTEGER PRIMARY KEY AUTOINCREMENT,
        household TEXT NOT NULL REFERENCES households(name),
        object TEXT NOT NULL,
        accepted INTEGER NOT NULL,
        received_at TEXT NOT NULL
    );
    """,
]


def _now() -> str:
    return dt.datetime.now(dt.timezone.utc).isoformat()


class Store:
    """One SQLite file (WAL mode); a lock serialises writers across request threads."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._lock = threading.Lock()
        try:
            self._db = sqlite3.connect(self.path, check_same_thread=False, isolation_level=None)
            self._db.execute("PRAGMA journal_mode=WAL")
            self._db.execute("PRAGMA synchronous=FULL")
            self._db.execute("PRAGMA foreign_keys=ON")
            self.migrate()
        except sqlite3.Error as err:
            raise StoreError(f"{self.path}: cannot open the database: {err}") from err

    @property
    def version(self) -> int:
        return self._db.execute("PRAGMA user_version").fetchone()[0]

    def migrate(self) -> None:
        with self._lock:
            current = self.version
            for number, script in enumerate(MIGRATIONS[current:], start=current + 1):
                self._db.execute("BEGIN IMMEDIATE")
                try:
                    for statement in filter(str.strip, script.split(";")):
                        self._db.execute(statement)
                    self._db.execute(f"PRAGMA user_version = {number}")
                    self._db.execute("COMMIT")
                except sqlite3.Error:
                    self._db.execute("ROLLBACK")
                    raise

    def _write(self, sql: str, params: tuple) -> int:
        with self._lock:
            try:
                cur = self._db.execute(sql, params)
                return cur.lastrowid or 0
            except sqlite3.Error as err:
                raise StoreError(f"database write failed: {err}") from err

    # -- households --------------------------------------------------------------------------
    def add_household(self, household: Household) -> None:
        with self._lock:
            try:
                self._db.execute("BEGIN IMMEDIATE")
                self._db.execute("INSERT INTO households (name, nodes, objects, created_at) VALUES (?, ?, ?, ?)",
                                 (household.name, json.dumps([asdict(n) for n in household.nodes]),
                                  json.dumps(household.objects), _now()))
                self._db.executemany("INSERT INTO training_days (household, position, day) VALUES (?, ?, ?)",
                                     [(household.name, i, json.dumps(asdict(d))) for i, d in enumerate(household.train)])
                self._db.execute("COMMIT")
            except sqlite3.Error as err:
                self._db.execute("ROLLBACK")
                raise StoreError(f"cannot store household {household.name!r}: {err}") from err

    def household_names(self) -> list[str]:
        with self._lock:
            return [r[0] for r in self._db.execute("SELECT name FROM households ORDER BY created_at, name")]

    def load_household(self, name: str) -> Household:
        with self._lock:
            row = self._db.execute("SELECT nodes, objects FROM households WHERE name = ?", (name,)).fetchone()
            days = [r[0] for r in self._db.execute(
                "SELECT day FROM training_days WHERE household = ? ORDER BY position", (name,))]
        nodes = tuple(Node(**n) for n in json.loads(row[0]))
        train = tuple(_day(json.loads(d)) for d in days)
        return Household(name, nodes, tuple(json.loads(row[1])), train, (), f"sqlite:{self.path}")

    # -- observations and feedback ----------------------------------------------------------
    def add_observation(self, household: str, time: dt.datetime, activity: str, locations: dict[str, str]) -> int:
        return self._write("INSERT INTO observations (household, time, activity, locations, received_at) VALUES (?, ?, ?, ?, ?)",
                           (household, time.isoformat(), activity, json.dumps(locations, sort_keys=True), _now()))

    def observations(self, household: str) -> Iterator[tuple[dt.datetime, str, dict[str, str]]]:
        with self._lock:
            rows = self._db.execute("SELECT time, activity, locations FROM observations WHERE household = ? ORDER BY id",
                                    (household,)).fetchall()
        for time, activity, locations in rows:
            yield dt.datetime.fromisoformat(time), activity, json.loads(locations)

    def add_feedback(self, household: str, obj: str, accepted: bool) -> int:
        return self._write("INSERT INTO feedback (household, object, accepted, received_at) VALUES (?, ?, ?, ?)",
                           (household, obj, int(accepted), _now()))

    def feedback(self, household: str) -> list[bool]:
        with self._lock:
            return [bool(r[0]) for r in self._db.execute(
                "SELECT accepted FROM feedback WHERE household = ? ORDER BY id", (household,))]

    def close(self) -> None:
        with self._lock:
            self._db.close()


def _day(payload: dict) -> Day:
    return Day(payload["name"], tuple(payload["minutes"]), tuple(payload["activities"]),
               tuple(tuple(s) for s in payload["locations"]), payload.get("source", ""))
