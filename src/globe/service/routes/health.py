"""``GET /health``: the only endpoint without a token (says nothing about any household's data)."""

from __future__ import annotations

from fastapi import APIRouter, Request

from globe import __version__
from globe.errors import StoreError
from globe.service.deps import RegistryDep
from globe.service.fastjson import FastJSONRoute
from globe.service.schemas import HEALTH_RESPONSES, HealthOut, MqttHealth

router = APIRouter(route_class=FastJSONRoute)


@router.get("/health", responses=HEALTH_RESPONSES)
def health(registry: RegistryDep, request: Request) -> HealthOut:
    problem = registry.store.problem()
    failed = registry.failures()
    bridge = getattr(request.app.state, "mqtt", None)  # the MQTT bridge, when [mqtt] is enabled
    mqtt = bridge.health() if bridge is not None else MqttHealth()
    try:
        households = len(registry.names())
    except StoreError as err:  # a database that cannot be read is what health is asked about
        problem, households = problem or str(err), 0
    degraded = problem is not None or bool(failed) or mqtt.state == "disconnected"
    llm = "none" if registry.backend is None else registry.backend.status
    return HealthOut(status="degraded" if degraded else "ok", version=__version__, database=problem or "ok",
                     households=households, built=registry.built(), failed=failed, llm=llm, mqtt=mqtt)
