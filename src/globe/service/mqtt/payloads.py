"""What GLOBE publishes for Home Assistant, as pure functions of the configuration and a
prediction: the topics, one device-based discovery payload per household, and its state.

Home Assistant's device-based discovery (``<prefix>/device/<object_id>/config``) takes one JSON
object per device: a ``device`` block (``identifiers`` required), an ``origin`` block (``name``
required) and ``components``, each with its ``platform`` and a ``unique_id``. Full key names are
used, not their abbreviations, so the payloads read like the documentation. Every entity reads
the household's one retained state message (the prediction as ``GET .../prediction`` returns it)
through a value template, and is available while GLOBE's status topic says ``online``. Each fetch
the robot should make is also one message on the household's fetch topic, read by an event entity:
an automation triggered by it runs once per fetch, also when two fetches follow each other (a state
that stays ``on`` would trigger only the first).

A household with sensors also has the activity recognised from them (a sensor reading the same
state message) and a *Question* event entity: each "what are you doing?" the household asks is one
message on its question topic, with the likely activities; the answer comes back as the activity's
name, plain text, on its answer topic (as a Home Assistant ``select`` is commanded with an option)."""

from __future__ import annotations

import hashlib
import json
import re
from typing import Any

from globe import __version__
from globe.config import MqttConfig
from globe.service.schemas import Prediction

ONLINE, OFFLINE = "online", "offline"
_SAFE_ID = re.compile(r"^[A-Za-z0-9_-]+$")  # what Home Assistant accepts as a discovery object id


def object_id(household: str) -> str:
    """The household's id in discovery topics and unique ids: ``globe_<name>``, made of
    ``[A-Za-z0-9_-]`` as Home Assistant requires (a name with a '.' gets a hash of the name, so two
    households never share an id)."""
    if _SAFE_ID.match(household):
        return f"globe_{household}"
    digest = hashlib.sha256(household.encode()).hexdigest()[:8]
    return f"globe_{re.sub(r'[^A-Za-z0-9_-]', '_', household)}_{digest}"


def availability_topic(config: MqttConfig) -> str:
    """GLOBE's status: ``online`` while connected, ``offline`` (its last will) otherwise."""
    return f"{config.topic_prefix}/status"


def state_topic(config: MqttConfig, household: str) -> str:
    return f"{config.topic_prefix}/{household}/state"


def fetch_topic(config: MqttConfig, household: str) -> str:
    """One message per fetch to make (never retained: a fetch is an event, not a state)."""
    return f"{config.topic_prefix}/{household}/fetch"


def question_topic(config: MqttConfig, household: str) -> str:
    """One message per question to the person (never retained: a question is an event)."""
    return f"{config.topic_prefix}/{household}/question"


def answer_topic(config: MqttConfig, household: str) -> str:
    """Where Home Assistant sends the answer: the activity, plain text."""
    return f"{config.topic_prefix}/{household}/answer"


def answer_household(config: MqttConfig, topic: str) -> str | None:
    """The household an answer topic names (None: not an answer topic)."""
    head, tail = f"{config.topic_prefix}/", "/answer"
    if not topic.startswith(head) or not topic.endswith(tail):
        return None
    name = topic[len(head):-len(tail)]
    return name if name and "/" not in name else None


def discovery_topic(config: MqttConfig, household: str) -> str:
    return f"{config.discovery_prefix}/device/{object_id(household)}/config"


def _percent(field: str) -> str:
    return f"{{{{ (value_json.{field} * 100) | round(1) if value_json.{field} is not none else none }}}}"


# component key -> (platform, name, value template, extra options)
_COMPONENTS: dict[str, tuple[str, str, str, dict[str, Any]]] = {
    "activity": ("sensor", "Next activity", "{{ value_json.activity }}",
                 {"icon": "mdi:human", "json_attributes_template":
                  '{{ {"probability": value_json.activity_probability, "day": value_json.day, '
                  '"step": value_json.step} | tojson }}'}),
    "activity_probability": ("sensor", "Next activity probability", _percent("activity_probability"),
                             {"unit_of_measurement": "%", "state_class": "measurement", "icon": "mdi:percent"}),
    "object": ("sensor", "Object needed next", "{{ value_json.object }}",
               {"icon": "mdi:cup", "json_attributes_template":
                '{{ {"probability": value_json.object_probability} | tojson }}'}),
    "object_probability": ("sensor", "Object probability", _percent("object_probability"),
                           {"unit_of_measurement": "%", "state_class": "measurement", "icon": "mdi:percent"}),
    "fetch_object": ("sensor", "Object to fetch", "{{ value_json.fetch_object }}", {"icon": "mdi:robot"}),
    "fetch_to": ("sensor", "Fetch to", "{{ value_json.fetch_to }}", {"icon": "mdi:map-marker"}),
    "fetch_probability": ("sensor", "Fetch probability", _percent("fetch_probability"),
                          {"unit_of_measurement": "%", "state_class": "measurement", "icon": "mdi:percent"}),
    "status": ("sensor", "Status", "{{ value_json.status }}",
               {"device_class": "enum", "options": ["learning", "ready"], "entity_category": "diagnostic"}),
    "days_learned": ("sensor", "Days learned", "{{ value_json.days_learned }}",
                     {"state_class": "measurement", "icon": "mdi:calendar-check", "entity_category": "diagnostic"}),
    "fetch": ("binary_sensor", "Fetch now", "{{ 'ON' if value_json.act else 'OFF' }}",
              {"payload_on": "ON", "payload_off": "OFF", "icon": "mdi:robot-excited",
               "json_attributes_template": '{{ {"object": value_json.fetch_object, "to": value_json.fetch_to, '
                                           '"probability": value_json.fetch_probability} | tojson }}'}),
}
FETCH_EVENT = "fetch_request"
COMPONENTS = (*_COMPONENTS, FETCH_EVENT)
"""The component keys of a household's device (``fetch_request``, the event an automation sends the
robot by; ``fetch``, the binary sensor saying a fetch is due now)."""
RECOGNISED = "recognised"
QUESTION_EVENT = "question"
SENSOR_COMPONENTS = (RECOGNISED, QUESTION_EVENT)
"""The components a household with sensors adds: the activity recognised from its sensors, and
the event of each question to the person."""


