"""Typed request and response bodies of the HTTP service (pydantic; shown in the OpenAPI).

Label lengths, list sizes and the time are checked again against the configured limits by the
app (the limits are configurable, these bounds are the hard ceilings)."""

from __future__ import annotations

import datetime as dt
import re
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, StrictBool

from globe.config import DeployMethod, ServiceConfig
from globe.errors import DataError

HOUSEHOLD_NAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$"
"""The one rule for household names (HTTP and the CLI): 1 to 64 ASCII letters, digits, '_', '.'
and '-', starting with a letter or digit (so never '.', '..', or a name read as an option)."""


def check_household_name(name: str, field: str = "name") -> str:
    """``name`` if it follows :data:`HOUSEHOLD_NAME_PATTERN`, else a :class:`DataError`."""
    if not re.fullmatch(HOUSEHOLD_NAME_PATTERN, name):
        raise DataError(f"household name {name[:80]!r} is not 1-64 letters, digits, '_', '.' or '-' starting with a "
                        "letter or digit", field=field)
    return name


_CONTROL = r"\x00-\x1f\x7f-\x9f"
_REFUSED = _CONTROL + r"\u061c\u200e\u200f\u202a-\u202e\u2066-\u2069\u200b\u2060\ufeff"  # control, bidi, invisible
LABEL_PATTERN = rf"^[ \t]*[^{_REFUSED}]*[^ \t{_REFUSED}][^{_REFUSED}]*[ \t]*$"
"""What the label rule (:func:`globe.data.csv_logs.activity_label`) accepts, as the OpenAPI
schema says it: spaces and tabs around it, something else inside, no control or
bidirectional-formatting character (lone surrogates are refused by JSON decoding already)."""
NODE_PATTERN = (rf"^[ \t]*[^{_REFUSED}]*[^ \t{_REFUSED}][^{_REFUSED}]*#[^#{_REFUSED}]*[^# \t{_REFUSED}][^#{_REFUSED}]*"
                r"[ \t]*$")
"""A node label: a label of the form ``class#id`` (the class before the last '#', the id after it)."""


def _documented(pattern: str) -> dict[str, Any]:
    """A pattern for the OpenAPI schema only: the server applies the rule itself, with messages
    that name what is wrong."""
    return {"pattern": pattern}


class _Body(BaseModel):
    model_config = ConfigDict(extra="forbid")


class NodeIn(_Body):
    model_config = ConfigDict(extra="forbid", populate_by_name=True)

    node: str = Field(..., min_length=1, max_length=4096, description="class#id, the node's unique label",
                      json_schema_extra=_documented(NODE_PATTERN))
    cls: str = Field(..., alias="class", min_length=1, max_length=4096, description="the node's class",
                     json_schema_extra=_documented(LABEL_PATTERN))
    category: str = Field(..., min_length=1, max_length=4096, description="Rooms, Furniture, ...",
                          json_schema_extra=_documented(rf"^[ \t]*[^{_CONTROL}]*[ \t]*$"))
    movable: StrictBool | int = Field(..., description="true for objects the person moves")
    start_location: str = Field(..., min_length=1, max_length=4096, json_schema_extra=_documented(LABEL_PATTERN),
                                description="node it is on or in at the start of a day")


class SensorIn(_Body):
    """One sensor of the home: a row of ``sensors.csv``."""

    sensor: str = Field(..., min_length=1, max_length=4096, description="the sensor's name in the log",
                        json_schema_extra=_documented(LABEL_PATTERN))
    type: str = Field("other", max_length=64, description="its kind in one lowercase word: motion, door, contact, "
                                                          "pressure, flush, appliance, ...")
    room: str = Field("", max_length=4096, description="the room it is in (empty: unknown)")
    object: str = Field("", max_length=4096, description="the object column it feeds (empty: none)")


