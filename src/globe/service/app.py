"""The HTTP service: ``create_app(config)`` builds a FastAPI app; state lives in ``app.state``.

Secure by default: every endpoint but ``/health`` needs ``Authorization: Bearer <token>``
(admin tokens manage households, household tokens reach their own household only); the Host
header must be an allowed name (loopback by default, which stops DNS rebinding); no CORS unless
configured; request bodies are size-limited before they are parsed. Every error is JSON
``{"detail", "field"}`` with a 4xx status for bad input, never a 500.

Each household's requests are serialised by its assistant's lock; an observation is validated
completely, committed to SQLite, then applied, all under that lock, and only then acknowledged.
"""

import json
import logging
import threading
from contextlib import aclosing, asynccontextmanager
from typing import Annotated, Any, Callable, Coroutine

import pydantic_core
from fastapi import Depends, FastAPI, Request, Response
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from fastapi.routing import APIRoute
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.types import ASGIApp, Receive, Scope, Send

from globe import __version__, assembly
from globe.config import GlobeConfig, ServiceConfig
from globe.errors import (
    AuthenticationError,
    ConfigError,
    DataError,
    GlobeError,
    LimitError,
    LLMError,
    PermissionDeniedError,
    StoreError,
)
from globe.models.io import model_to_dict
from globe.service import auth, timepolicy
from globe.service.assistant import Observation
from globe.service.registry import DuplicateHouseholdError, Registry, UnknownHouseholdError, check_timezone, no_gc
from globe.service.schemas import (
    ErrorOut,
    FeedbackIn,
    HouseholdCreate,
    HouseholdInfo,
    ObservationAck,
    ObservationIn,
    Prediction,
)
from globe.service.store import Store
from globe.service.upload import household_from, parse_nodes

log = logging.getLogger(__name__)

def _error(status: int, detail: str, field: str | None, headers: dict[str, str] | None = None) -> JSONResponse:
    return JSONResponse({"detail": detail, "field": field}, status_code=status, headers=headers)


class Guard:
    """Outermost ASGI layer: the Host allow-list and the body-size limits (read before parsing)."""

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
            await _error(400, f"host {host[:64]!r} is not allowed (service.allowed_hosts)", "host")(scope, receive, send)
            return
        limit = self.household_limit if scope["method"] == "POST" and scope["path"].rstrip("/") == "/households" else self.limit
        declared = headers.get("content-length")
        if declared is not None:
            if not declared.isdigit():
                await _error(400, "malformed Content-Length", "body")(scope, receive, send)
                return
            if int(declared) > limit:
                await _error(413, f"request body of {declared} bytes is over the limit of {limit}", "body")(scope, receive, send)
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
                await _error(413, f"request body is over the limit of {limit} bytes", "body")(scope, receive, send)
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


class _FastJSONRequest(Request):
    """A request whose JSON body is parsed by pydantic-core (a 6 MB household upload in a third
    of the time of :func:`json.loads`). Whatever it refuses goes to :func:`json.loads`, so every
    body is accepted or refused, and parsed, exactly as the standard library does. A body that
    arrives in one piece (the :class:`Guard` joins it) is not copied again."""

    async def body(self) -> bytes:
        if not hasattr(self, "_body"):
            async with aclosing(self.stream()) as stream:
                chunks = [chunk async for chunk in stream if chunk]
            self._body = chunks[0] if len(chunks) == 1 else b"".join(chunks)
        return self._body

    async def json(self) -> Any:
        if not hasattr(self, "_json"):
            body = await self.body()
            try:
                self._json = pydantic_core.from_json(body)
            except ValueError:
                self._json = json.loads(body)  # the error (and its position), or what only it accepts
        return self._json


class _FastJSONRoute(APIRoute):
    def get_route_handler(self) -> Callable[[Request], Coroutine[Any, Any, Response]]:
        handler = super().get_route_handler()

        async def route(request: Request) -> Response:
            return await handler(_FastJSONRequest(request.scope, request.receive))

        return route


