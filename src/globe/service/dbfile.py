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
        damage = shortened(path)
    except FileNotFoundError:
        return  # a new database
    except OSError as err:
        raise StoreError(f"{path}: cannot read the database file: {err.strerror or err}") from err
    if damage is not None:
        raise DamagedDatabaseError(f"{path}: {damage}; restore it from a backup, or start a new database with --new-db "
                                   "(the file is kept beside it)")


def shortened(path: Path, fd: int | None = None) -> str | None:
    """How a database file is shorter than what it held (empty, or shorter than its header says),
    or None (OSError when it cannot be read). ``fd``: the file, open already. A process using the
    database must pass one it keeps open: closing any descriptor of the file drops every POSIX
    lock the process holds on it, SQLite's among them (its connections would then read stale pages)."""
    if fd is None:
        with open(path, "rb") as fh:
            return shortened(path, fh.fileno())
    size = os.fstat(fd).st_size
    header = os.pread(fd, 100, 0)
    if size == 0:
        return "the database file is empty (0 bytes): a database that was truncated, or a file another program created"
    if not header.startswith(b"SQLite format 3\x00"):
        return None  # not SQLite at all: the identity check says so
    if size < 100:
        return f"the database file is truncated ({size} bytes, shorter than its header)"
    page_size = int.from_bytes(header[16:18], "big")
    page_size = 65536 if page_size == 1 else page_size
    pages, changes, valid_for = (int.from_bytes(header[i:i + 4], "big") for i in (28, 24, 92))
    if pages and changes == valid_for and size < page_size * pages:
        return f"the database file is truncated ({size} bytes; its header says {page_size * pages})"
    return None


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
        self._short: str | None = None  # how the file looked cut short at the last look
        self._fd: int | None = None  # the database file, open while the store is (see :func:`shortened`)
        try:
            self._fd = os.open(self.path, os.O_RDONLY)
        except OSError:
            pass

    def close(self) -> None:
        """After the database's connections are closed (this drops the process's locks on it)."""
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None

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
        if self._fd is None:
            return None
        try:
            damage = shortened(self.path, self._fd)
        except OSError:
            damage = "it cannot be read"
        # Twice in a row: another process's checkpoint may write the header before the pages it counts.
        seen, self._short = self._short, damage
        return None if damage is None or seen is None else f"database file {self.path} was cut short ({damage})"


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
