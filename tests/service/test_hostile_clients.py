"""Clients that spend the server's memory or connections: unauthenticated bodies, huge headers,
silent and half-sent requests, many household creations at once, and inputs whose error
messages could not be encoded. Real ``globe serve`` process, raw sockets where a client library
would refuse to misbehave; memory is the server's peak RSS (VmHWM, reset before each load)."""

import json
import socket
import threading
import time
from pathlib import Path

import httpx
import pytest

from globe.service.client import household_payload
from tests.service.conftest import at, upload

pytestmark = pytest.mark.service


def rss_mb(pid: int, field: str = "VmRSS:") -> float:
    line = next(x for x in Path(f"/proc/{pid}/status").read_text().splitlines() if x.startswith(field))
    return int(line.split()[1]) / 1024


def peak_growth_mb(pid: int, load) -> float:
    """How far the server's resident memory rose above where it was while ``load()`` ran."""
    before = rss_mb(pid)
    Path(f"/proc/{pid}/clear_refs").write_text("5")  # restart the peak (VmHWM) from now
    load()
    return rss_mb(pid, "VmHWM:") - before


def raw_request(port: int, head: bytes, body: bytes = b"", timeout: float = 30) -> bytes:
    """Send a request as bytes (the body in 1 MiB pieces, stopping if the server closes); the
    status line of the answer, or b"" if the connection was closed without one."""
    s = socket.create_connection(("127.0.0.1", port))
    s.settimeout(timeout)
    try:
        s.sendall(head)
        for i in range(0, len(body), 1 << 20):
            s.sendall(body[i:i + (1 << 20)])
    except OSError:
        pass  # the server stopped reading: what it answered is below
    try:
        return s.recv(4096).split(b"\r\n")[0]
    except OSError:
        return b""
    finally:
        s.close()


def post_head(path: str, length: int, extra: str = "") -> bytes:
    return (f"POST {path} HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
            f"Content-Length: {length}\r\n{extra}\r\n").encode()