def create_app(config: GlobeConfig) -> FastAPI:
    service = config.service

    @asynccontextmanager
    async def lifespan(app: FastAPI):
        store = Store(service.database)
        registry = Registry(store, config, assembly.llm_backend(config.llm))
        registry.load_all()
        app.state.registry = registry
        stop = threading.Event()
        if service.preload:
            threading.Thread(target=registry.warm_up, args=(stop,), name="globe-warm-up", daemon=True).start()
        yield
        stop.set()
        registry.close()
        store.close()

    app = FastAPI(title="GLOBE assistance service", version=__version__, lifespan=lifespan,
                  description="Predicts a household's next activity and the object a robot should fetch. "
                              "Every endpoint but /health needs 'Authorization: Bearer <token>' (globe token create).")
    app.router.route_class = _FastJSONRoute
    if service.cors_origins:
        from fastapi.middleware.cors import CORSMiddleware

        app.add_middleware(CORSMiddleware, allow_origins=list(service.cors_origins), allow_methods=["GET", "POST", "DELETE"],
                           allow_headers=["Authorization", "Content-Type"])
    app.add_middleware(Guard, service=service)

    def registry(request: Request) -> Registry:
        return request.app.state.registry

    def caller(request: Request) -> auth.Caller:
        return auth.authenticate(request.app.state.registry.store, request.headers.get("authorization"))

    def admin(request: Request) -> auth.Caller:
        who = caller(request)
        who.require_admin()
        return who

    def member(name: str, request: Request) -> auth.Caller:
        who = caller(request)
        who.require_household(name)
        return who

    # authorisation runs as a dependency: before the body is read or validated
    Reg = Annotated[Registry, Depends(registry)]
    Admin = Annotated[auth.Caller, Depends(admin)]
    Member = Annotated[auth.Caller, Depends(member)]
    errors: dict[int | str, dict[str, Any]] = {code: {"model": ErrorOut} for code in (401, 403, 404, 409, 413, 422, 503)}

    @app.exception_handler(GlobeError)
    async def globe_error(request: Request, err: GlobeError) -> JSONResponse:
        status, headers = 500, None
        if isinstance(err, AuthenticationError):
            status, headers = 401, {"WWW-Authenticate": "Bearer"}
        elif isinstance(err, PermissionDeniedError):
            status = 403
        elif isinstance(err, UnknownHouseholdError):
            status = 404
        elif isinstance(err, DuplicateHouseholdError):
            status = 409
        elif isinstance(err, (DataError, ConfigError)):
            status = 422
        elif isinstance(err, (StoreError, LLMError)):
            status = 503
        if status == 500:
            log.exception("unexpected error", exc_info=err)
        message = getattr(err, "message", None) or str(err)
        return _error(status, message, getattr(err, "field", None), headers)

    @app.exception_handler(RequestValidationError)
    async def invalid_request(request: Request, err: RequestValidationError) -> JSONResponse:
        first = err.errors()[0]
        field = ".".join(str(p) for p in first["loc"] if p != "body") or "body"
        return _error(422, f"{field}: {first['msg']}", field)

    @app.exception_handler(StarletteHTTPException)
    async def http_error(request: Request, err: StarletteHTTPException) -> JSONResponse:
        return _error(err.status_code, str(err.detail), None, getattr(err, "headers", None))

    @app.exception_handler(Exception)
    async def internal_error(request: Request, err: Exception) -> JSONResponse:
        log.exception("unexpected error", exc_info=err)
        return _error(500, f"internal error ({type(err).__name__}); the request changed nothing it could not finish", None)

    @app.get("/health")
    def health(request: Request) -> dict:
        reg: Registry = request.app.state.registry
        problem = reg.store.problem()
        degraded = problem is not None or bool(reg.failed)
        return {"status": "degraded" if degraded else "ok", "version": __version__, "database": problem or "ok",
                "households": len(reg.names()), "built": reg.built(), "failed": sorted(reg.failed)}

    @app.get("/households", responses=errors)
    def list_households(reg: Reg, who: Admin) -> list[str]:
        return reg.names()

    @app.post("/households", status_code=201, response_model=HouseholdInfo, responses=errors)
    def create_household(body: HouseholdCreate, reg: Reg, who: Admin) -> HouseholdInfo:
        s = reg.config.service
        if len(body.nodes) > s.max_nodes:
            raise LimitError(f"{len(body.nodes)} nodes (at most {s.max_nodes})", field="nodes")
        if len(body.days) > s.max_days:
            raise LimitError(f"{len(body.days)} days (at most {s.max_days})", field="days")
        timezone = check_timezone(body.timezone or s.timezone)
        nodes = parse_nodes([n.model_dump(by_alias=True) for n in body.nodes], max_label=s.max_label_length)
        try:
            with no_gc():
                household = household_from(body.name, nodes, body.days, max_label=s.max_label_length)
        except DataError as err:
            where = err.source or "days"
            detail = f"{where}:{err.line}: {err.message}" if err.line else f"{where}: {err.message}"
            raise type(err)(detail, field=f"{where}.{err.field}" if err.field else where) from None
        a = reg.create(household, timezone, body.days)
        return HouseholdInfo(name=body.name, timezone=timezone, objects=list(household.objects), days_learned=a.days_learned)

    @app.delete("/households/{name}", status_code=204, responses=errors)
    def delete_household(name: str, reg: Reg, who: Admin) -> Response:
        reg.delete(name)
        return Response(status_code=204)

    @app.post("/households/{name}/observations", status_code=201, response_model=ObservationAck, responses=errors)
    def observe(name: str, body: ObservationIn, reg: Reg, who: Member) -> ObservationAck:
        s = reg.config.service
        if body.id is not None and len(body.id) > s.max_label_length:
            raise LimitError(f"id longer than {s.max_label_length} characters", field="id")
        row = reg.row(name)
        time = timepolicy.to_zone(body.time, timepolicy.zone(row.timezone))
        activity = body.activity.strip() if body.activity is not None else None
        obs = Observation(time, activity, body.locations)
        reg.check_labels(obs)
        with reg.locked(name) as a:
            if body.id is not None:
                found = reg.store.find_observation(name, body.id)
                if found is not None:
                    return ObservationAck(id=body.id, day=found[1].get("day", ""), step=found[1].get("step", 0), duplicate=True)
            timepolicy.check_bounds(time, created=row.created_at, now=timepolicy.utcnow(), skew=s.max_clock_skew)
            a.validate(obs)
            place = a.placement(time)
            ack = {"day": place.day, "step": place.step}
            stored = reg.store.add_observation(name, time, activity, dict(body.locations), body.id, ack)
            a.observe(obs)
            return ObservationAck(id=body.id if body.id is not None else str(stored), duplicate=False, **ack)

    @app.get("/households/{name}/prediction", response_model=Prediction, responses=errors)
    def prediction(name: str, reg: Reg, who: Member) -> Prediction:
        with reg.locked(name) as a:
            return a.predict()

    @app.post("/households/{name}/feedback", status_code=201, responses=errors)
    def feedback(name: str, body: FeedbackIn, reg: Reg, who: Member) -> dict:
        with reg.locked(name) as a:
            if body.object not in a.household.objects:
                raise DataError(f"unknown object {body.object[:64]!r}", field="object")
            reg.store.add_feedback(name, body.object, body.accepted)
            a.record_feedback(body.accepted)
            return a.stats()["feedback"]

    @app.get("/households/{name}/stats", responses=errors)
    def stats(name: str, reg: Reg, who: Member) -> dict:
        row = reg.row(name)
        with reg.locked(name) as a:
            built = assembly.describe(a.activity_model, a.chooser)
            return {**a.stats(), "timezone": row.timezone, "created_at": row.created_at.isoformat(),
                    "chooser": built["chooser"], "models": {"activity": built["activity"], "objects": built["objects"]}}

    @app.get("/households/{name}/model", responses=errors)
    def export_model(name: str, reg: Reg, who: Member) -> dict:
        with reg.locked(name) as a:
            return {"activity": model_to_dict(a.activity_model), "objects": model_to_dict(a.chooser.model)}

    return app


__all__ = ["create_app", "Guard"]
