"""A crash-safe on-disk cache of LLM answers (SQLite, one committed row per answer).

Keyed by backend, model, prompt/context, candidates and parameters, so re-running an
experiment is reproducible and free, and an interrupted run keeps every answer it got.

The cache must never turn a prediction into an error. A failed lookup (the file is locked by
another process, was deleted, or is damaged) raises :class:`LLMCacheError`, an ``LLMError`` the
uncertainty gate already catches: that prediction falls back to the n-gram choice, counted with
its reason. A failed store is counted and logged (the answer is still used). A file that is
not a readable SQLite database is set aside (renamed ``*.corrupt-<time>``) and rebuilt empty,
with a logged warning.
"""

from __future__ import annotations

import hashlib
import json
import logging
import sqlite3
import threading
import time
from collections import Counter
from pathlib import Path
from typing import Any

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
        self.path.parent.mkdir(parents=True, exist_ok=True)
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
            raise LLMCacheError(f"{self.path}: cannot open the answer cache ({_reason(err)}): {err}") from err

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

    def get(self, key: str) -> Any | None:
        with self._lock:
            try:
                row = self._connection().execute("SELECT value FROM answers WHERE key = ?", (key,)).fetchone()
                value = None if row is None else json.loads(row[0])
            except LLMCacheError as err:
                self.errors[_reason(err)] += 1
                raise
            except (sqlite3.Error, ValueError) as err:
                reason = _reason(err)
                self.errors[reason] += 1
                if isinstance(err, sqlite3.Error):
                    self._recover(err)
                raise LLMCacheError(f"answer cache lookup failed ({reason}): {err}") from err
        if row is None:
            self.misses += 1
            return None
        self.hits += 1
        return value

    def put(self, key: str, value: Any) -> None:
        with self._lock:
            try:
                self._connection().execute("INSERT OR REPLACE INTO answers (key, value) VALUES (?, ?)", (key, json.dumps(value)))
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


def _reason(err: Exception) -> str:
    text = str(err).lower()
    if "locked" in text or "busy" in text:
        return "locked"
    if "not a database" in text or "malformed" in text or isinstance(err, ValueError):
        return "corrupt"
    if "no such table" in text or "readonly" in text or "unable to open" in text or "disk i/o" in text:
        return "missing"
    return type(err).__name__
