"""``GET /households/{name}/model``: both models as JSON (what ``globe.models.io`` reads)."""

from __future__ import annotations

from fastapi import APIRouter

from globe.service.deps import MemberDep, RegistryDep
from globe.service.fastjson import FastJSONRoute
from globe.service.schemas import ERROR_RESPONSES, ModelOut

router = APIRouter(route_class=FastJSONRoute)


@router.get("/households/{name}/model", responses=ERROR_RESPONSES)
def export_model(name: str, registry: RegistryDep, caller: MemberDep) -> ModelOut:
    return registry.export_model(name)
