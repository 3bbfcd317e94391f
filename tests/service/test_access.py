"""Access control, the Host guard, CORS, error shape and limits, over real loopback HTTP."""

import http.server
import threading

import httpx
import pytest

from globe.service.client import GlobeClient, ServiceError, household_payload
from tests.service.conftest import at, upload

pytestmark = pytest.mark.service


def endpoints(name: str) -> list[tuple[str, str, dict | None]]:
    return [
        ("GET", "/households", None),
        ("POST", "/households", {"name": "X", "nodes": []}),
        ("DELETE", f"/households/{name}", None),
        ("POST", f"/households/{name}/observations", {"time": at(0, 400).isoformat(), "activity": "idle"}),
        ("GET", f"/households/{name}/prediction", None),
        ("POST", f"/households/{name}/feedback", {"object": "book", "accepted": True}),
        ("GET", f"/households/{name}/stats", None),
        ("GET", f"/households/{name}/model", None),
    ]


def test_every_endpoint_but_health_needs_a_token(server, households):
    with server.client() as admin:
        upload(admin, "A", households["A"])
        upload(admin, "B", households["B"])
    token_a, token_b = server.token("A"), server.token("B")
    for method, path, body in endpoints("A"):
        for headers in ({}, {"Authorization": "Bearer globe_not-a-real-token"},
                        {"Authorization": "Basic YWRtaW46YWRtaW4="}):
            r = httpx.request(method, server.url + path, json=body, headers=headers)
            assert r.status_code == 401, (method, path, headers, r.text)
            assert r.json()["field"] == "authorization" and r.json()["detail"]
        r = httpx.request(method, server.url + path, json=body, headers={"Authorization": f"Bearer {token_b}"})
        assert r.status_code == 403, (method, path, r.text)  # a token of another household
    admin_only = [e for e in endpoints("A") if e[1] == "/households" or e[0] == "DELETE"]
    for method, path, body in admin_only:
        r = httpx.request(method, server.url + path, json=body, headers={"Authorization": f"Bearer {token_a}"})
        assert r.status_code == 403, (method, path, r.text)
    with GlobeClient(server.url, token=token_a) as own:
        assert own.observe("A", at(0, 400), "idle", {})["step"] == 4  # 06:40 on the household's 10-minute clock
        assert own.prediction("A").status == "ready"
        with pytest.raises(ServiceError) as err:
            own.stats("B")
        assert err.value.status == 403
    assert httpx.get(server.url + "/health").json()["status"] == "ok"  # no token needed


def test_revoked_tokens_and_tokens_of_deleted_households_stop_working(server, households):
    with server.client() as admin:
        upload(admin, "C", households["C"], days=False)
        token = server.token("C")
        with GlobeClient(server.url, token=token) as own:
            assert own.stats("C")["days_learned"] == 0
            r = httpx.get(server.url + "/households", headers={"Authorization": f"Bearer {token}"})
            assert r.status_code == 403
            from globe.service.auth import revoke
            from globe.service.store import Store

            store = Store(server.db)
            assert revoke(store, token) == 1
            store.close()
            with pytest.raises(ServiceError) as err:
                own.stats("C")
            assert err.value.status == 401


def test_host_header_is_checked_and_no_cors_by_default(server):
    for host in ("evil.example", "evil.example:8765", "127.0.0.1.nip.io"):
        r = httpx.get(server.url + "/households", headers={"Host": host, "Authorization": f"Bearer {server.admin}"})
        assert r.status_code == 400 and r.json()["field"] == "host", host
    r = httpx.get(server.url + "/health", headers={"Host": f"localhost:{server.port}", "Origin": "http://evil.example"})
    assert r.status_code == 200 and "access-control-allow-origin" not in r.headers
    pre = httpx.options(server.url + "/households",
                        headers={"Origin": "http://evil.example", "Access-Control-Request-Method": "GET"})
    assert "access-control-allow-origin" not in pre.headers
    import socket

    for hosts in (("127.0.0.1", "evil.example"), ("evil.example", "127.0.0.1"), ("127.0.0.1", "127.0.0.1")):
        with socket.create_connection(("127.0.0.1", server.port), timeout=10) as sock:  # the last one won
            sock.sendall(b"GET /households HTTP/1.1\r\n" + b"".join(f"Host: {h}\r\n".encode() for h in hosts)
                         + f"Authorization: Bearer {server.admin}\r\nConnection: close\r\n\r\n".encode())
            answer = b""
            while chunk := sock.recv(65536):
                answer += chunk
        assert answer.startswith(b"HTTP/1.1 400") and b"2 Host headers" in answer, (hosts, answer[:200])


