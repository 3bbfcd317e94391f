"""Home Assistant over MQTT for a household with sensors, end to end (a real ``globe serve`` and a
real Mosquitto broker, a test client in Home Assistant's place): mapped binary sensors' on/off
states reach the household as sensor activations with its observations (an entity naming no
sensor of the household shown in /health and left out), the recognised activity is published as
an entity of its own, and a question is one event whose answer, sent back over MQTT, is the label
of the step asked about."""

from __future__ import annotations

import datetime as dt
import json
import time

import httpx
import pytest

from tests.service.ha_discovery_schema import discovery_problems, entity_states
from tests.service.mosquitto import Listener, Mosquitto, mqtt_config
from tests.service.test_sensor_households import create_body
from tests.simulated_sensors import sensor_home

pytestmark = pytest.mark.service

HOME = "home"
DISCOVERY = f"homeassistant/device/globe_{HOME}/config"
STATE = f"globe/{HOME}/state"
QUESTION = f"globe/{HOME}/question"
ANSWER = f"globe/{HOME}/answer"
KITCHEN = "homeassistant/binary_sensor/kitchen_motion/state"
FRIDGE = "homeassistant/binary_sensor/fridge_door/state"
GARDEN = "homeassistant/binary_sensor/garden_motion/state"
STEP_S = 600


def config_text(broker: Mosquitto) -> str:
    """No activity entity: the household's activity is recognised from its sensors."""
    return mqtt_config(broker, f"""observe_interval_s = 1

[mqtt.households.{HOME}]
sensors = {{ "binary_sensor.kitchen_motion" = "M_kitchen", "binary_sensor.fridge_door" = "C_fridge", \
"binary_sensor.garden_motion" = "M_garden" }}
""")


def midday_zone() -> str:
    """A zone where it is about noon now, inside the household's day (06:00 to 24:00) whenever the
    test runs, so the step under way is one the household knows."""
    offset = (12 - dt.datetime.now(dt.timezone.utc).hour + 12) % 24 - 12
    return "UTC" if offset == 0 else f"Etc/GMT{'-' if offset > 0 else '+'}{abs(offset)}"  # Etc/GMT-5 is UTC+5


@pytest.fixture(scope="module")
def home():
    return sensor_home(days=6, test=1, step=10)


@pytest.fixture(scope="module")
def broker(tmp_path_factory):
    b = Mosquitto(tmp_path_factory.mktemp("broker"))
    b.start()
    yield b
    b.kill()


@pytest.fixture(scope="module")
def ha(broker):
    listener = Listener(broker.port)
    yield listener
    listener.close()


@pytest.fixture(scope="module")
def globe(tmp_path_factory, broker, ha, home):
    """``globe serve`` with the [mqtt] section above (questions_per_day high enough to ask at any
    unsure step), and household ``home`` created with its sensors (one service for the module: it
    takes seconds to start and to choose the household's recogniser)."""
    from tests.service_process import Server

    tmp = tmp_path_factory.mktemp("globe")
    path = tmp / "globe.toml"
    path.write_text(config_text(broker))
    srv = Server(tmp / "globe.sqlite3", tmp / "server.log", {"GLOBE_SERVICE__QUESTIONS_PER_DAY": "1000"})
    srv.args = ["--config", str(path)]
    srv.start()
    r = httpx.post(srv.url + "/households", json={**create_body(home, HOME), "timezone": midday_zone()},
                   headers=auth(srv), timeout=120)
    assert r.status_code == 201, r.text
    yield srv
    srv.stop()


def auth(srv) -> dict[str, str]:
    return {"Authorization": f"Bearer {srv.admin}"}


def health(srv) -> dict:
    return httpx.get(srv.url + "/health").json()


def exported(srv) -> list[dict]:
    r = httpx.get(f"{srv.url}/households/{HOME}/export", headers=auth(srv))
    r.raise_for_status()
    return r.json()["observations"]


def until(check, what: str, timeout: float = 10.0):
    deadline = time.time() + timeout
    while not (found := check()):
        assert time.time() < deadline, what
        time.sleep(0.2)
    return found


