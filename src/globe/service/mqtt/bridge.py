"""The service's link to Home Assistant over MQTT (paho-mqtt 2), started and stopped with the app.

Out: each household is published as a Home Assistant device (:mod:`.payloads`) when the broker
connects and whenever Home Assistant says ``online`` on its status topic; its state is published
(retained) after each observation applied, whoever sent it (:meth:`Registry.subscribe`), and after
a change of shadow mode; each fetch due is one (unretained) message on its fetch topic, sent once,
and so is each question to the person on its question topic (a household with sensors).

In: the states of the entities mapped in ``[mqtt.households]`` (:mod:`.statestream`) become one
observation per step of the household, submitted through :meth:`Registry.observe` like a robot's
HTTP observation (the same validation, the same store), with an id made of the step's time so a
repeat is idempotent; it carries the mapped binary sensors' activations since the one before. An
answer on a household's answer topic is an observation of that activity at the step under way
(the one asked about). Observations pause while the broker or Home Assistant is offline (the
states could be stale).

Nothing here can stop the service: a broker that is down or drops the connection is retried by
paho with backoff (``reconnect_min_s`` doubling up to ``reconnect_max_s``) and shown in
``/health``; a malformed message is logged, counted and dropped.

Threads: paho's network thread (callbacks only record and enqueue), one publisher (predictions and
discovery, so a slow prediction never holds the network loop up), one stepper (observations)."""

from __future__ import annotations

import datetime as dt
import logging
import queue
import sys
import threading
import time
from dataclasses import dataclass
from typing import Any

from globe.config import GlobeConfig
from globe.config.mqtt import broker_address
from globe.errors import GlobeError, MissingExtraError, UnknownHouseholdError
from globe.service import answers
from globe.service.mqtt import payloads
from globe.service.mqtt.statestream import MalformedMessage, StateBook, decode_state
from globe.service.registry import Registry
from globe.service.schemas import MqttHealth

try:
    import paho.mqtt.client as paho
except ImportError as err:  # pragma: no cover - paho-mqtt is in the service extra
    raise MissingExtraError("paho-mqtt", "service") from err

log = logging.getLogger(__name__)

QOS = 1
_ANNOUNCE = "\0announce"  # publisher job: discovery and state of every household
_ANSWER = "\0answer"  # publisher job: the answers received (in self._answers)
_STOP = "\0stop"


@dataclass(frozen=True, slots=True)
class _Known:
    """What a household has that its ``[mqtt.households]`` entry may name."""

    objects: frozenset[str]
    places: frozenset[str]
    sensors: frozenset[str]
    has_sensors: bool