class HouseholdCreate(_Body):
    name: str = Field(..., min_length=1, max_length=64, pattern=HOUSEHOLD_NAME_PATTERN, description="household id")
    timezone: str | None = Field(None, max_length=64,
                                 description="IANA time zone, e.g. Europe/Paris (default: the server's)")
    nodes: list[NodeIn] = Field(..., min_length=1, description="the household's map: the rows of nodes.csv")
    days: list[str] = Field(default_factory=list,
                            description="optional training logs: the text of day files (minute,activity,...)")
    dates: list[dt.date] | None = Field(None, description="optional: the date of each training day, in the order "
                                                          "of days (models that know the day of the week use them)")
    method: DeployMethod | None = Field(
        None, description="how its models are chosen (default: the service's selection.deploy): 'routine' or "
        "'ngram_smoothed' by cross-validation on its training days (in the background: the configured models run "
        "until it ends), 'ngram' (the paper's) or 'persistence'")
    new_activities: Literal["refuse", "learn"] | None = Field(
        None, description="an activity it has never seen: refused (the known ones listed) or learned; default: "
        "refused where it has training days, learned where it starts from none")
    sensors: list[SensorIn] | None = Field(
        None, max_length=10_000, description="optional: the home's ambient sensors (the rows of sensors.csv); "
        "its activities are then recognised from them where no label is given")
    events: list[str | None] | None = Field(
        None, description="optional, with sensors: each training day's activations, in the order of days (the text "
        "of events/<day>.csv: sensor,start,end in seconds after the day's midnight; null: not recorded)")


class HouseholdInfo(_Body):
    name: str
    timezone: str
    objects: list[str]
    days_learned: int
    grid: str = Field("", description="its clock: step, day start and steps a day (from its training days)")
    deployment: str = Field("", description="what it runs, in words")
    selecting: bool = Field(False, description="its models are being chosen by cross-validation in the background")
    sensors: int = Field(0, description="its ambient sensors (0: none; then activities come from labels only)")


class SensorEventIn(_Body):
    """One sensor activation: when it began and ended (ISO 8601 as the observation's time: naive =
    wall time in the household's zone, aware = converted; a number is seconds since 1970 UTC)."""

    sensor: str = Field(..., min_length=1, max_length=4096, description="the sensor's name (one of the household's)")
    start: dt.datetime
    end: dt.datetime | None = Field(None, description="when it ended (null: a firing, end = start)")


class ObservationIn(_Body):
    time: dt.datetime = Field(..., description="ISO 8601; naive = wall time in the household's zone, aware = converted")
    activity: str | None = Field(None, min_length=1, max_length=4096, json_schema_extra=_documented(LABEL_PATTERN),
                                 description="what the person is doing (null: unknown); NFC-normalised")
    locations: dict[str, str] = Field(default_factory=dict,
                                      description="object class -> node label where it is (partial allowed)")
    id: str | None = Field(None, min_length=1, max_length=4096,
                           description="client-chosen id: a retry with it returns the first answer")
    sensors: list[SensorEventIn] = Field(
        default_factory=list, max_length=100_000,
        description="sensor activations since the last observation (a household with sensors): the evidence its "
                    "activity is recognised from at this step")


class ObservationAck(_Body):
    id: str
    day: str
    step: int
    duplicate: bool = False
    pending: bool = Field(False, description="stored, but held until the server clock is within service.max_ahead "
                                             "of it")


class FetchOut(BaseModel):
    model_config = ConfigDict(extra="ignore", frozen=True)

    object: str
    to: str | None = Field(..., description="where to bring it: where it is most likely used")
    probability: float = Field(..., description="P(it is used within the policy's lead window)")


class RecognisedOut(BaseModel):
    model_config = ConfigDict(extra="ignore", frozen=True)

    activity: str
    probability: float


class QuestionOut(BaseModel):
    """"What are you doing?": answered by an observation with the activity (within the step)."""

    model_config = ConfigDict(extra="ignore", frozen=True)

    day: str
    step: int = Field(..., description="the step asked about (the last observed one)")
    time: str = Field(..., description="the step's start, HH:MM on the household's clock")
    activities: list[RecognisedOut] = Field(..., description="the likely activities, most probable first")


