"""Home Assistant's MQTT discovery schema, written from its documentation (integrations/mqtt:
"Device discovery payload", "Using availability topics"; integrations/sensor.mqtt and
binary_sensor.mqtt: their configuration variables), as a checker for the tests: it returns the
problems it finds in a device discovery message, and renders the value templates the way Home
Assistant would (Jinja with ``value_json``) against a state message.

Full key names only (GLOBE does not abbreviate); options not listed here are reported, so a typo
in a key is a failure rather than an option Home Assistant would silently ignore."""

from __future__ import annotations

import json
import re
from typing import Any

import jinja2

ID = re.compile(r"^[a-zA-Z0-9_-]+$")  # discovery object ids and component ids
ROOT_KEYS = {"device", "origin", "components", "availability", "availability_mode", "availability_topic",
             "payload_available", "payload_not_available", "state_topic", "command_topic", "qos", "encoding"}
DEVICE_KEYS = {"identifiers", "connections", "name", "manufacturer", "model", "model_id", "sw_version", "hw_version",
               "serial_number", "suggested_area", "via_device", "configuration_url"}
ORIGIN_KEYS = {"name", "sw_version", "support_url"}
AVAILABILITY_KEYS = {"topic", "payload_available", "payload_not_available", "value_template"}
_COMMON = {"platform", "availability", "availability_mode", "availability_template", "availability_topic",
           "device_class", "enabled_by_default", "encoding", "entity_category", "entity_picture", "expire_after",
           "force_update", "icon", "json_attributes_template", "json_attributes_topic", "name", "object_id",
           "default_entity_id", "payload_available", "payload_not_available", "qos", "state_topic", "unique_id",
           "value_template"}
PLATFORM_KEYS = {
    "sensor": _COMMON | {"last_reset_value_template", "options", "state_class", "suggested_display_precision",
                         "unit_of_measurement"},
    "binary_sensor": _COMMON | {"off_delay", "payload_off", "payload_on"},
    "event": (_COMMON - {"expire_after", "force_update"}) | {"event_types"},  # integrations/event.mqtt
}
STATE_CLASSES = {"measurement", "measurement_angle", "total", "total_increasing"}
ENTITY_CATEGORIES = {"config", "diagnostic"}


def _topic_problems(where: str, topic: Any) -> list[str]:
    if not isinstance(topic, str) or not topic:
        return [f"{where}: not a topic ({topic!r})"]
    if "+" in topic or "#" in topic:
        return [f"{where}: {topic!r} has a wildcard (a state topic names one topic)"]
    return []


