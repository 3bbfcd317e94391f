"""The database's files under a running service, and at start-up: whatever happens to them, an
acknowledged write is durable or the service stops acknowledging; an empty or truncated database
is refused, not restarted empty; failing writes show in /health. Real server, real SQLite."""

import os
import resource
import sqlite3
import subprocess
import sys
from pathlib import Path

import httpx
import pytest

from globe.service.auth import create_token
from globe.service.client import ServiceError
from tests.service.conftest import REPLAY_ENV, at, upload

pytestmark = pytest.mark.service


@pytest.mark.parametrize("side", ["-wal", "-shm"])
def test_a_deleted_write_ahead_log_loses_nothing_acknowledged(server, households, side):
    """After the log (or its index) is deleted under the service, what was acknowledged before
    survives a SIGKILL, and nothing more is acknowledged (503, /health degraded)."""
    h = households["A"]
    acknowledged = 0
    with server.client() as c:
        upload(c, "A", h, days=False)
        for t in range(30):
            c.observe("A", at(0, 360 + 10 * t), "reading", {})
            acknowledged += 1
        Path(str(server.db) + side).unlink()
        for t in range(30, 60):
            try:
                c.observe("A", at(0, 360 + 10 * t), "reading", {})
                acknowledged += 1
            except ServiceError as err:
                assert err.status == 503 and side in err.detail, err
        with pytest.raises(ServiceError) as err:
            upload(c, "B", households["B"], days=False)
        assert err.value.status == 503
        health = httpx.get(server.url + "/health").json()
        assert health["status"] == "degraded" and side in health["database"], health
    server.kill()
    server.start()
    with server.client() as c:
        assert c.stats("A")["observations"] == acknowledged == 30
        assert c.households() == ["A"]


def serve(db: Path, *extra: str) -> subprocess.CompletedProcess:
    """``globe serve`` on a port nothing may reach: returns at once when the database is refused."""
    return subprocess.run([sys.executable, "-m", "globe", "serve", "--db", str(db), "--port", "1", *extra],
                          capture_output=True, text=True, timeout=120, env={**os.environ, "GLOBE_LLM__BACKEND": "none"})


@pytest.mark.parametrize("cut", ["empty", "half"])
def test_an_empty_or_truncated_database_is_refused_unless_a_new_one_is_asked_for(server, households, cut):
    with server.client() as c:
        upload(c, "A", households["A"])
    server.stop()  # the log is copied into the file and removed
    size = server.db.stat().st_size
    assert size > 100_000 and not Path(str(server.db) + "-wal").exists()
    with open(server.db, "r+b") as fh:
        fh.truncate(0 if cut == "empty" else size // 2)
    r = serve(server.db)
    assert r.returncode == 1 and "Traceback" not in r.stderr, r.stderr
    message = r.stderr.strip().splitlines()[-1]
    assert ("is empty (0 bytes)" if cut == "empty" else "is truncated") in message and "--new-db" in message, message
    assert server.db.stat().st_size == (0 if cut == "empty" else size // 2)  # left as it was
    server.args = ["--new-db"]
    server.start()  # the operator asks for a new database: the damaged file is kept beside it
    kept = [p for p in server.db.parent.iterdir() if p.name.startswith(server.db.name + ".damaged-")]
    assert len(kept) == 1 and kept[0].stat().st_size == (0 if cut == "empty" else size // 2)
    assert httpx.get(server.url + "/health").json()["status"] == "ok"
    with server.client(token=create_token(server.db, admin=True)) as c:
        assert c.households() == []


def test_a_database_path_that_is_a_folder_is_one_line(tmp_path):
    r = serve(tmp_path)
    assert r.returncode == 1 and "Traceback" not in r.stderr and "is a folder" in r.stderr, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1


def test_health_is_degraded_while_writes_fail(make_server, households):
    """A full disk (here: the server's file-size limit) fails writes with 503, and /health says so
    until a write succeeds again."""
    limit = 192 << 10  # the map of A fits; the 65 days of B (about 210 KB compressed) do not
    srv = make_server(REPLAY_ENV, preexec_fn=lambda: resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit)))
    with srv.client() as c:
        upload(c, "small", households["A"], days=False)
        assert httpx.get(srv.url + "/health").json()["status"] == "ok"
        with pytest.raises(ServiceError) as err:
            upload(c, "big", households["B"])  # 65 days: far more than half a megabyte of log
        assert err.value.status == 503
        health = httpx.get(srv.url + "/health").json()
        assert health["status"] == "degraded" and "the last write failed" in health["database"], health
        assert c.households() == ["small"]
        c.observe("small", at(0, 400), "reading", {})  # a small write succeeds again
        assert httpx.get(srv.url + "/health").json()["status"] == "ok"
    db = sqlite3.connect(srv.db)
    assert db.execute("SELECT COUNT(*) FROM observations").fetchone()[0] == 1
    db.close()
