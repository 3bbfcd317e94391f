"""The database file on disk, before SQLite opens it: a file that cannot hold what was stored
(a folder, an empty or truncated file) is refused in one line, and ``globe serve --new-db`` sets
a damaged one aside instead of starting over in its place."""

from __future__ import annotations

import datetime as dt
import os
from pathlib import Path

from globe.errors import DamagedDatabaseError, StoreError

SIDE_FILES = ("-wal", "-shm")  # SQLite's write-ahead log and its index, beside the database file


def check_database_file(path: Path) -> None:
    """Refuse, before SQLite opens it, a database file that cannot hold what was stored: a
    folder, an empty file (SQLite would start an empty database in it, and every robot's token
    would be unknown), or a file shorter than its own header says (truncated)."""
    path = Path(path)
    if path.is_dir():
        raise StoreError(f"{path}: is a folder; --db names the database file (e.g. {path / 'globe.sqlite3'})")
    try:
        size = path.stat().st_size
        with open(path, "rb") as fh:
            header = fh.read(100)
    except FileNotFoundError:
        return  # a new database
    except OSError as err:
        raise StoreError(f"{path}: cannot read the database file: {err.strerror or err}") from err
    fix = "restore it from a backup, or start a new database with --new-db (the file is kept beside it)"
    if size == 0:
        raise DamagedDatabaseError(f"{path}: the database file is empty (0 bytes): a database that was truncated, or a "
                                   f"file another program created; {fix}")
    if not header.startswith(b"SQLite format 3\x00"):
        return  # not SQLite at all: the identity check says so
    if size < 100:
        raise DamagedDatabaseError(f"{path}: the database file is truncated ({size} bytes, shorter than its header); "
                                   f"{fix}")
    page_size = int.from_bytes(header[16:18], "big")
    page_size = 65536 if page_size == 1 else page_size
    pages, changes, valid_for = (int.from_bytes(header[i:i + 4], "big") for i in (28, 24, 92))
    if pages and changes == valid_for and size < page_size * pages:
        raise DamagedDatabaseError(f"{path}: the database file is truncated ({size} bytes; its header says "
                                   f"{page_size * pages}); {fix}")


def _file_id(path: Path) -> tuple[int, int] | None:
    try:
        st = os.stat(path)
    except OSError:
        return None
    return st.st_dev, st.st_ino


class DatabaseFiles:
    """The database file and its side files as first seen (device and inode), so that one going
    away or being replaced while the service runs is noticed; a side file SQLite has not created
    yet is noted when it appears."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self._known = {suffix: _file_id(Path(str(self.path) + suffix)) for suffix in ("", *SIDE_FILES)}

    def database_intact(self) -> bool:
        return _file_id(self.path) == self._known[""]

    def problem(self) -> str | None:
        """Which file went away or was replaced, or None."""
        for suffix, known in self._known.items():
            name = Path(str(self.path) + suffix)
            now = _file_id(name)
            if known is None and suffix:
                self._known[suffix] = now
            elif now is None:
                return f"database file {name} has disappeared"
            elif now != known:
                return f"database file {name} was replaced while the service ran"
        return None


def set_aside_database(path: Path) -> Path:
    """Rename a damaged database file (and its side files) to ``<name>.damaged-<time>``, so that a
    new one can start in its place; returns the new name."""
    path = Path(path)
    target = path.with_name(f"{path.name}.damaged-{dt.datetime.now().strftime('%Y%m%dT%H%M%S')}")
    for suffix in ("", *SIDE_FILES):
        source = Path(str(path) + suffix)
        if source.exists():
            source.replace(Path(str(target) + suffix))
    return target