def test_limits_are_4xx_naming_the_field(make_server, households):
    srv = make_server({"GLOBE_SERVICE__MAX_CLOCK_SKEW": "P400D", "GLOBE_SERVICE__MAX_LOCATIONS": "3",
                       "GLOBE_SERVICE__MAX_HOUSEHOLDS": "1", "GLOBE_SERVICE__MAX_LABEL_LENGTH": "40"})
    h = households["A"]
    with srv.client() as c:
        upload(c, "A", h, days=False)
        too_many = dict(zip(h.objects[:4], [h.nodes[0].node] * 4))
        cases = [
            (lambda: c._call("POST", "/households/A/observations", content=b'{"time": "' + b"x" * (2 << 20) + b'"}',
                             headers={"Content-Type": "application/json"}), 413, "body"),
            (lambda: c.observe("A", at(0, 400), "a" * 41, {}), 422, "activity"),
            (lambda: c.observe("A", at(0, 400), "idle", too_many), 422, "locations"),
            (lambda: c.observe("A", at(0, 400), "idle", {}, id="i" * 41), 422, "id"),
            (lambda: upload(c, "B", households["B"], days=False), 422, "name"),  # one household per service here
            (lambda: c._call("GET", "/no/such/route"), 404, None),
        ]
        for call, status, field in cases:
            with pytest.raises(ServiceError) as err:
                call()
            assert (err.value.status, err.value.field) == (status, field), err.value
        # a chunked body (no Content-Length) is limited too
        def chunks():
            for _ in range(40):
                yield b"x" * 65536
        r = httpx.post(srv.url + "/households/A/observations", content=chunks(),
                       headers={"Authorization": f"Bearer {srv.admin}", "Content-Type": "application/json"})
        assert r.status_code == 413 and r.json() == {"detail": r.json()["detail"], "field": "body"}
        assert c.stats("A")["observations"] == 0


def test_uploaded_maps_and_days_are_validated_like_files(server, households):
    h = households["B"]
    payload = household_payload(h)
    nodes, days = payload["nodes"], payload["days"]
    minute = days[0].split("\n")[5].split(",")[0]
    bad_day = days[0].replace(f"\n{minute},", "\n1,", 1)  # minutes no longer increase
    cases = [
        ({"nodes": nodes[:1] + [dict(nodes[1], start_location="nowhere#0")] + nodes[2:]}, "nodes[1].start_location"),
        ({"nodes": nodes + [nodes[0]]}, f"nodes[{len(nodes)}].node"),
        ({"nodes": nodes, "days": [days[0], bad_day]}, "days[1].minute"),
        ({"nodes": nodes, "days": ["minute,activity\n360,idle\n"]}, f"days[0].{h.objects[0]}"),
        ({"nodes": nodes, "timezone": "Mars/Olympus"}, "timezone"),
        ({"nodes": nodes, "source": "/etc"}, "source"),
    ]
    with server.client() as c:
        for extra, field in cases:
            with pytest.raises(ServiceError) as err:
                c._call("POST", "/households", json={"name": "B", **extra})
            assert err.value.status == 422 and err.value.field == field, (field, err.value)
        assert c.households() == []
        info = c.create_household("B", nodes, days[:3], timezone="Europe/Paris")
        assert info["days_learned"] == 3 and info["timezone"] == "Europe/Paris" and info["objects"] == list(h.objects)


def test_client_raises_a_typed_error_for_non_json_errors():
    class Proxy(http.server.BaseHTTPRequestHandler):
        def do_GET(self):
            self.send_response(502)
            self.send_header("Content-Type", "text/html")
            self.end_headers()
            self.wfile.write(b"<html>bad gateway</html>")

        def log_message(self, *args):
            pass

    httpd = http.server.HTTPServer(("127.0.0.1", 0), Proxy)
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    try:
        with GlobeClient(f"http://127.0.0.1:{httpd.server_address[1]}", token="t") as c:
            with pytest.raises(ServiceError) as err:
                c.stats("A")
        assert err.value.status == 502 and "bad gateway" in err.value.detail and err.value.field is None
    finally:
        httpd.shutdown()


@pytest.mark.parametrize("body", [
    b'{"name": "A", "days": ["x\\ny"]}', b'{"a": 1, "a": 2}', b"[NaN, Infinity, 1e400]", b'"\\ud800"',
    b"\xef\xbb\xbf{}", b" {} ", b"123456789012345678901234567890", b"[1,]", b'{"a": 1,}', b"[1 2]", b"{}x",
    b'{"a": "\x01"}', b"\xff", b"[" * 5000,
])
def test_request_json_is_parsed_and_refused_as_the_standard_library_does(body):
    """The service parses JSON bodies with pydantic-core (faster on a 6 MB upload), and gives
    whatever it refuses to json.loads: the same value, or the same error, for any body."""
    import asyncio
    import json

    from globe.service.fastjson import FastJSONRequest as _FastJSONRequest

    pieces = [body[:3], b"", body[3:7], body[7:]]  # as it may arrive; the Guard sends one piece

    def receiver(parts):
        parts = list(parts)

        async def receive():
            return {"type": "http.request", "body": parts.pop(0), "more_body": bool(parts)}
        return receive

    def parse(parser):
        try:
            return "ok", parser()
        except Exception as err:  # noqa: BLE001 - the kind of error is what is compared
            return "error", type(err)

    expected = parse(lambda: json.loads(body))
    for parts in ([body], pieces):
        request = _FastJSONRequest({"type": "http", "method": "POST", "headers": []}, receiver(parts))
        ours = parse(lambda r=request: asyncio.run(r.json()))
        assert ours[0] == expected[0] and (repr(ours[1]) == repr(expected[1]) if ours[0] == "ok"
                                           else ours[1] is expected[1])
        assert asyncio.run(request.body()) == body