def discovery_problems(topic: str, payload: dict[str, Any], prefix: str = "homeassistant") -> list[str]:
    """What in a device-based discovery message breaks the documented schema (empty: none)."""
    problems: list[str] = []
    m = re.fullmatch(rf"{re.escape(prefix)}/device/([^/]+)/config", topic)
    if m is None or not ID.match(m.group(1)):
        problems.append(f"topic {topic!r} is not {prefix}/device/<[a-zA-Z0-9_-]+>/config")
    problems += [f"unknown root option {k!r}" for k in set(payload) - ROOT_KEYS]
    device = payload.get("device")
    if not isinstance(device, dict):
        problems.append("the device mapping is required")
    else:
        problems += [f"unknown device option {k!r}" for k in set(device) - DEVICE_KEYS]
        ids = device.get("identifiers")
        if not ids and not device.get("connections"):
            problems.append("device needs identifiers (or connections)")
        strings = isinstance(ids, str) or (isinstance(ids, list) and all(isinstance(i, str) for i in ids))
        if ids is not None and not strings:
            problems.append("device identifiers: a string or a list of strings")
    origin = payload.get("origin")
    if not isinstance(origin, dict) or not isinstance(origin.get("name"), str):
        problems.append("the origin mapping with a name is required")
    else:
        problems += [f"unknown origin option {k!r}" for k in set(origin) - ORIGIN_KEYS]
    availability = payload.get("availability")
    if availability is not None:
        if "availability_topic" in payload:
            problems.append("availability and availability_topic must not both be used")
        if not isinstance(availability, list) or not availability:
            problems.append("availability: a list of {topic, ...}")
        else:
            for i, a in enumerate(availability):
                problems += _topic_problems(f"availability[{i}].topic", a.get("topic"))
                problems += [f"unknown availability option {k!r}" for k in set(a) - AVAILABILITY_KEYS]
    if payload.get("qos", 0) not in (0, 1, 2):
        problems.append("qos: 0, 1 or 2")
    components = payload.get("components")
    if not isinstance(components, dict) or not components:
        return problems + ["the components mapping is required"]
    unique_ids: set[str] = set()
    for key, comp in components.items():
        where = f"components.{key}"
        if not ID.match(key):
            problems.append(f"{where}: the component id is not [a-zA-Z0-9_-]+")
        platform = comp.get("platform")
        if platform not in PLATFORM_KEYS:
            problems.append(f"{where}: platform {platform!r} is not one this checker knows")
            continue
        problems += [f"{where}: unknown {platform} option {k!r}" for k in set(comp) - PLATFORM_KEYS[platform]]
        uid = comp.get("unique_id")
        if not isinstance(uid, str) or not uid:
            problems.append(f"{where}: unique_id is required for device discovery")
        elif uid in unique_ids:
            problems.append(f"{where}: unique_id {uid!r} used twice")
        else:
            unique_ids.add(uid)
        problems += _topic_problems(f"{where}.state_topic", comp.get("state_topic", payload.get("state_topic")))
        if "json_attributes_template" in comp and "json_attributes_topic" not in comp:
            problems.append(f"{where}: json_attributes_template without json_attributes_topic")
        if "json_attributes_topic" in comp:
            problems += _topic_problems(f"{where}.json_attributes_topic", comp["json_attributes_topic"])
        if comp.get("entity_category", "diagnostic") not in ENTITY_CATEGORIES:
            problems.append(f"{where}: entity_category {comp['entity_category']!r}")
        if platform == "event":
            types = comp.get("event_types")
            if not isinstance(types, list) or not types or not all(isinstance(t, str) for t in types):
                problems.append(f"{where}: an event needs event_types, a list of strings")
        if platform == "sensor":
            if comp.get("state_class", "measurement") not in STATE_CLASSES:
                problems.append(f"{where}: state_class {comp['state_class']!r}")
            if comp.get("device_class") == "enum":
                if not isinstance(comp.get("options"), list) or not comp["options"]:
                    problems.append(f"{where}: an enum sensor needs options")
                if "unit_of_measurement" in comp or "state_class" in comp:
                    problems.append(f"{where}: an enum sensor has no unit and no state_class")
            elif "options" in comp:
                problems.append(f"{where}: options only with device_class enum")
    return problems


_JINJA = jinja2.Environment(undefined=jinja2.StrictUndefined)


def render(template: str, state: dict[str, Any]) -> str:
    """A value template rendered as Home Assistant's MQTT entities do: ``value_json`` is the
    decoded payload, ``value`` its text."""
    return _JINJA.from_string(template).render(value_json=state, value=json.dumps(state))


def entity_states(payload: dict[str, Any], state: dict[str, Any]) -> dict[str, tuple[str, dict | None]]:
    """Each component's state (the rendered value template; 'None' is Home Assistant's unknown)
    and attributes (the rendered attributes template, a JSON object) for one state message."""
    out = {}
    for key, comp in payload["components"].items():
        if comp["platform"] == "event":
            continue  # it reads its own topic
        value = render(comp.get("value_template", "{{ value }}"), state).strip()
        attrs = None
        if "json_attributes_template" in comp:
            attrs = json.loads(render(comp["json_attributes_template"], state))
            assert isinstance(attrs, dict), f"{key}: attributes are not a JSON object"
        out[key] = (value, attrs)
    return out
