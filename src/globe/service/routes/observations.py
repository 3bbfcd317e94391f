"""``POST /households/{name}/observations``: what the robot saw at one moment."""

from __future__ import annotations

from fastapi import APIRouter

from globe.service.deps import MemberDep, RegistryDep
from globe.service.fastjson import FastJSONRoute
from globe.service.schemas import ERROR_RESPONSES, ObservationAck, ObservationIn

router = APIRouter(route_class=FastJSONRoute)


@router.post("/households/{name}/observations", status_code=201, response_model=ObservationAck,
             responses=ERROR_RESPONSES)
def observe(name: str, body: ObservationIn, registry: RegistryDep, caller: MemberDep) -> ObservationAck:
    return registry.observe(name, time=body.time, activity=body.activity, locations=body.locations, client_id=body.id,
                            sensors=[(e.sensor, e.start, e.end) for e in body.sensors])
