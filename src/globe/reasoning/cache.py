"""A crash-safe on-disk cache of LLM answers (SQLite, one committed row per answer).

Keyed by backend, model, prompt/context, candidates and parameters, so re-running an
experiment is reproducible and free, and an interrupted run keeps every answer it got.

The cache must never turn a prediction into an error. A failed lookup (the file is locked by
another process, was deleted, or is damaged; its folder cannot be made; a stored answer is not
of the shape its reader expects, e.g. ``"abc"``, ``[]`` or ``NaN`` where scores belong) raises
:class:`LLMCacheError`, an ``LLMError`` the uncertainty gate already catches: that prediction
falls back to the n-gram choice, counted with its reason. A misshapen answer is deleted, so the
question is asked afresh next time. A failed store is counted and logged (the answer is still
used). A file that is not a readable SQLite database is set aside (renamed ``*.corrupt-<time>``)
and rebuilt empty, with a logged warning. Nothing about the cache stops a program from starting.
"""

from __future__ import annotations

import hashlib
import json
import logging
import math
import sqlite3
import threading
import time
from collections import Counter
from pathlib import Path
from typing import Any, Callable

from globe.errors import LLMCacheError

log = logging.getLogger(__name__)

_SCHEMA = "CREATE TABLE IF NOT EXISTS answers (key TEXT PRIMARY KEY, value TEXT NOT NULL)"


def cache_key(**parts: Any) -> str:
    blob = json.dumps(parts, sort_keys=True, ensure_ascii=False, default=str)
    return hashlib.sha256(blob.encode("utf-8")).hexdigest()


def _corrupt(err: sqlite3.Error) -> bool:
    text = str(err).lower()
    return isinstance(err, sqlite3.DatabaseError) and ("not a database" in text or "malformed" in text)


class AnswerCache:
    """Maps a key to a JSON value; every ``put`` is committed before it returns."""

    def __init__(self, path: Path, *, timeout_s: float = 0.25) -> None:
        self.path = Path(path)
        self.timeout_s = timeout_s
        self._lock = threading.Lock()
        self.hits = 0
        self.misses = 0
        self.errors: Counter[str] = Counter()  # reason -> failed lookups or stores
        self.set_aside: list[Path] = []
        self._db: sqlite3.Connection | None = None
        try:
            self._db = self._open()
        except LLMCacheError as err:  # e.g. locked right now: retried at each lookup
            log.warning("%s", err)

    def _connect(self) -> sqlite3.Connection:
        self.path.parent.mkdir(parents=True, exist_ok=True)  # OSError if a file stands in its way
        db = sqlite3.connect(self.path, check_same_thread=False, isolation_level=None, timeout=self.timeout_s)
        try:
            db.execute("PRAGMA journal_mode=WAL")
            db.execute("PRAGMA synchronous=NORMAL")
            db.execute(_SCHEMA)
            db.execute("SELECT COUNT(*) FROM answers LIMIT 1").fetchone()
        except sqlite3.Error:
            db.close()
            raise
        return db

    def _open(self) -> sqlite3.Connection:
        try:
            try:
                return self._connect()
            except sqlite3.Error as err:
                if not _corrupt(err):
                    raise
                self._set_aside(err)
                return self._connect()
        except (sqlite3.Error, OSError) as err:
            failure = LLMCacheError(f"{self.path}: cannot open the answer cache ({_reason(err)}): {err}")
            failure.reason = _reason(err)
            raise failure from err

    def _set_aside(self, err: sqlite3.Error) -> None:
        target = self.path.with_name(f"{self.path.name}.corrupt-{time.strftime('%Y%m%dT%H%M%S')}")
        for suffix in ("", "-wal", "-shm"):
            src = Path(str(self.path) + suffix)
            if src.exists():
                src.replace(Path(str(target) + suffix))
        self.set_aside.append(target)
        log.warning("LLM answer cache %s is damaged (%s): set aside as %s and rebuilt empty", self.path, err, target)

    def _connection(self) -> sqlite3.Connection:
        if self._db is None:
            self._db = self._open()
        return self._db

    def _recover(self, err: sqlite3.Error) -> None:
        """After a failure: a damaged file is set aside and the cache reopened empty."""
        if not _corrupt(err):
            return
        try:
            if self._db is not None:
                self._db.close()
        except sqlite3.Error:
            pass
        self._db = None
        try:
            self._set_aside(err)
            self._db = self._connect()
        except (OSError, sqlite3.Error) as again:  # pragma: no cover - the next lookup reports it
            log.warning("LLM answer cache %s could not be rebuilt: %s", self.path, again)

    def get(self, key: str, valid: Callable[[Any], bool] | None = None) -> Any | None:
        """The stored answer, or None; :class:`LLMCacheError` if it cannot be read, or if
        ``valid`` says it is not of the expected shape (it is then deleted)."""
        with self._lock:
            try:
                row = self._connection().execute("SELECT value FROM answers WHERE key = ?", (key,)).fetchone()
            except LLMCacheError as err:
                self.errors[_reason(err)] += 1
                raise
            except sqlite3.Error as err:
                reason = _reason(err)
                self.errors[reason] += 1
                self._recover(err)
                raise LLMCacheError(f"answer cache lookup failed ({reason}): {err}") from err
            value, readable = None, True
            if row is not None:
                try:
                    value = json.loads(row[0])
                except (TypeError, ValueError, RecursionError):
                    readable = False
            if row is not None and (not readable or (valid is not None and not valid(value))):
                self.errors["corrupt"] += 1
                shown = str(row[0]) if len(str(row[0])) <= 60 else str(row[0])[:60] + "..."
                log.warning("LLM answer cache %s: a stored answer is not of the expected shape (%s): deleted",
                            self.path, shown)
                try:
                    self._connection().execute("DELETE FROM answers WHERE key = ?", (key,))
                except (sqlite3.Error, LLMCacheError) as err:
                    log.warning("LLM answer cache %s: could not delete it: %s", self.path, err)
                raise LLMCacheError(f"answer cache entry is not of the expected shape ({shown!r}); asked afresh next "
                                    "time")
        if row is None:
            self.misses += 1
            return None
        self.hits += 1
        return value

    def put(self, key: str, value: Any) -> None:
        with self._lock:
            try:
                self._connection().execute("INSERT OR REPLACE INTO answers (key, value) VALUES (?, ?)",
                                           (key, json.dumps(value)))
            except LLMCacheError as err:
                self.errors[_reason(err)] += 1
                log.warning("LLM answer not cached: %s", err)
            except sqlite3.Error as err:
                self.errors[_reason(err)] += 1
                log.warning("LLM answer not cached (%s): %s", _reason(err), err)
                self._recover(err)

    def __len__(self) -> int:
        with self._lock:
            return self._connection().execute("SELECT COUNT(*) FROM answers").fetchone()[0]

    def close(self) -> None:
        with self._lock:
            if self._db is not None:
                self._db.close()
                self._db = None


def finite_number(value: Any) -> bool:
    """A JSON number that is a real score: not a bool, not NaN or infinite."""
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _reason(err: Exception) -> str:
    if isinstance(err, LLMCacheError) and err.reason:
        return err.reason
    text = str(err).lower()
    if "locked" in text or "busy" in text:
        return "locked"
    if "not a database" in text or "malformed" in text or isinstance(err, (ValueError, RecursionError)):
        return "corrupt"
    if "no such table" in text or "readonly" in text or "unable to open" in text or "disk i/o" in text \
            or isinstance(err, OSError):
        return "missing"
    return type(err).__name__
