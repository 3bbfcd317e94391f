"""The outermost ASGI layer of the service, applied before anything reads a request body: the
Host allow-list, authentication from the headers (no memory is spent on the body of a request
without a known token, and such a request is a 401 whatever its body), the body-size limits, a
time limit on the body, and a bound on how many household creations are read and built at once.

Errors are ``{"detail", "field"}`` like every other; a refusal sent before the body was read
closes the connection, so nothing more of that body is read either.
"""

from __future__ import annotations

import asyncio
from typing import Any

from fastapi.responses import JSONResponse
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from globe.config import ServiceConfig
from globe.errors import GlobeError
from globe.service import auth

PUBLIC_PATHS = frozenset({"/health", "/openapi.json", "/docs", "/docs/oauth2-redirect", "/redoc"})
"""Paths answered without a token (none reads a body or tells anything about a household)."""
DASHBOARD = "/dashboard"
"""The dashboard's paths: a browser sends no Authorization header, its session cookie is checked by
:mod:`globe.service.routes.dashboard` (the Host allow-list and the body limits still apply here)."""
DASHBOARD_FORM_BYTES = 8192
"""The largest body a dashboard form may post: its forms are read before anyone is known."""


def printable(text: str) -> str:
    """``text`` as UTF-8 can carry it: a lone surrogate (JSON's ``"\\ud800"``) becomes its escape."""
    return text.encode("utf-8", "backslashreplace").decode("utf-8")


def error_response(status: int, detail: str, field: str | None, headers: dict[str, str] | None = None) -> JSONResponse:
    """Every error the service sends: ``{"detail", "field"}``, encodable whatever the input was."""
    return JSONResponse({"detail": printable(detail), "field": None if field is None else printable(field)},
                        status_code=status, headers=headers)


class Guard:
    """See the module: host, token, size, time and creation limits, before the body is read."""

    def __init__(self, app: ASGIApp, service: ServiceConfig) -> None:
        self.app = app
        self.any_host = "*" in service.allowed_hosts
        self.hosts = {h.lower().strip("[]") for h in service.allowed_hosts}
        self.limit = service.max_body_bytes
        self.household_limit = service.max_household_bytes
        self.body_timeout_s = service.body_timeout_s
        self.creations = asyncio.Semaphore(service.max_concurrent_creations)

    @staticmethod
    def _hostname(value: str) -> str:
        value = value.strip().lower()
        if value.startswith("["):  # [::1]:8765
            return value[1:value.find("]")] if "]" in value else value
        return value.rsplit(":", 1)[0] if value.count(":") == 1 else value

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        headers = {k.decode("latin-1").lower(): v.decode("latin-1") for k, v in scope.get("headers", [])}
        declared = headers.get("content-length")
        pending_body = (declared not in (None, "0")) or "transfer-encoding" in headers

        async def refuse(status: int, detail: str, field: str | None, extra: dict[str, str] | None = None) -> None:
            closing = {"Connection": "close"} if pending_body else {}  # the body is not read: neither is the rest
            await error_response(status, detail, field, {**(extra or {}), **closing})(scope, receive, send)

        hosts = [v for k, v in scope.get("headers", []) if k.lower() == b"host"]
        if len(hosts) > 1:  # which one a proxy or the app reads differs: a rebinding trick, or a broken client
            await refuse(400, f"{len(hosts)} Host headers (a request has one)", "host")
            return
        host = self._hostname(headers.get("host", ""))
        if not self.any_host and host not in self.hosts:
            await refuse(400, f"host {host[:64]!r} is not allowed (service.allowed_hosts)", "host")
            return
        dashboard = scope["path"] == DASHBOARD or scope["path"].startswith(DASHBOARD + "/")
        if scope["method"] != "OPTIONS" and scope["path"] not in PUBLIC_PATHS and not dashboard:
            try:
                scope.setdefault("state", {})["caller"] = auth.authenticate(scope["app"].state.registry.store,
                                                                            headers.get("authorization"))
            except GlobeError as err:
                await refuse(err.http_status, str(err), err.field, dict(err.http_headers))
                return
        if dashboard and scope["method"] not in ("GET", "HEAD", "POST"):
            await refuse(405, f"{scope['method'][:16]} is not a method of the dashboard", None)
            return
        creating = scope["method"] == "POST" and scope["path"].rstrip("/") == "/households"
        # The dashboard's forms are read before anyone is known (the login form carries the token):
        # a few KiB at most, so an unauthenticated client cannot make the service buffer more.
        limit = self.household_limit if creating else DASHBOARD_FORM_BYTES if dashboard else self.limit
        if declared is not None:
            if not declared.isdigit():
                await refuse(400, "malformed Content-Length", "body")
                return
            if int(declared) > limit:
                await refuse(413, f"request body of {declared} bytes is over the limit of {limit}", "body")
                return
        if scope["method"] in ("GET", "HEAD", "DELETE", "OPTIONS") and not pending_body:
            await self.app(scope, receive, send)
            return
        if creating:
            async with self.creations:  # waiting here reads nothing of the body
                await self._with_body(scope, receive, send, limit, refuse)
        else:
            await self._with_body(scope, receive, send, limit, refuse)

    async def _with_body(self, scope: Scope, receive: Receive, send: Send, limit: int, refuse: Any) -> None:
        """Read the whole body (within the size and time limits), then pass the request on."""
        chunks, total = [], 0
        loop = asyncio.get_running_loop()
        deadline = loop.time() + self.body_timeout_s
        while True:
            try:
                message = await asyncio.wait_for(receive(), max(0.0, deadline - loop.time()))
            except TimeoutError:
                await refuse(408, f"the request body did not arrive within {self.body_timeout_s:g} s "
                                  "(service.body_timeout_s)", "body")
                return
            if message["type"] != "http.request":
                return  # the client went away
            body = message.get("body", b"")
            total += len(body)
            if total > limit:
                await refuse(413, f"request body is over the limit of {limit} bytes", "body")
                return
            chunks.append(body)
            if not message.get("more_body", False):
                break
        sent = False

        async def replay() -> Message:
            nonlocal sent
            if not sent:
                sent = True
                return {"type": "http.request", "body": b"".join(chunks), "more_body": False}
            return await receive()

        await self.app(scope, replay, send)


__all__ = ["Guard", "PUBLIC_PATHS", "error_response", "printable"]
