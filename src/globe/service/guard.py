"""The outermost ASGI layer of the service: the Host allow-list and the body-size limits, applied
before anything reads or parses a request body."""

from __future__ import annotations

from typing import Any

from fastapi.responses import JSONResponse
from starlette.types import ASGIApp, Receive, Scope, Send

from globe.config import ServiceConfig


def error_response(status: int, detail: str, field: str | None, headers: dict[str, str] | None = None) -> JSONResponse:
    """Every error the service sends: ``{"detail", "field"}``."""
    return JSONResponse({"detail": detail, "field": field}, status_code=status, headers=headers)


class Guard:
    """The Host allow-list and the body-size limits (read before parsing)."""

    def __init__(self, app: ASGIApp, service: ServiceConfig) -> None:
        self.app = app
        self.any_host = "*" in service.allowed_hosts
        self.hosts = {h.lower().strip("[]") for h in service.allowed_hosts}
        self.limit = service.max_body_bytes
        self.household_limit = service.max_household_bytes

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
        host = self._hostname(headers.get("host", ""))
        if not self.any_host and host not in self.hosts:
            await error_response(400, f"host {host[:64]!r} is not allowed (service.allowed_hosts)", "host")(scope, receive, send)
            return
        creating = scope["method"] == "POST" and scope["path"].rstrip("/") == "/households"
        limit = self.household_limit if creating else self.limit
        declared = headers.get("content-length")
        if declared is not None:
            if not declared.isdigit():
                await error_response(400, "malformed Content-Length", "body")(scope, receive, send)
                return
            if int(declared) > limit:
                await error_response(413, f"request body of {declared} bytes is over the limit of {limit}", "body")(
                    scope, receive, send)
                return
        if scope["method"] in ("GET", "HEAD", "DELETE", "OPTIONS") and declared in (None, "0"):
            await self.app(scope, receive, send)
            return
        chunks, total = [], 0
        while True:
            message = await receive()
            if message["type"] != "http.request":
                return  # the client went away
            body = message.get("body", b"")
            total += len(body)
            if total > limit:
                await error_response(413, f"request body is over the limit of {limit} bytes", "body")(scope, receive, send)
                return
            chunks.append(body)
            if not message.get("more_body", False):
                break
        sent = False

        async def replay() -> Any:
            nonlocal sent
            if not sent:
                sent = True
                return {"type": "http.request", "body": b"".join(chunks), "more_body": False}
            return await receive()

        await self.app(scope, replay, send)
