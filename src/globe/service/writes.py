"""A write the service's store queues for its next group commit, and what it changed.

:class:`~globe.service.store.Store` commits the writes of concurrent requests together; each
caller waits on its own :class:`Write` and learns its own outcome (the row it added, the rows it
changed, its own error), never another's.
"""

from __future__ import annotations

import sqlite3
from dataclasses import dataclass
from typing import Callable, Sequence


def inserted_row(sql: str, cursor: sqlite3.Cursor) -> int:
    """The row id a plain INSERT added; 0 for any other statement (SQLite's last row id would
    then be another statement's, perhaps another caller's in the same commit)."""
    plain = sql.lstrip()[:12].upper() == "INSERT INTO " and "ON CONFLICT" not in sql.upper()
    return (cursor.lastrowid or 0) if plain and cursor.rowcount == 1 else 0


@dataclass(slots=True, eq=False)
class Write:
    """One caller's transaction, queued for the next commit."""

    what: str
    statements: Sequence[tuple[str, tuple]]
    household: str | None
    row: int = 0  # the row id a plain INSERT as first statement added
    changed: int = 0  # how many rows the first statement changed
    error: Exception | None = None
    done: bool = False

    @staticmethod
    def settle(batch: list[Write], error: Callable[[Write], Exception | None],
               cause: Exception | None = None) -> None:
        """Settle every write of ``batch`` with its own error (None: committed)."""
        for w in batch:
            w.error = error(w)
            if w.error is not None and cause is not None:
                w.error.__cause__ = cause
            w.done = True