def away_from_a_step_boundary(margin: float = 30.0) -> None:
    """A question and its answer must fall in one 10-minute step: start well inside one."""
    left = STEP_S - time.time() % STEP_S
    if left < margin:
        time.sleep(left + 1)


def test_a_question_is_an_event_and_its_answer_over_mqtt_labels_the_step(globe, ha):
    """First in the module: the household asks at most once in ten steps."""
    srv = globe
    away_from_a_step_boundary()
    seen = len(ha.messages)
    for _ in range(3):  # the kitchen busy: meal preparation, washing dishes or a meal; worth asking
        ha.publish(KITCHEN, "on")
        ha.publish(KITCHEN, "off")
    asked = ha.wait_for(lambda m: m.topic == QUESTION, timeout=15, after=seen)
    question = json.loads(asked.payload)
    assert not asked.retain and question["event_type"] == "question" and question["answer_topic"] == ANSWER
    assert question["activities"] and len(question["probabilities"]) == len(question["activities"])
    state = json.loads(ha.wait_for(lambda m: m.topic == STATE and json.loads(m.payload)["question"]).payload)
    assert (state["question"]["day"], state["question"]["step"]) == (question["day"], question["step"])

    answer = question["activities"][-1]
    seen = len(ha.messages)
    ha.publish(ANSWER, answer)
    stored = until(lambda: [o for o in exported(srv) if (o["client_id"] or "").startswith("ha-answer-")],
                   f"the answer stored: {health(srv)}")
    assert stored[0]["activity"] == answer
    after = json.loads(ha.wait_for(lambda m: m.topic == STATE and json.loads(m.payload)["labelled_steps"] >= 1,
                                   after=seen).payload)
    assert after["question"] is None and after["recognised"] is None  # the step has its label now
    assert after["step"] == question["step"] + 1 and after["day"] == question["day"]

    # an activity the household does not know is refused and counted, never stored
    rejected = health(srv)["mqtt"]["rejected"]
    ha.publish(ANSWER, "juggling")
    until(lambda: health(srv)["mqtt"]["rejected"] == rejected + 1, "the unknown answer counted")
    assert [o["activity"] for o in exported(srv) if (o["client_id"] or "").startswith("ha-answer-")] == [answer]


def test_binary_sensors_reach_the_household_and_the_recognised_activity_is_published(globe, ha):
    srv = globe
    rejected = health(srv)["mqtt"]["rejected"]
    for _ in range(2):
        ha.publish(KITCHEN, "on")
        ha.publish(FRIDGE, "on")
        time.sleep(0.1)
        ha.publish(FRIDGE, "off")
        ha.publish(KITCHEN, "off")
    ha.publish(GARDEN, "on")  # no sensor of the household: shown in /health, left out
    ha.publish(GARDEN, "off")

    def carried() -> list[list]:
        return [e for o in exported(srv) if (o["client_id"] or "").startswith("ha-") and o["sensors"]
                for e in json.loads(o["sensors"])]

    # an on..off spell (not only the firing sent at its switch-on), with the other sensor's
    until(lambda: sum(e[0] == "C_fridge" and e[1] != e[2] for e in carried()) >= 2, f"stored: {health(srv)}")
    assert {e[0] for e in carried()} == {"M_kitchen", "C_fridge"}
    problems = health(srv)["mqtt"]["problems"]
    assert problems == ["home: binary_sensor.garden_motion is sensor 'M_garden', not a sensor of the household"]
    assert health(srv)["mqtt"]["rejected"] == rejected  # the garden left out, not the observations refused

    # the device has the recognised activity, read from the state message like every entity
    config = json.loads(ha.wait_for(lambda m: m.topic == DISCOVERY and m.payload != b"").payload)
    assert discovery_problems(DISCOVERY, config) == []
    assert {"recognised", "question"} <= set(config["components"])
    state = json.loads(ha.wait_for(lambda m: m.topic == STATE and json.loads(m.payload)["recognised"]).payload)
    value, attributes = entity_states(config, state)["recognised"]
    assert value == state["recognised"]["activity"] and attributes is not None
    assert attributes["probability"] == state["recognised"]["probability"] and attributes["recognised_steps"] >= 1
