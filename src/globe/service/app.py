"""The HTTP service: ``create_app(config)`` assembles the routers (:mod:`globe.service.routes`),
the lifespan that opens the store and the registry (state lives in ``app.state``), the middleware
and the error handlers.

Secure by default: every endpoint but ``/health`` needs ``Authorization: Bearer <token>``
(admin tokens manage households, household tokens reach their own household only); the Host
header must be an allowed name (loopback by default, which stops DNS rebinding); no CORS unless
configured; request bodies are size-limited before they are parsed. Every error is JSON
``{"detail", "field"}`` with a 4xx status for bad input, never a 500: each error class carries its
status (``GlobeError.http_status``).

Each household's requests are serialised by its lock in the registry; an observation is
validated completely, committed to SQLite, then applied, all under that lock, and only then
acknowledged (:meth:`globe.service.registry.Registry.observe`).

With ``[mqtt] enabled = true`` the lifespan also starts the link to Home Assistant
(:mod:`globe.service.mqtt`), which publishes each new prediction and observes through the same
registry.
"""

from __future__ import annotations

import logging
import threading
from contextlib import asynccontextmanager
from typing import Any, AsyncIterator, MutableMapping

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.routing import Match

from globe import __version__, assembly
from globe.config import GlobeConfig
from globe.errors import GlobeError
from globe.service.fastjson import FastJSONRoute
from globe.service.guard import Guard, error_response
from globe.service.registry import Registry
from globe.service.routes import ROUTERS
from globe.service.schemas import document_limits
from globe.service.store import Store

log = logging.getLogger(__name__)


def create_app(config: GlobeConfig) -> FastAPI:
    service = config.service

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        store = Store(service.database)
        registry = Registry(store, config, assembly.service_llm_backend(config))
        registry.load_all()
        app.state.registry = registry
        stop = threading.Event()
        threading.Thread(target=_watch, args=(store, stop), name="globe-watch", daemon=True).start()
        if service.preload:
            threading.Thread(target=registry.warm_up, args=(stop,), name="globe-warm-up", daemon=True).start()
        bridge = None
        if config.mqtt.enabled:
            from globe.service.mqtt.bridge import MqttBridge  # paho-mqtt: only with [mqtt] enabled

            bridge = app.state.mqtt = MqttBridge(registry, config)
            bridge.start()
        yield
        if bridge is not None:
            bridge.stop()
        stop.set()
        registry.close()
        store.close()

    app = FastAPI(title="GLOBE assistance service", version=__version__, lifespan=lifespan,
                  description="Predicts a household's next activity and the object a robot should fetch. "
                              "Every endpoint but /health needs 'Authorization: Bearer <token>' (globe token create).")
    app.router.route_class = FastJSONRoute
    for router in ROUTERS:
        app.include_router(router)
    if service.cors_origins:
        from fastapi.middleware.cors import CORSMiddleware

        app.add_middleware(CORSMiddleware, allow_origins=list(service.cors_origins),
                           allow_methods=["GET", "POST", "DELETE"], allow_headers=["Authorization", "Content-Type"])
    app.add_middleware(Guard, service=service)
    _add_error_handlers(app)
    default_openapi = app.openapi

    def openapi() -> dict:
        if app.openapi_schema is None:
            app.openapi_schema = document_limits(default_openapi(), service)
        return app.openapi_schema

    app.openapi = openapi  # type: ignore[method-assign]
    return app


WATCH_INTERVAL_S = 1.0  # how often the database's files are checked when no request comes


def _watch(store: Store, stop: threading.Event) -> None:
    """Check the database's files every second: a write-ahead log deleted under the service is
    copied into the database file at once, not at the next write (which a crash may never see)."""
    while not stop.wait(WATCH_INTERVAL_S):
        try:
            store.watch()
        except Exception:  # noqa: BLE001 - the watch must outlive anything; each failure is logged
            log.exception("checking the database files failed")


METHODS = ("DELETE", "GET", "HEAD", "PATCH", "POST", "PUT")


def allowed_methods(app: FastAPI, scope: MutableMapping[str, Any]) -> list[str]:
    """The methods some route of ``scope``'s path answers: each asked of the router's routes."""
    return [m for m in METHODS if any(r.matches({**scope, "method": m})[0] == Match.FULL for r in app.router.routes)]


def _add_error_handlers(app: FastAPI) -> None:
    @app.exception_handler(GlobeError)
    async def globe_error(request: Request, err: GlobeError) -> JSONResponse:
        if err.http_status >= 500 and err.http_status != 503:
            log.exception("unexpected error", exc_info=err)
        message = getattr(err, "message", None) or str(err)
        return error_response(err.http_status, message, err.field, dict(err.http_headers) or None)

    @app.exception_handler(RequestValidationError)
    async def invalid_request(request: Request, err: RequestValidationError) -> JSONResponse:
        first = err.errors()[0]
        field = ".".join(str(p) for p in first["loc"] if p != "body") or "body"
        return error_response(422, f"{field}: {first['msg']}", field)

    @app.exception_handler(StarletteHTTPException)
    async def http_error(request: Request, err: StarletteHTTPException) -> JSONResponse:
        headers = dict(getattr(err, "headers", None) or {})
        if err.status_code == 405:  # every method of the path (the router names only its first route's)
            headers["Allow"] = ", ".join(allowed_methods(app, request.scope))
        return error_response(err.status_code, str(err.detail), None, headers or None)

    @app.exception_handler(Exception)
    async def internal_error(request: Request, err: Exception) -> JSONResponse:
        log.exception("unexpected error", exc_info=err)
        return error_response(500, f"internal error ({type(err).__name__}); the request changed nothing it could not "
                                   "finish", None)


__all__ = ["create_app", "Guard"]