def discovery_payload(config: MqttConfig, household: str, sensors: bool = False) -> dict[str, Any]:
    """The household as one Home Assistant device (published retained on :func:`discovery_topic`);
    ``sensors``: it has sensors, so its activity is recognised and it may ask questions."""
    ident = object_id(household)
    topic = state_topic(config, household)
    components: dict[str, dict[str, Any]] = {}
    for key, (platform, name, template, extra) in _COMPONENTS.items():
        component: dict[str, Any] = {"platform": platform, "name": name, "unique_id": f"{ident}_{key}",
                                     "state_topic": topic, "value_template": template, **extra}
        if "json_attributes_template" in extra:
            component["json_attributes_topic"] = topic
        components[key] = component
    components[FETCH_EVENT] = {"platform": "event", "name": "Fetch request", "unique_id": f"{ident}_{FETCH_EVENT}",
                               "state_topic": fetch_topic(config, household), "event_types": ["fetch"],
                               "icon": "mdi:robot-excited"}
    if sensors:
        components[RECOGNISED] = {
            "platform": "sensor", "name": "Recognised activity", "unique_id": f"{ident}_{RECOGNISED}",
            "state_topic": topic, "json_attributes_topic": topic, "icon": "mdi:motion-sensor",
            "value_template": "{{ value_json.recognised.activity if value_json.recognised else none }}",
            "json_attributes_template": '{{ {"probability": value_json.recognised.probability if '
                                        'value_json.recognised else none, "labelled_steps": value_json.labelled_steps, '
                                        '"recognised_steps": value_json.recognised_steps} | tojson }}'}
        components[QUESTION_EVENT] = {"platform": "event", "name": "Question", "unique_id": f"{ident}_{QUESTION_EVENT}",
                                      "state_topic": question_topic(config, household), "event_types": ["question"],
                                      "icon": "mdi:chat-question"}
    return {
        "device": {"identifiers": [ident], "name": f"GLOBE {household}", "manufacturer": "GLOBE",
                   "model": "Household assistant", "sw_version": __version__},
        "origin": {"name": "GLOBE", "sw_version": __version__},
        "availability": [{"topic": availability_topic(config), "payload_available": ONLINE,
                          "payload_not_available": OFFLINE}],
        "qos": 1,
        "components": components,
    }


def state_payload(prediction: Prediction) -> str:
    """The household's state: the prediction as the HTTP API returns it (JSON)."""
    return prediction.model_dump_json()


def fetch_events(prediction: Prediction) -> list[str]:
    """The fetch topic's messages for a prediction: one per fetch when the robot is to act (none in
    shadow mode or while learning). Its keys besides ``event_type`` are the event's attributes."""
    if not prediction.act:
        return []
    return [encode({"event_type": "fetch", "object": f.object, "to": f.to, "probability": f.probability,
                    "day": prediction.day, "step": prediction.step}) for f in prediction.fetches]


def question_event(config: MqttConfig, household: str, prediction: Prediction) -> str | None:
    """The question topic's message for a prediction that asks one (else None): the likely
    activities, most probable first (``activities``, with ``probabilities`` in the same order),
    the step asked about (``day``, ``step``, ``time``) and where the answer goes
    (``answer_topic``, so one automation serves every household). Its keys besides
    ``event_type`` are the event's attributes."""
    q = prediction.question
    if q is None:
        return None
    return encode({"event_type": "question", "household": household,
                   "activities": [a.activity for a in q.activities],
                   "probabilities": [round(a.probability, 4) for a in q.activities], "day": q.day, "step": q.step,
                   "time": q.time, "answer_topic": answer_topic(config, household)})


def encode(payload: dict[str, Any]) -> str:
    return json.dumps(payload, separators=(",", ":"), ensure_ascii=False)


__all__ = ["COMPONENTS", "ONLINE", "OFFLINE", "object_id", "availability_topic", "state_topic", "fetch_topic",
           "discovery_topic", "discovery_payload", "state_payload", "fetch_events", "encode", "FETCH_EVENT",
           "RECOGNISED", "QUESTION_EVENT", "SENSOR_COMPONENTS", "question_topic", "answer_topic", "answer_household",
           "question_event"]
