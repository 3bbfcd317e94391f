"""Home Assistant's states, as its ``mqtt_statestream`` integration publishes them
(``<base_topic>/<domain>/<object_id>/state``, the payload the state string), turned into what one
observation of a household says: the latest activity, the latest known place of each object, and
the sensor activations since the observation before (a mapped binary sensor's on..off spells).

Pure bookkeeping, no MQTT: :class:`StateBook` is fed (topic, payload) pairs and read once per step
by the bridge (:mod:`globe.service.mqtt.bridge`), which submits the observation."""

from __future__ import annotations

import json
import threading
import time
from dataclasses import dataclass, field

from globe.config import MqttConfig
from globe.data.csv_logs import activity_label

UNKNOWN_STATES = frozenset({"", "unknown", "unavailable", "none"})
"""States Home Assistant reports when it does not know: the activity is then unknown (null), an
object stays where it was last seen."""
MAX_PAYLOAD_BYTES = 1024
MAX_PENDING_EVENTS = 10_000
"""Sensor activations kept for a household's next observation, at most (the oldest go first: a
household that cannot be observed for long must not grow the service's memory without bound)."""


class MalformedMessage(ValueError):
    """A statestream message that cannot be a state (not UTF-8, too long, control characters, a
    label GLOBE refuses): logged and counted by the bridge, never stored."""


@dataclass(frozen=True, slots=True)
class Role:
    """What one entity tells one household: its activity (``obj`` and ``sensor`` None), where
    ``obj`` is, or when ``sensor`` (one of the household's sensors) is on."""

    household: str
    entity: str
    obj: str | None = None
    sensor: str | None = None


@dataclass(frozen=True, slots=True)
class Activation:
    """One sensor activation seen over MQTT: the household's sensor, and when it went on and off
    (epoch seconds; a firing, seen only as one change, has ``end == start``)."""

    sensor: str
    start: float
    end: float


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
            for entity, sensor in entities.sensors.items():
                self.roles.setdefault(entity_topic(config, entity), []).append(Role(name, entity, sensor=sensor))
        self._snapshots = {name: Snapshot() for name in config.households}
        self._on: dict[tuple[str, str], float] = {}  # (household, entity) -> since when it is on
        self._fired: dict[tuple[str, str], int] = {}  # (household, entity) -> its pending firing at switch-on
        self._pending: dict[str, list[Activation]] = {name: [] for name in config.households}
        self._lock = threading.Lock()

    def topics(self) -> list[str]:
        """The statestream topics to subscribe to."""
        return sorted(self.roles)

    def receive(self, topic: str, payload: bytes, now: float | None = None, retained: bool = False) -> int:
        """Record one statestream message (``now``: when it arrived, epoch seconds; ``retained``:
        the broker's stored state sent on subscribing, a state of unknown age rather than a
        change); returns how many households it changed. Raises :class:`MalformedMessage` (and
        records nothing) for a payload that is not a state."""
        roles = self.roles.get(topic, ())
        if not roles:
            return 0
        state = decode_state(payload, self.max_label_length)
        now = time.time() if now is None else now
        updates: list[tuple[Role, str | None]] = []
        for role in roles:
            entities = self.config.households[role.household]
            if role.sensor is not None:
                switch = state.lower()
                if switch in ("on", "off"):
                    updates.append((role, switch))
            elif role.obj is None:
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
                if role.sensor is not None:
                    self._switch(role, value == "on", now, retained)
                elif role.obj is None:
                    snap.activity = value
                elif value is not None:
                    snap.locations[role.obj] = value
        return len(updates)

    def _switch(self, role: Role, on: bool, now: float, retained: bool) -> None:
        """A binary sensor's state (under the lock): a switch-on is sent at once as a firing (its
        change is evidence now) and the whole activation when it switches off; an off never seen
        on is a firing. A retained state only says where the sensor stands (since when is not known)."""
        key = (role.household, role.entity)
        pending = self._pending[role.household]
        since = self._on.get(key)
        if on:
            if since is None:
                self._on[key] = now
                if not retained:
                    self._fired[key] = len(pending)
                    self._add(role.household, Activation(role.sensor or "", now, now))
            return
        if since is None and retained:
            return
        self._on.pop(key, None)
        fired = self._fired.pop(key, None)
        activation = Activation(role.sensor or "", now if since is None else since, now)
        if fired is not None and fired < len(pending) and pending[fired].start == activation.start \
                and pending[fired].sensor == activation.sensor:
            pending[fired] = activation  # its switch-on not observed yet: one activation, not two
        else:
            self._add(role.household, activation)

    def _add(self, household: str, activation: Activation) -> None:
        pending = self._pending[household]
        pending.append(activation)
        if len(pending) > MAX_PENDING_EVENTS:
            drop = len(pending) - MAX_PENDING_EVENTS
            del pending[:drop]
            self._fired = {k: i - (drop if k[0] == household else 0) for k, i in self._fired.items()
                           if k[0] != household or i >= drop}

    def take_activations(self, household: str) -> list[Activation]:
        """The household's sensor activations since the last call, for its next observation."""
        with self._lock:
            found, self._pending[household] = self._pending[household], []
            self._fired = {k: i for k, i in self._fired.items() if k[0] != household}
            return found

    def snapshot(self, household: str) -> Snapshot:
        """A copy of what the household's entities said last."""
        with self._lock:
            snap = self._snapshots[household]
            return Snapshot(snap.activity, dict(snap.locations), snap.seen)


__all__ = ["StateBook", "Snapshot", "Role", "Activation", "MalformedMessage", "entity_topic", "decode_state",
           "UNKNOWN_STATES", "MAX_PENDING_EVENTS"]
