"""``GET /households/{name}/prediction``: the next activity, the object, and whether to fetch."""

from __future__ import annotations

from fastapi import APIRouter

from globe.service.deps import MemberDep, RegistryDep
from globe.service.fastjson import FastJSONRoute
from globe.service.schemas import ERROR_RESPONSES, Prediction

router = APIRouter(route_class=FastJSONRoute)


@router.get("/households/{name}/prediction", response_model=Prediction, responses=ERROR_RESPONSES)
def prediction(name: str, registry: RegistryDep, caller: MemberDep) -> Prediction:
    return registry.predict(name)
