"""SQLite persistence of the service: households (map, time zone, training logs), every
observation, feedback, and the hashes of access tokens.

The schema (:mod:`globe.service.schema`) is created and migrated here. A file that is not a
GLOBE database, one written by a newer GLOBE, or one that is empty or truncated is refused with a
clear message instead of being altered or started anew.
Every accepted observation is committed before the service replies. The database file, its
write-ahead log and the log's index are watched (see :class:`Store`): if one disappears or is
replaced while the service runs, what was acknowledged stays durable and later writes fail with
:class:`StoreUnavailableError` (503) rather than vanishing.
"""

from __future__ import annotations

import datetime as dt
import json
import logging
import math
import sqlite3
import threading
import time
from dataclasses import fields
from pathlib import Path
from typing import Callable, Iterator, Sequence

from globe.data.records import Household, Node
from globe.data.sensors import Sensor, SensorData, format_events
from globe.errors import StoreError, StoreUnavailableError
from globe.service.dbfile import DatabaseFiles, check_database_file
from globe.service.schema import (
    APPLICATION_ID,
    MIGRATIONS,
    SCHEMA_VERSION,
    SCORE_COLUMNS,
    DayScore,
    FetchRow,
    FoundObservation,
    HouseholdRow,
    StepPrediction,
    StoredDay,
    StoredObservation,
    TokenRow,
)
from globe.service.stored_days import decode_day, encode_day
from globe.service.writes import Write, inserted_row

log = logging.getLogger(__name__)

_NODE_FIELDS = tuple(f.name for f in fields(Node))


def _now() -> str:
    return dt.datetime.now(dt.timezone.utc).isoformat()


