"""Home Assistant's states, as its ``mqtt_statestream`` integration publishes them
(``<base_topic>/<domain>/<object_id>/state``, the payload the state string), turned into what one
observation of a household says: the latest activity and the latest known place of each object.

Pure bookkeeping, no MQTT: :class:`StateBook` is fed (topic, payload) pairs and read once per step
by the bridge (:mod:`globe.service.mqtt.bridge`), which submits the observation."""

from __future__ import annotations

import json
import threading
from dataclasses import dataclass, field

from globe.config import MqttConfig
from globe.data.csv_logs import activity_label

UNKNOWN_STATES = frozenset({"", "unknown", "unavailable", "none"})
"""States Home Assistant reports when it does not know: the activity is then unknown (null), an
object stays where it was last seen."""
MAX_PAYLOAD_BYTES = 1024


class MalformedMessage(ValueError):
    """A statestream message that cannot be a state (not UTF-8, too long, control characters, a
    label GLOBE refuses): logged and counted by the bridge, never stored."""


@dataclass(frozen=True, slots=True)
class Role:
    """What one entity tells one household: its activity (``obj`` None) or where ``obj`` is."""

    household: str
    entity: str
    obj: str | None = None


@dataclass(slots=True)
class Snapshot:
    """What a household's entities said last (``seen``: whether any of them said anything yet)."""

    activity: str | None = None
    locations: dict[str, str] = field(default_factory=dict)
    seen: bool = False


def entity_topic(config: MqttConfig, entity: str) -> str:
    """``input_select.activity`` -> ``<statestream_topic>/input_select/activity/state``."""
    domain, _, object_id = entity.partition(".")
    return f"{config.statestream_topic}/{domain}/{object_id}/state"


def decode_state(payload: bytes, max_length: int) -> str:
    """The state string of a statestream payload: UTF-8 text, or a JSON string (older Home
    Assistant releases JSON-encoded states: ``"on"`` quoted)."""
    if len(payload) > MAX_PAYLOAD_BYTES:
        raise MalformedMessage(f"payload of {len(payload)} bytes (at most {MAX_PAYLOAD_BYTES})")
    try:
        text = payload.decode("utf-8")
    except UnicodeDecodeError as err:
        raise MalformedMessage(f"payload is not UTF-8 text (byte {err.start})") from None
    if len(text) >= 2 and text[0] == text[-1] == '"':
        try:
            text = json.loads(text)
        except ValueError:
            raise MalformedMessage("payload is a malformed JSON string") from None
        if not isinstance(text, str):  # pragma: no cover - a quoted JSON text is a string
            raise MalformedMessage("payload is not a string")
    text = text.strip()
    if len(text) > max_length:
        raise MalformedMessage(f"state longer than {max_length} characters")
    if any(ord(c) < 32 or 127 <= ord(c) < 160 for c in text):
        raise MalformedMessage("state contains control characters")
    return text


class StateBook:
    """The latest states of the mapped entities, per household (thread-safe: MQTT's network thread
    writes, the bridge's step thread reads)."""

    def __init__(self, config: MqttConfig, max_label_length: int = 128) -> None:
        self.config = config
        self.max_label_length = max_label_length
        self.roles: dict[str, list[Role]] = {}  # topic -> who listens to it
        for name, entities in config.households.items():
            if entities.activity is not None:
                self.roles.setdefault(entity_topic(config, entities.activity), []).append(Role(name, entities.activity))
            for entity, mapped in entities.objects.items():
                self.roles.setdefault(entity_topic(config, entity), []).append(Role(name, entity, mapped.object))
        self._snapshots = {name: Snapshot() for name in config.households}
        self._lock = threading.Lock()

    def topics(self) -> list[str]:
        """The statestream topics to subscribe to."""
        return sorted(self.roles)

    def receive(self, topic: str, payload: bytes) -> int:
        """Record one statestream message; returns how many households it changed. Raises
        :class:`MalformedMessage` (and records nothing) for a payload that is not a state."""
        roles = self.roles.get(topic, ())
        if not roles:
            return 0
        state = decode_state(payload, self.max_label_length)
        updates: list[tuple[Role, str | None]] = []
        for role in roles:
            entities = self.config.households[role.household]
            if role.obj is None:
                activity = None if state.lower() in UNKNOWN_STATES else entities.activities.get(state, state)
                if activity is not None:
                    try:
                        activity = activity_label(activity)
                    except ValueError as err:
                        raise MalformedMessage(f"activity state {state[:64]!r}: {err}") from None
                updates.append((role, activity))
            else:
                location = entities.objects[role.entity].locations.get(state)
                if location is not None:
                    updates.append((role, location))
        with self._lock:
            for role, value in updates:
                snap = self._snapshots[role.household]
                snap.seen = True
                if role.obj is None:
                    snap.activity = value
                elif value is not None:
                    snap.locations[role.obj] = value
        return len(updates)

    def snapshot(self, household: str) -> Snapshot:
        """A copy of what the household's entities said last."""
        with self._lock:
            snap = self._snapshots[household]
            return Snapshot(snap.activity, dict(snap.locations), snap.seen)


__all__ = ["StateBook", "Snapshot", "Role", "MalformedMessage", "entity_topic", "decode_state", "UNKNOWN_STATES"]