class Prediction(BaseModel):
    """What the service predicts after a step: decided by the household's session, returned by the
    app, parsed by the client (one definition for all three; unknown fields are ignored so an
    older client reads a newer service)."""

    model_config = ConfigDict(extra="ignore", frozen=True)

    status: str = Field(..., description="'learning' until a first day is learned, then 'ready'")
    days_learned: int
    day: str
    step: int
    activity: str | None = Field(..., description="the most likely next activity")
    activity_probability: float
    object: str | None = Field(..., description="the object most likely needed next (for that activity)")
    object_probability: float
    llm_consulted: bool
    llm_fallback: str | None
    act: bool = Field(..., description="fetch now (never while learning, never in shadow mode): see fetch_object")
    fetch_object: str | None = Field(None, description="what to fetch now, when act is true")
    fetch_to: str | None = Field(None, description="where to bring it: where it is most likely used")
    fetch_probability: float | None = Field(
        None, description="the fetch policy's probability that the object is used within the lead window")
    fetches: list[FetchOut] = Field(
        default_factory=list, description="every fetch to start now, most likely useful first (at most "
        "policy.max_fetches_per_step; fetch_object is the first), also in shadow mode, where act stays false")
    shadow: bool = Field(False, description="the household is in shadow mode: GLOBE decided fetch_object (and scores "
                                            "that decision) but act stays false until an admin switches shadow off")
    recognised: RecognisedOut | None = Field(
        None, description="a household with sensors, the last observed step unlabelled: the activity under way as "
                          "recognised from the sensors, and its probability")
    labelled_steps: int = Field(0, description="today's steps with an activity label (answers included)")
    recognised_steps: int = Field(0, description="today's steps without a label, their activity recognised")
    question: QuestionOut | None = Field(
        None, description="ask the person what they are doing now (a budget of service.questions_per_day a day, "
                          "spent where the recognised activity is least sure); the answer is an observation's activity")


class FeedbackIn(_Body):
    object: str = Field(..., min_length=1, max_length=4096)
    accepted: StrictBool


class FeedbackCounts(_Body):
    accepted: int = Field(..., description="fetches the person accepted")
    refused: int = Field(..., description="fetches the person refused")


class ModelSettings(_Body):
    activity: dict[str, Any] = Field(..., description="the activity model's kind and parameters, as built")
    objects: dict[str, Any] = Field(..., description="the object model's kind and parameters, as built")


class ShadowIn(_Body):
    shadow: StrictBool = Field(..., description="true: predict and score, never act; false: act")


class ShadowOut(_Body):
    household: str
    shadow: bool


class DayScoreOut(_Body):
    """One day's online scores (counts, and the rates they give; a rate is null without its counts)."""

    day: str
    predictions: int = Field(..., description="steps whose one-step-ahead activity prediction was scored")
    correct: int = Field(..., description="of those, steps whose predicted top activity was the observed one")
    accuracy: float | None
    fetches: int = Field(..., description="fetches GLOBE decided (in shadow mode too)")
    useful_fetches: int = Field(..., description="fetches whose object was then used within the lead window")
    precision: float | None
    uses: int = Field(..., description="times an object was used (moved)")
    uses_fetched: int = Field(..., description="uses that a fetch within the lead window before had anticipated")
    recall: float | None
    baseline_predictions: int = Field(0, description="of the steps scored, those the baselines were scored at too "
                                                     "(all of them, but on days scored before version 9 kept them)")
    persistence_correct: int = Field(0, description="of those steps, those where persistence (the activity stays) "
                                                    "was right")
    persistence_accuracy: float | None = Field(None, description="persistence's one-step accuracy on those steps")
    hour_activity_correct: int = Field(0, description="of the steps scored, those where hour + activity (the most "
                                                      "frequent next activity given the current one and the hour, "
                                                      "counted on the days learnt) was right")
    hour_activity_accuracy: float | None = Field(None, description="hour + activity's one-step accuracy on those "
                                                                   "steps")


def _rate(hits: int, total: int) -> float | None:
    return round(hits / total, 4) if total else None