class MqttBridge:
    """Home Assistant over MQTT for one service (see the module doc)."""

    def __init__(self, registry: Registry, config: GlobeConfig) -> None:
        self.registry = registry
        self.config = config.mqtt
        self.host, self.port, tls = broker_address(self.config.broker)  # checked with the configuration
        self.book = StateBook(self.config, config.service.max_label_length)
        self._fetched: dict[str, tuple[str, int]] = {}  # per household, the step whose fetches were sent (publisher)
        self._asked: dict[str, tuple[str, int]] = {}  # per household, the step whose question was sent (publisher)
        self._answers: queue.Queue[tuple[str, bytes, float]] = queue.Queue()  # (household, payload, arrival)
        self._lock = threading.Lock()  # guards the fields below
        self._connected = False
        self._ha_online = True  # until Home Assistant says otherwise on its status topic
        self._last_error: str | None = None
        self._counts = {"malformed": 0, "observations": 0, "rejected": 0, "published": 0}
        self._announced: set[str] = set()
        self._steps: dict[str, int] = {}  # household -> seconds between its observations
        self._maps: dict[str, _Known] = {}  # household -> what it has, for its [mqtt.households] entry
        self._sensing: dict[str, bool] = {}  # household -> whether it has sensors (its device's components)
        self._problems: dict[str, list[str]] = {}  # household -> what its [mqtt.households] entry names wrong
        self._jobs: queue.Queue[str] = queue.Queue()
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._stopping = False
        client = paho.Client(paho.CallbackAPIVersion.VERSION2, client_id=self.config.client_id,
                             protocol=paho.MQTTv311)
        if self.config.username is not None:
            client.username_pw_set(self.config.username, self.config.password_text())
        if tls:
            ca = self.config.ca_file
            client.tls_set(ca_certs=str(ca) if ca is not None else None)
        client.will_set(payloads.availability_topic(self.config), payloads.OFFLINE, qos=QOS, retain=True)
        client.reconnect_delay_set(self.config.reconnect_min_s, self.config.reconnect_max_s)
        client.on_connect = self._on_connect
        client.on_connect_fail = self._on_connect_fail
        client.on_disconnect = self._on_disconnect
        client.on_message = self._on_message
        self.client = client

    # -- life ------------------------------------------------------------------------------------
    def start(self) -> None:
        """Connect in the background (never raises for a broker that is down: it is retried)."""
        self.registry.subscribe(self._observed)
        missing = sorted(set(self.config.households) - set(self.registry.names()))
        if missing:
            log.warning("[mqtt.households] maps %s, not in the database (yet): observed once created",
                        ", ".join(missing))
        for target, name in ((self._publish_loop, "globe-mqtt-publish"), (self._step_loop, "globe-mqtt-step")):
            thread = threading.Thread(target=target, name=name, daemon=True)
            thread.start()
            self._threads.append(thread)
        self.client.connect_async(self.host, self.port, keepalive=self.config.keepalive_s)
        self.client.loop_start()

    def stop(self) -> None:
        """Say ``offline``, disconnect, and stop the threads."""
        self._stopping = True
        self._stop.set()
        self._jobs.put(_STOP)
        for thread in self._threads:
            thread.join(timeout=10)
        if self.connected:
            info = self.client.publish(payloads.availability_topic(self.config), payloads.OFFLINE, qos=QOS, retain=True)
            try:
                info.wait_for_publish(timeout=2)
            except (RuntimeError, ValueError):
                pass
        self.client.disconnect()
        self.client.loop_stop()

    @property
    def connected(self) -> bool:
        with self._lock:
            return self._connected

    def health(self) -> MqttHealth:
        with self._lock:
            return MqttHealth(state="connected" if self._connected else "disconnected", broker=self.config.broker,
                              last_error=self._last_error, **self._counts,
                              problems=[p for found in self._problems.values() for p in found])

    def _count(self, what: str) -> None:
        with self._lock:
            self._counts[what] += 1

    # -- paho's callbacks (its network thread: record and enqueue only) ----------------------------
    def _on_connect(self, client: paho.Client, userdata: Any, flags: Any, reason: Any, properties: Any) -> None:
        if reason.is_failure:
            with self._lock:
                self._last_error = f"the broker refused the connection: {reason}"
            log.warning("MQTT broker %s refused the connection: %s", self.config.broker, reason)
            return
        with self._lock:
            self._connected = True
        log.info("connected to the MQTT broker %s", self.config.broker)
        client.subscribe([(self.config.status_topic, QOS), (payloads.answer_topic(self.config, "+"), QOS)]
                         + [(t, QOS) for t in self.book.topics()])
        client.publish(payloads.availability_topic(self.config), payloads.ONLINE, qos=QOS, retain=True)
        self._jobs.put(_ANNOUNCE)

    def _on_connect_fail(self, client: paho.Client, userdata: Any) -> None:
        err = sys.exc_info()[1]  # paho calls this while handling the connection's OSError
        message = f"cannot connect to {self.host}:{self.port}: {err or 'connection failed'}"
        with self._lock:
            repeated, self._last_error = message == self._last_error, message
        if not repeated:  # once per cause, not at every retry of a broker that stays down
            log.warning("MQTT: %s (retrying with backoff up to %d s)", message, self.config.reconnect_max_s)

    def _on_disconnect(self, client: paho.Client, userdata: Any, flags: Any, reason: Any, properties: Any) -> None:
        with self._lock:
            self._connected = False
            if not self._stopping:
                self._last_error = f"connection lost: {reason}"
        if not self._stopping:
            log.warning("MQTT broker %s: connection lost (%s); reconnecting", self.config.broker, reason)

    def _on_message(self, client: paho.Client, userdata: Any, message: paho.MQTTMessage) -> None:
        try:
            if message.topic == self.config.status_topic:
                status = message.payload.decode("utf-8", "replace").strip()
                with self._lock:
                    self._ha_online = status != payloads.OFFLINE
                if status == payloads.ONLINE:
                    self._jobs.put(_ANNOUNCE)
                return
            answered = payloads.answer_household(self.config, message.topic)
            if answered is not None:
                if not message.retain:  # a retained answer is an old one, not the person now
                    self._answers.put((answered, bytes(message.payload), time.time()))
                    self._jobs.put(_ANSWER)
                return
            self.book.receive(message.topic, bytes(message.payload), now=time.time(), retained=bool(message.retain))
        except MalformedMessage as err:
            self._count("malformed")
            log.warning("MQTT message on %s dropped: %s", message.topic[:200], err)
        except Exception:  # noqa: BLE001 - no message can stop the network thread
            self._count("malformed")
            log.exception("MQTT message on %s dropped", message.topic[:200])

    # -- out: discovery and states ----------------------------------------------------------------
    def _observed(self, household: str) -> None:
        """The registry's listener: a new prediction to publish (by the publisher thread)."""
        self._jobs.put(household)

    def _publish_loop(self) -> None:
        while True:
            jobs = {self._jobs.get()}
            while True:  # everything queued meanwhile, each household once
                try:
                    jobs.add(self._jobs.get_nowait())
                except queue.Empty:
                    break
            if _STOP in jobs:
                return
            try:
                if _ANSWER in jobs:
                    self._take_answers()
                names = self._announce() if _ANNOUNCE in jobs else set()
                for name in sorted(jobs - names - {_ANNOUNCE, _ANSWER}):
                    self._publish_state(name)
            except Exception:  # noqa: BLE001 - the publisher outlives any failure; each is logged
                log.exception("publishing to MQTT failed")

    def _publish(self, topic: str, payload: str) -> None:
        self.client.publish(topic, payload, qos=QOS, retain=True)

    def _announce(self) -> set[str]:
        """Discovery and state of every household; the devices of deleted ones removed."""
        names = set(self.registry.names())
        if not self.connected:
            return names
        for gone in sorted(self._announced - names):
            self._remove(gone)
        for name in sorted(names):
            self._publish_discovery(name)
            self._publish_state(name)
        return names

    def _publish_discovery(self, name: str) -> None:
        sensors = self._has_sensors(name)
        self._publish(payloads.discovery_topic(self.config, name),
                      payloads.encode(payloads.discovery_payload(self.config, name, sensors=sensors)))
        self._announced.add(name)

    def _has_sensors(self, name: str) -> bool:
        """Whether the household has sensors (its device then shows the recognised activity and its
        questions); False while it cannot be built, asked again then."""
        if name not in self._sensing:
            try:
                with self.registry.locked(name) as session:
                    self._sensing[name] = session.sensing is not None
            except GlobeError:
                return False
        return self._sensing[name]

    def _publish_state(self, name: str) -> None:
        if not self.connected:
            return  # everything is published again when the broker connects
        try:
            prediction = self.registry.predict(name)
        except UnknownHouseholdError:
            if name in self._announced:
                self._remove(name)
            return
        except GlobeError as err:
            log.warning("MQTT: no state for household %s: %s", name, err)
            return
        if name not in self._announced:  # created since the last announcement
            self._publish_discovery(name)
        self._publish(payloads.state_topic(self.config, name), payloads.state_payload(prediction))
        self._count("published")
        events = payloads.fetch_events(prediction)
        if events and self._fetched.get(name) != (prediction.day, prediction.step):  # each fetch once
            self._fetched[name] = (prediction.day, prediction.step)
            for event in events:
                self.client.publish(payloads.fetch_topic(self.config, name), event, qos=QOS, retain=False)
        question = payloads.question_event(self.config, name, prediction)
        asked = prediction.question
        if question is not None and asked is not None and self._asked.get(name) != (asked.day, asked.step):
            self._asked[name] = (asked.day, asked.step)  # each question once
            self.client.publish(payloads.question_topic(self.config, name), question, qos=QOS, retain=False)

    def _remove(self, name: str) -> None:
        """An empty retained config removes the device from Home Assistant (and its state)."""
        self._fetched.pop(name, None)
        self._asked.pop(name, None)
        self._publish(payloads.discovery_topic(self.config, name), "")
        self._publish(payloads.state_topic(self.config, name), "")
        self._announced.discard(name)
        with self._lock:  # a household made again under this name is looked at afresh
            self._maps.pop(name, None)
            self._problems.pop(name, None)
            self._steps.pop(name, None)
        self._sensing.pop(name, None)

    # -- in: observations from Home Assistant's states ----------------------------------------------
    def _step_loop(self) -> None:
        """Wake at every tick (``observe_interval_s``, else each minute, aligned to the clock) and
        observe each mapped household whose step starts then."""
        if not self.config.households:
            return
        tick_s = self.config.observe_interval_s or 60
        boundary = (int(time.time()) // tick_s + 1) * tick_s
        while not self._stop.wait(max(0.0, boundary - time.time())):
            if time.time() < boundary:
                continue
            for name in self.config.households:
                try:
                    step = self._step_seconds(name)
                    if step and boundary % step == 0:
                        self._observe(name, boundary)
                except Exception:  # noqa: BLE001 - one household's failure never stops the others
                    self._count("rejected")
                    log.exception("MQTT: observing household %s failed", name)
            boundary = (int(time.time()) // tick_s + 1) * tick_s

    def _step_seconds(self, name: str) -> int | None:
        """Seconds between the household's observations: ``observe_interval_s``, else its step
        (None while it cannot be built or does not exist)."""
        if self.config.observe_interval_s is not None:
            return self.config.observe_interval_s
        if name not in self._steps:
            try:
                with self.registry.locked(name) as session:
                    self._steps[name] = session.grid.step_minutes * 60
            except GlobeError:
                return None
        return self._steps[name]

    def _map(self, name: str) -> _Known | None:
        """The household's objects, places and sensors (None while it cannot be built); its
        ``[mqtt.households]`` entry checked against them once: an object it does not have, a
        place not on its map or a sensor it does not have is logged and shown in /health, and that
        entity's state is left out of the household's observations (once, it refused every
        observation, activity and all)."""
        if name not in self._maps:
            try:
                with self.registry.locked(name) as session:
                    sensing = session.sensing
                    found = _Known(frozenset(session.household.objects), frozenset(session.household.locations),
                                   frozenset(sensing.index) if sensing is not None else frozenset(),
                                   sensing is not None)
            except GlobeError:
                return None
            entry, problems = self.config.households.get(name), []
            for entity, mapped in (entry.objects.items() if entry is not None else ()):
                if mapped.object not in found.objects:
                    problems.append(f"{name}: {entity} follows {mapped.object!r}, not an object of the household")
                problems += [f"{name}: {entity} state {state!r} puts {mapped.object} at {place!r}, not a place of "
                             "the household's map" for state, place in mapped.locations.items()
                             if place not in found.places]
            mapped_sensors = entry.sensors.items() if entry is not None else ()
            if mapped_sensors and not found.has_sensors:
                problems.append(f"{name}: sensors are mapped, but the household has none (create it with its "
                                "sensors)")
            else:
                problems += [f"{name}: {entity} is sensor {sensor!r}, not a sensor of the household"
                             for entity, sensor in mapped_sensors if sensor not in found.sensors]
            for problem in problems:
                log.warning("MQTT: [mqtt.households.%s]: %s (that state is left out of its observations)", name,
                            problem)
            with self._lock:
                self._maps[name], self._problems[name] = found, problems
        return self._maps[name]

    def _observe(self, name: str, instant: int) -> None:
        """One observation of the household at ``instant`` (epoch seconds) from the latest states,
        with the sensor activations seen since the one before."""
        snap = self.book.snapshot(name)
        with self._lock:
            live = self._connected and self._ha_online
        if not snap.seen or not live:
            return
        known = self._map(name)
        if known is None:
            return
        locations = {obj: place for obj, place in snap.locations.items()
                     if obj in known.objects and place in known.places}
        sensors = [(a.sensor, _utc(a.start), _utc(a.end)) for a in self.book.take_activations(name)
                   if a.sensor in known.sensors]
        when = _utc(instant)
        try:
            self.registry.observe(name, time=when, activity=snap.activity, locations=locations,
                                  client_id=f"ha-{when:%Y%m%dT%H%M%SZ}", sensors=sensors)
        except GlobeError as err:
            self._count("rejected")
            log.warning("MQTT: observation of household %s at %s refused: %s", name, when.isoformat(), err)
            return
        self._count("observations")

    # -- in: answers to questions ---------------------------------------------------------------------
    def _take_answers(self) -> None:
        while True:
            try:
                name, payload, arrived = self._answers.get_nowait()
            except queue.Empty:
                return
            try:
                self._answer(name, payload, arrived)
            except Exception:  # noqa: BLE001 - one answer's failure never stops the publisher
                self._count("rejected")
                log.exception("MQTT: the answer for household %s failed", name)

    def _answer(self, name: str, payload: bytes, arrived: float) -> None:
        """An answer (the activity, plain text) is the label of the step under way, the one a
        question asks about, observed at its arrival (:func:`globe.service.answers.answer`). One
        arriving after that step was left is logged and left out: the person may be doing
        something else by then."""
        try:
            text = decode_state(payload, self.book.max_label_length)
        except MalformedMessage as err:
            self._count("malformed")
            log.warning("MQTT: answer for household %s dropped: %s", name, err)
            return
        entry = self.config.households.get(name)
        activity = entry.activities.get(text, text) if entry is not None else text
        when = _utc(arrived)
        try:
            answers.answer(self.registry, name, activity, arrived=when, client_id=f"ha-answer-{when:%Y%m%dT%H%M%S.%fZ}")
        except GlobeError as err:
            self._count("rejected")
            log.warning("MQTT: answer for household %s refused: %s", name, err)
            return
        self._count("observations")


def _utc(instant: float) -> dt.datetime:
    return dt.datetime.fromtimestamp(instant, dt.timezone.utc)


__all__ = ["MqttBridge", "broker_address"]
