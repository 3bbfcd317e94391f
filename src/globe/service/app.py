"""The HTTP service: ``create_app(config)`` builds a FastAPI app; state lives in ``app.state``.

Each household's requests are serialised by its assistant's lock; an observation is validated,
committed to SQLite, then applied, all under that lock, and only then acknowledged.
"""


from contextlib import asynccontextmanager
from typing import Annotated

from fastapi import Depends, FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse

from globe import __version__, assembly
from globe.config import GlobeConfig
from globe.errors import DataError, GlobeError, LLMError, StoreError
from globe.models.io import model_to_dict
from globe.service.assistant import Observation
from globe.service.registry import (
    DuplicateHouseholdError,
    Registry,
    UnknownHouseholdError,
)
from globe.service.schemas import (
    ErrorOut,
    FeedbackIn,
    HouseholdCreate,
    HouseholdInfo,
    ObservationAck,
    ObservationIn,
    PredictionOut,
)
from globe.service.store import Store


def create_app(config: GlobeConfig) -> FastAPI:
    @asynccontextmanager
    async def lifespan(app: FastAPI):
        store = Store(config.service.database)
        registry = Registry(store, config, assembly.llm_backend(config.llm))
        registry.load_all()
        app.state.registry = registry
        yield
        store.close()

    app = FastAPI(title="GLOBE assistance service", version=__version__, lifespan=lifespan,
                  description="Predicts a household's next activity and the object a robot should fetch.")

    def registry(request: Request) -> Registry:
        return request.app.state.registry

    Reg = Annotated[Registry, Depends(registry)]
    errors = {404: {"model": ErrorOut}, 409: {"model": ErrorOut}, 422: {"model": ErrorOut}, 503: {"model": ErrorOut}}

    @app.exception_handler(GlobeError)
    async def globe_error(request: Request, err: GlobeError) -> JSONResponse:
        status = 500
        if isinstance(err, UnknownHouseholdError):
            status = 404
        elif isinstance(err, DuplicateHouseholdError):
            status = 409
        elif isinstance(err, DataError):
            status = 422
        elif isinstance(err, (StoreError, LLMError)):
            status = 503
        field = getattr(err, "field", None)
        message = getattr(err, "message", None) or str(err)
        return JSONResponse({"detail": message, "field": field}, status_code=status)

    @app.exception_handler(RequestValidationError)
    async def invalid_request(request: Request, err: RequestValidationError) -> JSONResponse:
        first = err.errors()[0]
        field = ".".join(str(p) for p in first["loc"] if p != "body")
        return JSONResponse({"detail": f"{field}: {first['msg']}", "field": field}, status_code=422)

    @app.get("/health")
    def health() -> dict:
        return {"status": "ok", "version": __version__}

    @app.get("/households")
    def list_households(reg: Reg) -> list[str]:
        return reg.names()

    @app.post("/households", status_code=201, response_model=HouseholdInfo, responses=errors)
    def create_household(body: HouseholdCreate, reg: Reg) -> HouseholdInfo:
        a = reg.create(body.name, body.source)
        return HouseholdInfo(name=body.name, objects=list(a.household.objects), training_days=len(a.household.train))

    @app.post("/households/{name}/observations", status_code=201, response_model=ObservationAck, responses=errors)
    def observe(name: str, body: ObservationIn, reg: Reg) -> ObservationAck:
        a = reg.get(name)
        obs = Observation(body.time, body.activity.strip(), body.locations)
        with a.lock:
            a.validate(obs)
            row = reg.store.add_observation(name, body.time, obs.activity, dict(body.locations))
            a.observe(obs)
            return ObservationAck(id=row, day=a.day_key(body.time), step=a.stats()["steps_today"] - 1)

    @app.get("/households/{name}/prediction", response_model=PredictionOut, responses=errors)
    def prediction(name: str, reg: Reg) -> PredictionOut:
        a = reg.get(name)
        with a.lock:
            p = a.predict()
        return PredictionOut(day=p.day, step=p.step, activity=p.activity, activity_probability=p.activity_probability,
                             object=p.obj, object_probability=p.object_probability, llm_consulted=p.llm_consulted,
                             llm_fallback=p.llm_fallback, act=p.act, fetch_to=p.fetch_to)

    @app.post("/households/{name}/feedback", status_code=201, responses=errors)
    def feedback(name: str, body: FeedbackIn, reg: Reg) -> dict:
        a = reg.get(name)
        if body.object not in a.household.objects:
            raise DataError(f"unknown object {body.object!r}", field="object")
        with a.lock:
            reg.store.add_feedback(name, body.object, body.accepted)
            a.record_feedback(body.accepted)
            return a.stats()["feedback"]

    @app.get("/households/{name}/stats", responses=errors)
    def stats(name: str, reg: Reg) -> dict:
        a = reg.get(name)
        with a.lock:
            return a.stats()

    @app.get("/households/{name}/model", responses=errors)
    def export_model(name: str, reg: Reg) -> dict:
        a = reg.get(name)
        with a.lock:
            return {"activity": model_to_dict(a.activity_model), "objects": model_to_dict(a.chooser.model)}

    return app
