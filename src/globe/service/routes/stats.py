"""``GET /households/{name}/stats``: counts, and the effective settings of the built models."""

from __future__ import annotations

from fastapi import APIRouter

from globe.service.deps import MemberDep, RegistryDep
from globe.service.fastjson import FastJSONRoute
from globe.service.schemas import ERROR_RESPONSES, StatsOut

router = APIRouter(route_class=FastJSONRoute)


@router.get("/households/{name}/stats", responses=ERROR_RESPONSES)
def stats(name: str, registry: RegistryDep, caller: MemberDep) -> StatsOut:
    return registry.stats(name)