class OnlineScores(_Body):
    """How well GLOBE does in this home, scored online against what then happened, per day (the
    current day so far last) and in total."""

    days: list[DayScoreOut]
    accuracy: float | None = Field(..., description="activity accuracy one step ahead over these days")
    precision: float | None = Field(..., description="fetch precision over these days")
    recall: float | None = Field(..., description="fetch recall over these days")
    persistence_accuracy: float | None = Field(
        None, description="persistence's one-step accuracy (the activity stays) over the same scored steps: the rule "
                          "the model must beat (days scored before the baselines were kept are left out)")
    hour_activity_accuracy: float | None = Field(
        None, description="hour + current activity's one-step accuracy over the same scored steps (the most frequent "
                          "next activity given the current one and the hour, counted on the days learnt)")

    @classmethod
    def from_days(cls, rows: list[Any]) -> "OnlineScores":
        """From :class:`globe.service.store.DayScore` rows."""
        days = [DayScoreOut(day=r.day, predictions=r.predictions, correct=r.correct,
                            accuracy=_rate(r.correct, r.predictions), fetches=r.fetches,
                            useful_fetches=r.useful_fetches, precision=_rate(r.useful_fetches, r.fetches),
                            uses=r.uses, uses_fetched=r.uses_fetched, recall=_rate(r.uses_fetched, r.uses),
                            baseline_predictions=r.baseline_predictions, persistence_correct=r.persistence_correct,
                            persistence_accuracy=_rate(r.persistence_correct, r.baseline_predictions),
                            hour_activity_correct=r.hour_activity_correct,
                            hour_activity_accuracy=_rate(r.hour_activity_correct, r.baseline_predictions))
                for r in rows]
        total = {k: sum(getattr(d, k) for d in days) for k in ("predictions", "correct", "fetches", "useful_fetches",
                                                               "uses", "uses_fetched", "baseline_predictions",
                                                               "persistence_correct", "hour_activity_correct")}
        return cls(days=days, accuracy=_rate(total["correct"], total["predictions"]),
                   precision=_rate(total["useful_fetches"], total["fetches"]),
                   recall=_rate(total["uses_fetched"], total["uses"]),
                   persistence_accuracy=_rate(total["persistence_correct"], total["baseline_predictions"]),
                   hour_activity_accuracy=_rate(total["hour_activity_correct"], total["baseline_predictions"]))


class StatsOut(_Body):
    household: str
    status: str = Field(..., description="'learning' until a first day is learned, then 'ready'")
    days_learned: int
    observations: int = Field(..., description="observations applied since the household was created")
    current_day: str | None = Field(..., description="the day the last observation belongs to (null before any)")
    steps_today: int
    feedback: FeedbackCounts
    activities_known: int
    training_days: int
    quarantined: int = Field(..., description="stored observations set aside because they could not be replayed")
    training_days_set_aside: int = Field(..., description="stored training days set aside: they could not be read")
    pending: int = Field(..., description="observations stored but held until the server clock reaches them")
    llm_fallbacks: dict[str, int] = Field(..., description="predictions that fell back to the n-gram choice, by reason")
    timezone: str
    created_at: str
    chooser: dict[str, Any] = Field(..., description="the object chooser's kind and settings, as built")
    models: ModelSettings
    grid: str = Field(..., description="its clock: step, day start and steps a day")
    deployment: dict[str, Any] = Field(..., description="what it runs: the models its cross-validation chose (or the "
                                                        "configured ones, with a note saying why), and their scores")
    selecting: bool = Field(..., description="its models are being chosen in the background")
    shadow: bool = Field(..., description="shadow mode: predictions never ask the robot to act")
    scores: OnlineScores = Field(..., description="online scores of the last 28 days")


class ModelFile(_Body):
    """One model as :func:`globe.models.io.model_to_dict` writes it."""

    format: str
    version: int
    kind: str
    params: dict[str, Any]
    data: list[Any] = Field(..., description="the observed sequences the model counted")
    weekdays: list[int | None] | None = Field(None, description="each day's day of the week (Monday 0), for a "
                                                                "model that knows it")


class ModelOut(_Body):
    activity: ModelFile
    objects: ModelFile
    deployment: dict[str, Any] = Field(default_factory=dict, description="what the household runs (its deployment)")


class StoredObservation(_Body):
    id: int
    time: str
    activity: str | None
    locations: str = Field(..., description="JSON object: object class -> node label")
    received_at: str
    client_id: str | None
    quarantined: bool
    sensors: str | None = Field(None, description="JSON list of [sensor, start, end] it carried (null: none)")


class StoredFeedback(_Body):
    object: str
    accepted: bool
    received_at: str