def run_all(targets) -> list:
    results = [None] * len(targets)
    threads = [threading.Thread(target=lambda i=i, t=t: results.__setitem__(i, t())) for i, t in enumerate(targets)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    return results


def warm(srv, households) -> None:
    """First-use imports and allocations happen before anything is measured."""
    with srv.client(timeout_s=120) as c:
        upload(c, "warm-up", households["A"])
        c.prediction("warm-up")
        c.delete_household("warm-up")


def test_unauthenticated_bodies_are_refused_before_they_are_read(server, households):
    """8 concurrent unauthenticated 31 MiB POST /households: 401 each, and the server's memory
    does not move (it rose by about 670 MB when bodies were read and parsed before the token)."""
    warm(server, households)
    body = b'{"name": "' + b"x" * (31 << 20) + b'"}'
    statuses: list = []
    grew = peak_growth_mb(server.proc.pid, lambda: statuses.extend(run_all(
        [lambda: raw_request(server.port, post_head("/households", len(body)), body)] * 8)))
    print(f"peak RSS growth under 8 concurrent unauthenticated 31 MiB bodies: {grew:.1f} MB")
    assert grew < 30, grew
    assert all(s in (b"HTTP/1.1 401 Unauthorized", b"") for s in statuses) and b"HTTP/1.1 401 Unauthorized" in statuses
    r = httpx.post(server.url + "/households", content=b'{"name": "A", "nodes": [',
                   headers={"Content-Type": "application/json"})
    assert r.status_code == 401 and r.json()["field"] == "authorization"  # not a 422 about the JSON
    assert httpx.get(server.url + "/health").json()["status"] == "ok"


def test_request_headers_are_bounded(server):
    """A 16 MiB header is refused (431, or the connection closed) once the limit is passed,
    without the server holding it; a 4 KiB one is fine."""
    warm_head = b"GET /health HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Pad: " + b"p" * 4096 + b"\r\n\r\n"
    assert raw_request(server.port, warm_head) == b"HTTP/1.1 200 OK"
    huge = b"GET /health HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Pad: " + b"p" * (16 << 20) + b"\r\n\r\n"
    status: list = []
    grew = peak_growth_mb(server.proc.pid, lambda: status.append(raw_request(server.port, huge)))
    assert status[0] in (b"HTTP/1.1 431 Request Header Fields Too Large", b""), status
    assert grew < 8, grew
    assert httpx.get(server.url + "/health").status_code == 200


def test_silent_half_sent_and_slow_requests_are_closed(make_server):
    """Silent connections, half-sent headers and bodies that stop coming are closed once their
    time limit passes (they stayed open for good)."""
    srv = make_server({"GLOBE_SERVICE__HEADER_TIMEOUT_S": "1", "GLOBE_SERVICE__BODY_TIMEOUT_S": "1"})
    auth = f"Authorization: Bearer {srv.admin}\r\n"
    openings = [b""] * 10 + [b"GET /heal"] * 10 + [b"GET /health HTTP/1.1\r\nHost: 127.0.0.1\r\nX-A: b"] * 10
    openings += [post_head("/households/A/observations", 100, auth) + b'{"time": '] * 10
    sockets = []
    for opening in openings:
        s = socket.create_connection(("127.0.0.1", srv.port))
        s.sendall(opening)
        sockets.append(s)
    started = time.monotonic()
    answers = []
    for s in sockets:
        s.settimeout(max(0.1, started + 8 - time.monotonic()))
        try:
            data = s.recv(4096)
            while data and not data.endswith(b"}"):
                data += s.recv(4096)
            answers.append((data.split(b"\r\n")[0], s.recv(10)))  # the status line, then the end
        except OSError as err:
            answers.append((type(err).__name__.encode(), b"?"))
        s.close()
    assert time.monotonic() - started < 8
    for status, rest in answers:
        assert status in (b"HTTP/1.1 408 Request Timeout", b"") and rest == b"", (status, rest)
    assert sum(status == b"HTTP/1.1 408 Request Timeout" for status, _ in answers) >= 10  # the bodies at least
    assert httpx.get(srv.url + "/health").status_code == 200


def test_concurrent_household_creations_are_throttled(server, households):
    """12 creations of a HOMER+ household sent at once all succeed, read and built a few at a time
    (service.max_concurrent_creations): the peak stays near a few households' worth (it rose by
    about 150 MB for 8 at once, 337 MB for 16, when all were read and built together)."""
    warm(server, households)
    payload = household_payload(households["A"])
    bodies = [json.dumps({"name": f"h{i}", "timezone": "UTC", **payload}).encode() for i in range(12)]
    auth = f"Authorization: Bearer {server.admin}\r\n"
    statuses: list = []
    grew = peak_growth_mb(server.proc.pid, lambda: statuses.extend(run_all(
        [lambda b=b: raw_request(server.port, post_head("/households", len(b), auth), b, timeout=300)
         for b in bodies])))
    print(f"peak RSS growth under 12 concurrent HOMER+ household creations: {grew:.1f} MB")
    assert statuses == [b"HTTP/1.1 201 Created"] * 12
    assert grew < 110, grew
    with server.client() as c:
        assert len(c.households()) == 12


@pytest.mark.parametrize("body", [
    {"time": "T", "locations": {"\ud800": "x"}},
    {"time": "T", "activity": "\udfff idle"},
    {"time": "T", "locations": {"book": "\ud800"}},
    {"time": "T", "id": "\ud800"},
])
def test_every_error_body_is_encodable(server, households, body):
    """Inputs carrying lone surrogates (JSON can, UTF-8 cannot) get a 422 naming the field in a
    JSON body, not a 500 from an error that cannot be encoded."""
    with server.client() as c:
        upload(c, "A", households["A"], days=False)
    body = {**body, "time": at(0, 400).isoformat()}
    r = httpx.post(server.url + "/households/A/observations", content=json.dumps(body).encode(),
                   headers={"Authorization": f"Bearer {server.admin}", "Content-Type": "application/json"})
    assert r.status_code == 422, r.text
    answer = r.json()
    assert set(answer) == {"detail", "field"}, answer
    assert answer["field"].split(".")[0] in ("locations", "activity", "id"), answer
