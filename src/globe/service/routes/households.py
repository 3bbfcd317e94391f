"""``/households`` (admin): list, create from a map and day logs, export or delete with all its data, switch
shadow mode."""

from __future__ import annotations

from fastapi import APIRouter, Response

from globe.service.deps import AdminDep, RegistryDep
from globe.service.fastjson import FastJSONRoute
from globe.service.schemas import ERROR_RESPONSES, HouseholdCreate, HouseholdExport, HouseholdInfo, ShadowIn, ShadowOut

router = APIRouter(route_class=FastJSONRoute)


@router.get("/households", responses=ERROR_RESPONSES)
def list_households(registry: RegistryDep, caller: AdminDep) -> list[str]:
    return registry.names()


@router.post("/households", status_code=201, response_model=HouseholdInfo, responses=ERROR_RESPONSES)
def create_household(body: HouseholdCreate, registry: RegistryDep, caller: AdminDep) -> HouseholdInfo:
    nodes = [n.model_dump(by_alias=True) for n in body.nodes]
    sensors = None if body.sensors is None else [s.model_dump() for s in body.sensors]
    return registry.create_uploaded(body.name, body.timezone, nodes, body.days, body.dates, method=body.method,
                                    new_activities=body.new_activities, sensors=sensors, events=body.events)


@router.delete("/households/{name}", status_code=204, responses=ERROR_RESPONSES)
def delete_household(name: str, registry: RegistryDep, caller: AdminDep) -> Response:
    registry.delete(name)
    return Response(status_code=204)


@router.get("/households/{name}/export", responses=ERROR_RESPONSES)
def export_household(name: str, registry: RegistryDep, caller: AdminDep) -> HouseholdExport:
    """Everything stored about the household, as stored (also when it cannot be built)."""
    return HouseholdExport.model_validate(registry.export(name))


@router.put("/households/{name}/shadow", responses=ERROR_RESPONSES)
def set_shadow(name: str, body: ShadowIn, registry: RegistryDep, caller: AdminDep) -> ShadowOut:
    """Shadow mode on (GLOBE predicts and scores itself, ``act`` stays false) or off (the robot acts).
    New households start in shadow mode."""
    return registry.set_shadow(name, body.shadow)
