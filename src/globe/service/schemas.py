"""Typed request and response bodies of the HTTP service (pydantic; shown in the OpenAPI)."""

from __future__ import annotations

import datetime as dt

from pydantic import BaseModel, ConfigDict, Field


class _Body(BaseModel):
    model_config = ConfigDict(extra="forbid")


class HouseholdCreate(_Body):
    name: str = Field(..., min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_.-]+$", description="household id")
    source: str = Field(..., description="server-side folder in GLOBE's CSV format (nodes.csv, train/*.csv)")


class HouseholdInfo(_Body):
    name: str
    objects: list[str]
    training_days: int


class ObservationIn(_Body):
    time: dt.datetime = Field(..., description="when it was observed (ISO 8601)")
    activity: str = Field(..., min_length=1, description="what the person is doing")
    locations: dict[str, str] = Field(default_factory=dict, description="object -> class#id of where it is (partial allowed)")


class ObservationAck(_Body):
    id: int
    day: str
    step: int


class PredictionOut(_Body):
    day: str
    step: int
    activity: str | None
    activity_probability: float
    object: str | None
    object_probability: float
    llm_consulted: bool
    llm_fallback: str | None
    act: bool = Field(..., description="fetch now: object probability >= the action threshold")
    fetch_to: str | None = Field(None, description="where the object is usually taken during that activity")


class FeedbackIn(_Body):
    object: str
    accepted: bool


class ErrorOut(_Body):
    detail: str
    field: str | None = None
