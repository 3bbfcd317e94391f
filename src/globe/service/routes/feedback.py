"""``POST /households/{name}/feedback``: the person accepted or refused a fetched object."""

from __future__ import annotations

from fastapi import APIRouter

from globe.service.deps import MemberDep, RegistryDep
from globe.service.fastjson import FastJSONRoute
from globe.service.schemas import ERROR_RESPONSES, FeedbackCounts, FeedbackIn

router = APIRouter(route_class=FastJSONRoute)


@router.post("/households/{name}/feedback", status_code=201, responses=ERROR_RESPONSES)
def feedback(name: str, body: FeedbackIn, registry: RegistryDep, caller: MemberDep) -> FeedbackCounts:
    return registry.feedback(name, body.object, body.accepted)