class HouseholdExport(_Body):
    """Everything stored about a household, as stored: also a household that cannot be built."""

    name: str
    timezone: str
    created_at: str
    nodes: str = Field(..., description="the map as stored (JSON text: a list of nodes)")
    objects: str = Field(..., description="the object columns as stored (JSON text)")
    settings: str | None = Field(None, description="what it runs, as stored (JSON text: its grid, deployment and "
                                                   "label rule; null: not stored yet)")
    days: list[str] = Field(..., description="the training days' texts (day-file CSV)")
    dates: list[str | None] = Field(default_factory=list, description="each training day's date, as stored (null: "
                                                                      "not given)")
    sensors: str | None = Field(None, description="its sensors as stored (JSON text: rows of sensors.csv; null: "
                                                  "none)")
    events: list[str | None] = Field(default_factory=list, description="each training day's sensor events CSV, as "
                                                                       "stored (null: not recorded)")
    observations: list[StoredObservation]
    feedback: list[StoredFeedback]


class MqttHealth(_Body):
    """The link to Home Assistant over MQTT (``[mqtt]``)."""

    state: Literal["disabled", "connected", "disconnected"] = Field(
        "disabled", description="'disabled' without [mqtt] enabled; else whether the broker is connected now "
                                "(while it is not, GLOBE retries with backoff)")
    broker: str | None = Field(None, description="the broker's URL")
    last_error: str | None = Field(None, description="the last connection problem (null: none since start-up)")
    malformed: int = Field(0, description="messages from Home Assistant logged and dropped as malformed")
    observations: int = Field(0, description="observations made from Home Assistant's states and stored")
    rejected: int = Field(0, description="observations made from Home Assistant's states that GLOBE refused (logged)")
    published: int = Field(0, description="state messages published (one per household after each new prediction)")
    problems: list[str] = Field(default_factory=list, description="what an [mqtt.households] entry names that its "
                                                                  "household does not have (those states are left out)")


class HealthOut(_Body):
    status: str = Field(..., description="'ok', or 'degraded' when writes are refused, a household cannot be built "
                                         "or the MQTT broker (when enabled) is not connected")
    version: str
    database: str = Field(..., description="'ok', or why writes are refused")
    households: int
    built: int = Field(..., description="households whose models are in memory")
    failed: list[str] = Field(..., description="households that could not be built")
    llm: str = Field(..., description="'none', 'ready', 'loading' (predictions use the n-gram choice meanwhile) or "
                                      "'failed: <why>'")
    mqtt: MqttHealth = Field(default_factory=MqttHealth, description="Home Assistant over MQTT")


class ErrorOut(_Body):
    detail: str
    field: str | None = None


ERROR_RESPONSES: dict[int | str, dict[str, Any]] = {
    code: {"model": ErrorOut} for code in (400, 401, 403, 404, 408, 409, 413, 422, 431, 503)
}
"""The error answers every endpoint but ``/health`` documents (400: a Host not allowed or a
malformed Content-Length; 408 and 431: a request too slow or its headers too large)."""

HEALTH_RESPONSES: dict[int | str, dict[str, Any]] = {code: {"model": ErrorOut} for code in (400, 408, 431)}


def document_limits(openapi: dict[str, Any], service: ServiceConfig) -> dict[str, Any]:
    """The OpenAPI schema with this service's configured limits where the models carry only hard
    ceilings (the server checks the configured ones), so that it says what the server enforces."""
    schemas = openapi.get("components", {}).get("schemas", {})
    label = service.max_label_length

    def limit(model: str, field: str, key: str, value: int) -> None:
        prop = schemas.get(model, {}).get("properties", {}).get(field)
        if prop is None:
            return
        for target in prop.get("anyOf", [prop]):  # an optional field: the non-null branch
            if target.get("type") in ("string", "array", "object"):
                target[key] = value

    for field in ("activity", "id"):
        limit("ObservationIn", field, "maxLength", label)
    limit("ObservationIn", "locations", "maxProperties", service.max_locations)
    for field in ("node", "class", "category", "start_location"):
        limit("NodeIn", field, "maxLength", label)
    limit("HouseholdCreate", "nodes", "maxItems", service.max_nodes)
    limit("HouseholdCreate", "days", "maxItems", service.max_days)
    return openapi
