"""Small helpers shared by tests."""

import itertools
import os
import random
import socket
from typing import NoReturn

#: Ports below the kernel's ephemeral range (32768 up on Linux), a slice per pytest-xdist worker.
_WORKER_PORTS, _PORTS_PER_WORKER = 20000, 500
_next_port: "itertools.count[int] | None" = None


def free_port() -> int:
    """A TCP port on loopback that nothing listens on right now. Under pytest-xdist each worker
    hands out the ports of its own slice in turn, so another worker (or an outgoing connection,
    which gets an ephemeral port) cannot take the same port before the server binds it; a plain
    run lets the kernel choose."""
    global _next_port
    worker = os.environ.get("PYTEST_XDIST_WORKER", "")
    if worker.startswith("gw") and worker[2:].isdigit():
        first = _WORKER_PORTS + int(worker[2:]) % 24 * _PORTS_PER_WORKER
        if _next_port is None:
            _next_port = itertools.count(random.randrange(_PORTS_PER_WORKER))
        for _ in range(_PORTS_PER_WORKER):
            port = first + next(_next_port) % _PORTS_PER_WORKER
            with socket.socket() as s:
                try:
                    s.bind(("127.0.0.1", port))
                except OSError:
                    continue  # in use (another program, or a server of this run not yet gone)
                return port
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def enumerate_paths(model, history, steps: int) -> list[tuple[float, tuple[str, ...]]]:
    """Every continuation of ``history`` by ``steps`` activities that ``model.predict_proba``
    allows, with its probability: the exact answer a beam without pruning must give."""
    out: list[tuple[float, tuple[str, ...]]] = [(1.0, ())]
    for _ in range(steps):
        grown = []
        for p, path in out:
            for a, q in model.predict_proba(tuple(history) + path).items():
                if q > 0:
                    grown.append((p * q, path + (a,)))
        out = grown
    return out


def absent(message: str) -> NoReturn:
    """What a test does when something it needs outside Python is missing: skip, saying what to
    install, on a developer's machine; fail under ``CI=true`` (CI installs everything: its absence
    there is a broken set-up, not a skip)."""
    import os

    import pytest

    if os.environ.get("CI", "").lower() == "true":
        pytest.fail(message)
    pytest.skip(message)


def require_system(*names: str, install: str) -> None:
    """:func:`absent` unless every system program in ``names`` is on the PATH."""
    import shutil

    missing = [n for n in names if shutil.which(n) is None]
    if missing:
        absent(f"{', '.join(missing)} not found: install {install}")


def results_folder(*parts: str):
    """Where a test run writes what a person looks at afterwards (screenshots): ``$GLOBE_TEST_RESULTS``,
    else ``results/test-run`` under the repository root (ignored by git)."""
    import os
    from pathlib import Path

    root = Path(os.environ.get("GLOBE_TEST_RESULTS") or Path(__file__).resolve().parents[1] / "results" / "test-run")
    folder = root.joinpath(*parts)
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def database_at_schema(path, version: int):
    """A service database created by the first ``version`` migrations (as an older GLOBE left it):
    an open sqlite3 connection in autocommit mode, to fill with that schema's rows."""
    import sqlite3

    from globe.service.schema import MIGRATIONS

    db = sqlite3.connect(path, isolation_level=None)
    for number, script in enumerate(MIGRATIONS[:version], start=1):
        for statement in filter(str.strip, script.split(";")):
            db.execute(statement)
        db.execute(f"PRAGMA user_version = {number}")
    return db