class Store:
    """One SQLite file (WAL mode); a lock serialises access across request threads.

    The files are watched: if the database file, its write-ahead log or the log's index
    disappears or is replaced while the service runs, what the log holds is copied into the
    database file at once (so every write acknowledged before is durable) and every later write
    fails with :class:`StoreUnavailableError` (503) until a restart. A failed write (a full disk)
    is reported by :meth:`problem` until a write succeeds."""

    shadow_recheck_s = 1.0
    """How soon another connection's shadow switch reaches :meth:`shadow` (seconds)."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        check_database_file(self.path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._lock = threading.Lock()
        self._queue: list[Write] = []  # writes waiting for the next commit (group commit)
        self._queued = threading.Condition(threading.Lock())  # guards the queue and _committing
        self._committing = False
        self._lost: str | None = None  # why writes stopped for good (a file went away), once seen
        self._failed_write: str | None = None  # the last write's error, until a write succeeds
        self._shadows: dict[str, bool] = {}  # shadow flags read, valid while data_version stays
        self._shadow_version: int | None = None
        self._shadow_checked = -math.inf
        try:
            self._db = sqlite3.connect(self.path, check_same_thread=False, isolation_level=None)
        except sqlite3.Error as err:
            raise StoreError(f"{self.path}: cannot open the database file (SQLite says: {err})") from err
        try:
            self._check_identity()
            self._db.execute("PRAGMA journal_mode=WAL")
            self._db.execute("PRAGMA synchronous=FULL")
            self._db.execute("PRAGMA foreign_keys=ON")
            self._db.execute("PRAGMA busy_timeout=5000")
            self.migrate()
        except sqlite3.DatabaseError as err:
            self._db.close()
            raise StoreError(f"{self.path}: not a GLOBE database (SQLite says: {err})") from err
        except StoreError:
            self._db.close()
            raise
        # Token lookups have their own connection: every request makes one (in the event loop,
        # before its body is read), and a reader in WAL mode never waits for a write under way.
        self._token_db = sqlite3.connect(self.path, check_same_thread=False, isolation_level=None)
        self._token_lock = threading.Lock()
        self._files = DatabaseFiles(self.path)

    # -- identity and schema -------------------------------------------------------------------
    def _check_identity(self) -> None:
        app_id = self._db.execute("PRAGMA application_id").fetchone()[0]
        version = self._db.execute("PRAGMA user_version").fetchone()[0]
        tables = {r[0] for r in self._db.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
        if app_id == APPLICATION_ID:
            if version > SCHEMA_VERSION:
                raise StoreError(f"{self.path}: database schema version {version} is newer than this GLOBE's "
                                 f"({SCHEMA_VERSION}); upgrade GLOBE, or use another --db file")
            return
        legacy = app_id == 0 and 1 <= version < SCHEMA_VERSION and "households" in tables
        fresh = app_id == 0 and version == 0 and not tables
        if not (legacy or fresh):
            raise StoreError(f"{self.path}: not a GLOBE database (application id {app_id:#x}, schema version "
                             f"{version}, {len(tables)} tables); refusing to change it")

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

    def _check_files(self) -> str | None:
        """(Under the lock.) Once a file is gone, what the write-ahead log holds is copied into
        the database file (the acknowledged writes stay durable) and writes stop for good."""
        if self._lost is None:
            reason = self._files.problem()
            if reason is not None:
                saved = ""
                if self._files.database_intact():
                    try:
                        busy, _, copied = self._db.execute("PRAGMA wal_checkpoint(FULL)").fetchone()
                        saved = "" if busy else f"; the {copied} pages its log held were copied into {self.path.name}"
                    except sqlite3.Error as err:
                        saved = f"; copying its log into {self.path.name} failed ({err})"
                self._lost = reason + saved
                log.error("%s: writes are refused until the service restarts", self._lost)
        return self._lost

    def watch(self) -> None:
        """Check the files now (the service calls this every second, so that a deleted log is
        copied into the database file even when no write comes)."""
        with self._lock:
            self._check_files()

    def problem(self) -> str | None:
        """Why writes are refused (a file is gone or was replaced) or failing (the last write's
        error), or None."""
        with self._lock:
            lost = self._check_files()
        if lost:
            return lost
        return self._failed_write

    def _writable(self) -> None:
        reason = self._check_files()
        if reason:
            raise StoreUnavailableError(
                f"{reason}; restart the service (writes are refused so nothing is lost silently)")

    def _transaction(self, what: str, statements: Sequence[tuple[str, tuple]], household: str | None = None) -> int:
        """Run ``statements`` in one transaction, durable when this returns; returns the row id
        the first one added if it is a plain INSERT (else 0). ``household``: whose row they may
        change (its remembered shadow flag is dropped with the commit, under the same lock).

        Group commit: writes that arrive while a commit is under way queue up, and when it ends
        one of them commits them all in one transaction, in the order they came (one sync of the
        log for all instead of one each); each caller returns once its own write is durable."""
        return self._write(what, statements, household).row

    def _write(self, what: str, statements: Sequence[tuple[str, tuple]], household: str | None = None) -> Write:
        """:meth:`_transaction`, returning the settled write."""
        write = Write(what, statements, household)
        with self._queued:
            self._queue.append(write)
            try:
                while self._committing and not write.done:
                    self._queued.wait()
            except BaseException:  # interrupted while waiting: not written, so never written later
                if not write.done:
                    self._queue.remove(write)
                raise
            lead = not write.done
            if lead:  # nobody is committing: commit every queued write
                batch, self._queue, self._committing = self._queue, [], True
        if lead:
            try:
                with self._lock:
                    self._commit(batch)
            finally:
                with self._queued:
                    Write.settle([w for w in batch if not w.done],
                                  lambda w: StoreError(f"cannot {w.what}: the commit was interrupted"))
                    self._committing = False
                    self._queued.notify_all()
        if write.error is not None:
            raise write.error
        return write

    def _commit(self, batch: list[Write]) -> None:
        """(Under the lock.) ``batch`` in one transaction. A statement that fails (a constraint,
        a value SQLite cannot take) fails only its own write: the batch is rolled back and each
        write committed alone. A failing BEGIN or COMMIT (a full disk, a locked file) fails all."""
        try:
            self._writable()
        except StoreUnavailableError as err:
            refused = str(err)
            return Write.settle(batch, lambda w: StoreUnavailableError(refused))
        db = self._db
        try:
            db.execute("BEGIN IMMEDIATE")
        except sqlite3.Error as err:
            return self._failed(batch, err)
        try:
            for w in batch:
                for i, (sql, params) in enumerate(w.statements):
                    cursor = db.execute(sql, params)
                    if i == 0:
                        w.row, w.changed = inserted_row(sql, cursor), cursor.rowcount
        except Exception as err:  # noqa: BLE001 - whatever one write's statements raise fails that write alone
            if db.in_transaction:  # some errors (a full disk) roll back on their own
                db.execute("ROLLBACK")
            if len(batch) == 1:
                return self._failed(batch, err)
            for w in batch:
                self._commit([w])
            return None
        try:
            db.execute("COMMIT")
        except sqlite3.Error as err:
            if db.in_transaction:
                db.execute("ROLLBACK")
            return self._failed(batch, err)
        for w in batch:
            self._shadows.pop(w.household or "", None)
        self._failed_write = None
        if self._check_files() and not self._files.database_intact():  # the log was lost with this commit in it
            return Write.settle(batch, lambda w: StoreUnavailableError(
                f"{self._lost}; cannot {w.what} durably (restart the service)"))
        return Write.settle(batch, lambda w: None)

    def _failed(self, batch: list[Write], err: Exception) -> None:
        if isinstance(err, sqlite3.Error):
            self._note_failure(batch[0].what if len(batch) == 1 else f"{len(batch)} writes", err)
        Write.settle(batch, lambda w: StoreError(f"cannot {w.what}: {err}"), err)

    def _note_failure(self, what: str, err: sqlite3.Error) -> None:
        """A write that failed for the database's sake (not a constraint): reported by /health."""
        if not isinstance(err, sqlite3.IntegrityError):
            self._failed_write = f"the last write failed ({what}: {err}) at {_now()}"
            log.error("%s", self._failed_write)

    def _read(self, sql: str, params: tuple = ()) -> list[tuple]:
        with self._lock:
            try:
                return self._db.execute(sql, params).fetchall()
            except sqlite3.Error as err:
                raise StoreError(f"database read failed: {err}") from err

    # -- households --------------------------------------------------------------------------
    @staticmethod
    def encode_days(day_texts: Sequence[str]) -> list[bytes]:
        """Training days as they are stored: their CSV text, zlib-compressed (a tenth of the size).
        Compression releases the GIL: :class:`DayEncoding` shares the work between threads."""
        return [encode_day(text) for text in day_texts]

    def add_household(self, household: Household, timezone: str, day_texts: Sequence[str],
                      encoded: Sequence[bytes] | None = None, shadow: bool = True,
                      settings: dict | None = None, sensors: SensorData | None = None) -> None:
        """Store the map and the training days (as their CSV text: compact, re-validated on load;
        with the date of each of ``household.train`` named by one) and what it runs (``settings``,
        see schema 7); ``encoded`` is :meth:`encode_days` of ``day_texts`` when the caller has it;
        ``sensors``: the home's sensors and each training day's activations (schema 8)."""
        blobs = self.encode_days(day_texts) if encoded is None else encoded
        if len(blobs) != len(day_texts):
            raise ValueError(f"{len(blobs)} encoded days for {len(day_texts)} day texts")
        stmts: list[tuple[str, tuple]] = [
            ("INSERT INTO households (name, nodes, objects, created_at, timezone, shadow, settings, sensors) "
             "VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
             (household.name, json.dumps([{f: getattr(n, f) for f in _NODE_FIELDS} for n in household.nodes]),
              json.dumps(household.objects), _now(), timezone, int(shadow),
              None if settings is None else json.dumps(settings),
              None if sensors is None else json.dumps([[s.name, s.type, s.room, s.object] for s in sensors.sensors]))),
        ]
        events: list[bytes | None] = [None] * len(household.train)
        if sensors is not None:
            for i, day in enumerate(household.train):
                found = sensors.of(day.name)
                events[i] = None if found is None else encode_day(format_events(found, sensors.sensors))
        dates = [None if d.calendar_date is None else d.calendar_date.isoformat() for d in household.train]
        if len(dates) != len(blobs):
            raise ValueError(f"{len(blobs)} day texts for {len(dates)} training days")
        stmts += [("INSERT INTO training_days (household, position, day, date, events) VALUES (?, ?, ?, ?, ?)",
                   (household.name, i, blob, when, ev)) for i, (blob, when, ev) in enumerate(zip(blobs, dates, events))]
        self._transaction(f"store household {household.name!r}", stmts, household.name)

    def households(self) -> list[HouseholdRow]:
        rows = self._read("SELECT name, timezone, created_at, shadow FROM households ORDER BY created_at, name")
        return [_household_row(*r) for r in rows]

    def household(self, name: str) -> HouseholdRow | None:
        rows = self._read("SELECT name, timezone, created_at, shadow FROM households WHERE name = ?", (name,))
        return _household_row(*rows[0]) if rows else None

    def count_households(self) -> int:
        return self._read("SELECT COUNT(*) FROM households")[0][0]

    def load_map(self, name: str) -> tuple[tuple[Node, ...], tuple[str, ...]]:
        rows = self._read("SELECT nodes, objects FROM households WHERE name = ?", (name,))
        if not rows:
            raise StoreError(f"household {name!r} is not in the database")
        try:
            nodes = tuple(Node(**n) for n in json.loads(rows[0][0]))
            objects = json.loads(rows[0][1])
            texts = ("node", "cls", "category", "start_location")
            if not all(isinstance(getattr(n, f), str) for n in nodes for f in texts) \
                    or not isinstance(objects, list) or not all(isinstance(o, str) for o in objects):
                raise TypeError("a node or object label is not text")
        except (ValueError, TypeError, RecursionError) as err:
            raise StoreError(f"the stored map of household {name!r} is damaged ({type(err).__name__}: {err})") from None
        return nodes, tuple(objects)

    def settings(self, name: str) -> dict:
        """What the household runs (schema 7's JSON; {} when none is stored yet)."""
        rows = self._read("SELECT settings FROM households WHERE name = ?", (name,))
        try:
            found = json.loads(rows[0][0]) if rows and rows[0][0] is not None else {}
        except ValueError as err:
            raise StoreError(f"the stored settings of household {name!r} are damaged ({err})") from None
        if not isinstance(found, dict):
            raise StoreError(f"the stored settings of household {name!r} are not a JSON object")
        return found

    def set_settings(self, name: str, settings: dict) -> int:
        return self._transaction(f"store the settings of household {name!r}", [
            ("UPDATE households SET settings = ? WHERE name = ?", (json.dumps(settings), name))], name)

    def training_days(self, name: str) -> list[StoredDay]:
        """Each stored day: its CSV text (stored zlib-compressed: a tenth of the size; or, from
        schema 1-2 files, a JSON-encoded :class:`Day`), its date, if given, and its sensor events."""
        rows = self._read("SELECT day, date, events FROM training_days WHERE household = ? ORDER BY position", (name,))
        return [StoredDay(decode_day(day), date, None if ev is None else decode_day(ev)) for day, date, ev in rows]

    def sensors(self, name: str) -> tuple[Sensor, ...] | None:
        """The household's sensors (schema 8; None: it has none)."""
        rows = self._read("SELECT sensors FROM households WHERE name = ?", (name,))
        if not rows or rows[0][0] is None:
            return None
        try:
            found = json.loads(rows[0][0])
            return tuple(Sensor(*(str(v) for v in row)) for row in found)
        except (ValueError, TypeError) as err:
            raise StoreError(f"the stored sensors of household {name!r} are damaged ({err})") from None

    def export_household(self, name: str) -> dict | None:
        """Everything stored about a household, as stored (nothing is parsed, so a damaged row is
        exported too): its map's JSON text, its training days' texts and dates, its observations
        and feedback. None if there is no such household."""
        rows = self._read("SELECT name, timezone, created_at, nodes, objects, settings, sensors FROM households "
                          "WHERE name = ?", (name,))
        if not rows:
            return None
        name_, timezone, created_at, nodes, objects, settings, sensors = rows[0]
        observations = self._read("SELECT id, time, activity, locations, received_at, client_id, quarantined, sensors "
                                  "FROM observations WHERE household = ? ORDER BY id", (name,))
        feedback = self._read("SELECT object, accepted, received_at FROM feedback WHERE household = ? ORDER BY id",
                              (name,))
        days = self.training_days(name)
        return {
            "name": name_, "timezone": timezone, "created_at": created_at, "nodes": nodes, "objects": objects,
            "settings": settings, "days": [d.text for d in days], "dates": [d.date for d in days],
            "sensors": sensors, "events": [d.events for d in days],
            "observations": [{"id": i, "time": t, "activity": a, "locations": loc, "received_at": r, "client_id": c,
                              "quarantined": bool(q), "sensors": sn} for i, t, a, loc, r, c, q, sn in observations],
            "feedback": [{"object": o, "accepted": bool(a), "received_at": r} for o, a, r in feedback],
        }

    def delete_household(self, name: str) -> None:
        """Everything about a household, in one transaction (the right to be forgotten)."""
        self._transaction(f"delete household {name!r}", [
            (f"DELETE FROM {table} WHERE household = ?", (name,))
            for table in ("tokens", "feedback", "observations", "training_days", "step_predictions", "fetches",
                          "day_scores")
        ] + [("DELETE FROM households WHERE name = ?", (name,))], name)

    # -- observations and feedback ----------------------------------------------------------
    def add_observation(self, household: str, time: dt.datetime, activity: str | None, locations: dict[str, str],
                        client_id: str | None, ack: dict, also: Sequence[tuple[str, tuple]] = (),
                        sensors: Sequence[tuple[str, dt.datetime, dt.datetime]] = ()) -> int:
        """Store an observation (with the sensor activations it carried), with ``also`` (the scores
        it settles) in the same transaction; returns the observation's row id."""
        events = json.dumps([[n, a.isoformat(), b.isoformat()] for n, a, b in sensors]) if sensors else None
        return self._transaction("store the observation", [(
            "INSERT INTO observations (household, time, activity, locations, received_at, client_id, ack, sensors) "
            "VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
            (household, time.isoformat(), activity, json.dumps(locations, sort_keys=True), _now(), client_id,
             json.dumps(ack), events)), *also])

    def find_observation(self, household: str, client_id: str) -> FoundObservation | None:
        rows = self._read("SELECT id, ack, time, activity, locations FROM observations "
                          "WHERE household = ? AND client_id = ?", (household, client_id))
        if not rows:
            return None
        found_id, ack, time, activity, locations = rows[0]
        try:
            answer = json.loads(ack or "{}")
        except ValueError:
            answer = {}
        return FoundObservation(found_id, answer if isinstance(answer, dict) else {}, time, activity, locations)

    def observations(self, household: str) -> Iterator[StoredObservation]:
        rows = self._read("SELECT id, time, activity, locations, received_at, sensors FROM observations "
                          "WHERE household = ? AND quarantined = 0 ORDER BY id", (household,))
        for r in rows:
            yield StoredObservation(*r)

    def quarantine(self, ids: Sequence[int]) -> None:
        """Set rows aside that cannot be replayed (kept for inspection, never replayed again)."""
        if ids:
            self._transaction("quarantine observations",
                              [("UPDATE observations SET quarantined = 1 WHERE id = ?", (i,)) for i in ids])

    def quarantined(self, household: str) -> int:
        return self._read("SELECT COUNT(*) FROM observations WHERE household = ? AND quarantined = 1",
                          (household,))[0][0]

    def add_feedback(self, household: str, obj: str, accepted: bool) -> int:
        return self._transaction("store the feedback", [(
            "INSERT INTO feedback (household, object, accepted, received_at) VALUES (?, ?, ?, ?)",
            (household, obj, int(accepted), _now()))])

    def feedback(self, household: str) -> list[bool]:
        rows = self._read("SELECT accepted FROM feedback WHERE household = ? ORDER BY id", (household,))
        return [bool(r[0]) for r in rows]

    # -- shadow mode and online scores -------------------------------------------------------
    def set_shadow(self, household: str, shadow: bool) -> int:
        return self._transaction("switch shadow mode", [("UPDATE households SET shadow = ? WHERE name = ?",
                                                  (int(shadow), household))], household)

    def shadow(self, household: str) -> bool:
        """Whether the household is in shadow mode. Asked at every prediction, so kept in memory
        (no wait for the store's lock behind other households' writes). This connection's own
        switches show at once (dropped with their commit, which ``data_version`` does not count);
        another's (``globe household shadow`` under a running service) within
        :attr:`shadow_recheck_s`, once ``data_version`` changes."""
        found, now = self._shadows.get(household), time.monotonic()
        if found is not None:
            if now - self._shadow_checked < self.shadow_recheck_s:
                return found
            self._shadow_checked = now  # this caller rechecks; the others keep the flag meanwhile
        with self._lock:
            try:
                version = self._db.execute("PRAGMA data_version").fetchone()[0]
                self._shadow_checked = time.monotonic()
                if version != self._shadow_version:
                    self._shadows, self._shadow_version = {}, version
                found = self._shadows.get(household)
                if found is None:
                    rows = self._db.execute("SELECT shadow FROM households WHERE name = ?", (household,)).fetchall()
                    if not rows:
                        return True
                    found = self._shadows[household] = bool(rows[0][0])
            except sqlite3.Error as err:
                raise StoreError(f"database read failed: {err}") from err
        return found

    def add_fetch(self, household: str, day: str, step: int, obj: str, to_location: str | None,
                  probability: float | None, shadow: bool) -> None:
        self._transaction("store the fetch decision", [(
            "INSERT INTO fetches (household, day, step, object, to_location, probability, shadow, made_at) "
            "VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
            (household, day, step, obj, to_location, probability, int(shadow), _now()))])

    def step_predictions(self, household: str, day: str) -> list[StepPrediction]:
        rows = self._read("SELECT step, activity, probability, observed FROM step_predictions "
                          "WHERE household = ? AND day = ? ORDER BY step", (household, day))
        return [StepPrediction(*r) for r in rows]

    def fetches(self, household: str, day: str) -> list[FetchRow]:
        """The fetches decided since the day (re)started and not yet counted in its scores."""
        rows = self._read("SELECT day, step, object, to_location, probability, shadow, made_at FROM fetches "
                          "WHERE household = ? AND day = ? AND settled = 0 ORDER BY id", (household, day))
        return [FetchRow(d, s, o, t, p, bool(sh), m) for d, s, o, t, p, sh, m in rows]

    def day_scores(self, household: str, since: str) -> list[DayScore]:
        """The per-day scores of days from ``since`` (ISO date) on, oldest first."""
        rows = self._read(f"SELECT day, {', '.join(SCORE_COLUMNS)} FROM day_scores WHERE household = ? AND day >= ? "
                          "ORDER BY day", (household, since))
        return [DayScore(*r) for r in rows]

    def feedback_since(self, household: str, since: str) -> list[tuple[str, bool, str]]:
        """(object, accepted, received_at) of the feedback received from ``since`` (ISO time, UTC) on."""
        rows = self._read("SELECT object, accepted, received_at FROM feedback WHERE household = ? AND received_at >= ? "
                          "ORDER BY id", (household, since))
        return [(o, bool(a), r) for o, a, r in rows]

    def secret(self, key: str, make: Callable[[], str]) -> str:
        """A server secret kept in the database (made by ``make`` the first time)."""
        found = self._read("SELECT value FROM settings WHERE key = ?", (key,))
        if found:
            return found[0][0]
        self._transaction("store a server secret", [("INSERT OR IGNORE INTO settings (key, value) VALUES (?, ?)",
                                                     (key, make()))])
        return self._read("SELECT value FROM settings WHERE key = ?", (key,))[0][0]

    def end_session(self, nonce: str, expires: int) -> None:
        """Note a dashboard session as ended (logged out) until it would have expired; sessions
        that have expired anyway are forgotten."""
        now = int(time.time())
        self._transaction("end a dashboard session", [
            ("DELETE FROM settings WHERE key LIKE 'ended_session:%' AND CAST(value AS INTEGER) < ?", (now,)),
            ("INSERT OR REPLACE INTO settings (key, value) VALUES (?, ?)", (f"ended_session:{nonce}", str(expires)))])

    def session_ended(self, nonce: str) -> bool:
        return bool(self._read("SELECT 1 FROM settings WHERE key = ?", (f"ended_session:{nonce}",)))

    # -- tokens ------------------------------------------------------------------------------
    def add_token(self, token_id: str, digest: str, household: str | None, admin: bool) -> None:
        self._transaction("store the token", [(
            "INSERT INTO tokens (id, hash, household, admin, created_at) VALUES (?, ?, ?, ?, ?)",
            (token_id, digest, household, int(admin), _now()))])

    def token(self, digest: str) -> TokenRow | None:
        """The token with this hash (on the token connection: never waits for a write)."""
        return self._token_where("hash", digest)

    def token_by_id(self, token_id: str) -> TokenRow | None:
        """The token with this id (a dashboard session names its token by id, never by the token)."""
        return self._token_where("id", token_id)

    def _token_where(self, column: str, value: str) -> TokenRow | None:
        with self._token_lock:
            try:
                rows = self._token_db.execute("SELECT id, household, admin, created_at, revoked_at FROM tokens "
                                              f"WHERE {column} = ?", (value,)).fetchall()
            except sqlite3.Error as err:
                raise StoreError(f"database read failed: {err}") from err
        return TokenRow(rows[0][0], rows[0][1], bool(rows[0][2]), rows[0][3], rows[0][4]) if rows else None

    def revoke_token(self, token_id: str | None = None, digest: str | None = None) -> int:
        """Revoke by id or hash; returns how many tokens were revoked (0 if none matched)."""
        return self._write("revoke the token", [("UPDATE tokens SET revoked_at = ? WHERE (id = ? OR hash = ?) "
                                                 "AND revoked_at IS NULL", (_now(), token_id, digest))]).changed

    def tokens(self) -> list[TokenRow]:
        rows = self._read("SELECT id, household, admin, created_at, revoked_at FROM tokens ORDER BY created_at")
        return [TokenRow(r[0], r[1], bool(r[2]), r[3], r[4]) for r in rows]

    def close(self) -> None:
        with self._token_lock:
            self._token_db.close()
        with self._lock:
            self._db.close()
            self._files.close()


def _aware(text: str) -> dt.datetime:
    t = dt.datetime.fromisoformat(text)
    return t if t.tzinfo else t.replace(tzinfo=dt.timezone.utc)


def _household_row(name: str, timezone: object, created_at: object, shadow: object = 0) -> HouseholdRow:
    """A stored household's row; one whose creation time cannot be read says so in ``problem``
    (it is then served as failed) instead of stopping whoever lists the households."""
    try:
        created = _aware(created_at)  # type: ignore[arg-type]
    except (TypeError, ValueError) as err:
        return HouseholdRow(name, str(timezone), dt.datetime.fromtimestamp(0, dt.timezone.utc),
                            f"its stored creation time {str(created_at)[:40]!r} cannot be read ({err})", bool(shadow))
    return HouseholdRow(name, str(timezone), created, shadow=bool(shadow))
