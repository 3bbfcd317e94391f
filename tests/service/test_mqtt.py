"""Home Assistant over MQTT, end to end: a real ``globe serve`` with an ``[mqtt]`` section and a
real Mosquitto broker on a loopback port, with a test client in Home Assistant's place (it reads
the discovery and state messages, and publishes what ``mqtt_statestream`` would)."""

from __future__ import annotations

import datetime as dt
import json
import time

import httpx
import pytest

from tests.service.conftest import upload
from tests.service.ha_discovery_schema import discovery_problems, entity_states
from tests.service.mosquitto import Listener, Mosquitto, mqtt_config
from tests.simulated import clock_home

pytestmark = pytest.mark.service

HOME = "home"
DISCOVERY = f"homeassistant/device/globe_{HOME}/config"
STATE = f"globe/{HOME}/state"
ACTIVITY_TOPIC = "homeassistant/input_select/activity/state"
KETTLE_TOPIC = "homeassistant/binary_sensor/kettle_in_use/state"


STATESTREAM = f"""observe_interval_s = 1

[mqtt.households.{HOME}]
activity = "input_select.activity"
activities = {{ "Making tea" = "breakfast" }}

[mqtt.households.{HOME}.objects."binary_sensor.kettle_in_use"]
object = "kettle"
locations = {{ on = "in_use#4", off = "counter#3" }}
"""


@pytest.fixture()
def broker(tmp_path):
    b = Mosquitto(tmp_path)
    yield b
    b.kill()


@pytest.fixture()
def listeners():
    made: list[Listener] = []

    def make(port: int) -> Listener:
        made.append(Listener(port))
        return made[-1]

    yield make
    for listener in made:
        listener.close()


@pytest.fixture()
def globe(make_server, tmp_path):
    """``globe serve`` with ``config_text`` as its configuration file."""
    def make(config_text: str, start: bool = True):
        path = tmp_path / "globe.toml"
        path.write_text(config_text)
        srv = make_server(start=False)
        srv.args = ["--config", str(path)]
        return srv.start() if start else srv

    return make


def health(srv) -> dict:
    return httpx.get(srv.url + "/health").json()


def wait_health(srv, state: str, timeout: float = 10) -> dict:
    deadline = time.time() + timeout
    while (h := health(srv))["mqtt"]["state"] != state:
        assert time.time() < deadline, h
        time.sleep(0.1)
    return h


def household(srv):
    with srv.client() as c:
        upload(c, HOME, clock_home(days=6, test=1))


def exported(srv) -> list[dict]:
    r = httpx.get(f"{srv.url}/households/{HOME}/export", headers={"Authorization": f"Bearer {srv.admin}"})
    r.raise_for_status()
    return r.json()["observations"]


def test_a_household_is_a_home_assistant_device_whose_state_follows_each_observation(broker, globe, listeners):
    broker.start()
    srv = globe(mqtt_config(broker))
    household(srv)
    ha = listeners(broker.port)
    assert ha.wait_for(lambda m: m.topic == "globe/status").payload == b"online"
    config = ha.wait_for(lambda m: m.topic == DISCOVERY)
    later = listeners(broker.port)  # Home Assistant started later gets the device too: it is retained
    assert later.wait_for(lambda m: m.topic == DISCOVERY).retain and later.wait_for(lambda m: m.topic == STATE).retain
    payload = json.loads(config.payload)
    assert discovery_problems(config.topic, payload) == []
    first = json.loads(ha.wait_for(lambda m: m.topic == STATE).payload)
    assert first["status"] == "ready" and first["days_learned"] == 5

    # an observation over HTTP, as a robot sends it: its prediction reaches MQTT within a second
    seen = len(ha.messages)
    with srv.client() as c:
        start = time.perf_counter()
        ack = c.observe(HOME, dt.datetime.now(dt.timezone.utc), "breakfast", {"kettle": "in_use#4"})
        # the prediction is for the step after the observation's
        state = ha.wait_for(lambda m: m.topic == STATE and json.loads(m.payload)["step"] == ack["step"] + 1
                            and json.loads(m.payload)["day"] == ack["day"], after=seen)
        delay = state.at - start
        expected = c.prediction(HOME)
    print(f"\nMQTT delay: observation sent -> its prediction received on {STATE}: {delay * 1000:.1f} ms")
    assert delay < 1.0
    published = json.loads(state.payload)
    assert published == expected.model_dump()
    states = entity_states(payload, published)
    assert states["activity"][0] == str(expected.activity)
    assert states["fetch"][0] == ("ON" if expected.act else "OFF")
    assert states["days_learned"][0] == "5"

    # shadow mode switched off: the state says so at once, not at the next step; a fetch due now is
    # one event on the fetch topic (never retained)
    seen = len(ha.messages)
    with srv.client() as c:
        c.set_shadow(HOME, False)
        now = c.prediction(HOME)
    switched = ha.wait_for(lambda m: m.topic == STATE and json.loads(m.payload)["shadow"] is False, after=seen)
    assert json.loads(switched.payload)["act"] == now.act
    if now.act:
        event = ha.wait_for(lambda m: m.topic == f"globe/{HOME}/fetch", after=seen)
        assert not event.retain and json.loads(event.payload)["object"] == now.fetch_object

    # Home Assistant restarts and says so: the discovery is sent again
    seen = len(ha.messages)
    ha.publish("homeassistant/status", "online")
    again = ha.wait_for(lambda m: m.topic == DISCOVERY, after=seen)
    assert json.loads(again.payload) == payload
    assert health(srv)["mqtt"]["state"] == "connected" and health(srv)["status"] == "ok"

    # a household created over HTTP is a device at once, before any observation; a household
    # deleted has its device removed at once (an empty retained config), not when GLOBE reconnects
    seen = len(ha.messages)
    other = "homeassistant/device/globe_second/config"
    with srv.client() as c:
        upload(c, "second", clock_home(days=6, test=1))
        assert json.loads(ha.wait_for(lambda m: m.topic == other, after=seen).payload)
        seen = len(ha.messages)
        c.delete_household(HOME)
        c.delete_household("second")
    gone = {ha.wait_for(lambda m, t=t: m.topic == t, after=seen).payload for t in (DISCOVERY, other, STATE)}
    assert gone == {b""}

    # GLOBE killed: the broker publishes its last will, and Home Assistant marks the entities unavailable
    seen = len(ha.messages)
    srv.kill()
    assert ha.wait_for(lambda m: m.topic == "globe/status", after=seen).payload == b"offline"


def test_home_assistant_states_become_stored_observations_and_malformed_ones_are_counted(broker, globe, listeners):
    broker.start()
    srv = globe(mqtt_config(broker, STATESTREAM))
    household(srv)
    ha = listeners(broker.port)
    # what mqtt_statestream publishes (retained, the state as text)
    ha.publish(ACTIVITY_TOPIC, "Making tea", retain=True)
    ha.publish(KETTLE_TOPIC, "on", retain=True)
    deadline = time.time() + 5  # (a step may fall between the two messages: the kettle is then in a later one)
    while not (mine := [o for o in exported(srv) if (o["client_id"] or "").startswith("ha-")
                        and json.loads(o["locations"]) == {"kettle": "in_use#4"}]):
        assert time.time() < deadline, health(srv)
        time.sleep(0.2)
    assert mine[0]["activity"] == "breakfast"
    assert health(srv)["mqtt"]["observations"] >= 1
    # and each one published a new prediction for Home Assistant
    assert json.loads(ha.wait_for(lambda m: m.topic == STATE).payload)["status"] == "ready"

    for bad in (b"\xff\xfe not text", b"tea\x00time"):
        ha.publish(ACTIVITY_TOPIC, bad)
    ha.publish(KETTLE_TOPIC, "off")
    deadline = time.time() + 5
    while health(srv)["mqtt"]["malformed"] < 2 or json.loads(exported(srv)[-1]["locations"]) != {"kettle": "counter#3"}:
        assert time.time() < deadline, health(srv)
        time.sleep(0.2)
    stored = exported(srv)
    assert health(srv)["mqtt"]["malformed"] == 2
    assert {o["activity"] for o in stored} == {"breakfast"}  # nothing malformed stored: the last good state kept
    assert health(srv)["mqtt"]["rejected"] == 0

    # a restart loses nothing stored, and the retained states let it go on observing
    srv.stop()
    srv.start()
    assert [o["id"] for o in exported(srv)][: len(stored)] == [o["id"] for o in stored]
    deadline = time.time() + 5
    while len(exported(srv)) <= len(stored):
        assert time.time() < deadline, health(srv)
        time.sleep(0.2)
    ids = [o["client_id"] for o in exported(srv)]
    assert len(ids) == len(set(ids))


def test_a_broker_down_at_start_and_restarted_is_reconnected_and_served_again(broker, globe, listeners):
    srv = globe(mqtt_config(broker))  # the broker is not running yet: the service starts all the same
    household(srv)
    h = wait_health(srv, "disconnected")
    assert h["status"] == "degraded" and "cannot connect" in h["mqtt"]["last_error"]

    broker.start()
    wait_health(srv, "connected")
    ha = listeners(broker.port)
    ha.wait_for(lambda m: m.topic == DISCOVERY)

    broker.kill()
    h = wait_health(srv, "disconnected")
    assert "connection lost" in h["mqtt"]["last_error"]
    with srv.client() as c:  # the service goes on serving meanwhile
        c.observe(HOME, dt.datetime.now(dt.timezone.utc), "relax", {})

    broker.start()  # the same port; it remembers nothing (no persistence)
    started = time.perf_counter()
    h = wait_health(srv, "connected")
    print(f"\nreconnected {time.perf_counter() - started:.1f} s after the broker came back")
    ha = listeners(broker.port)
    assert ha.wait_for(lambda m: m.topic == "globe/status").payload == b"online"
    assert discovery_problems(DISCOVERY, json.loads(ha.wait_for(lambda m: m.topic == DISCOVERY).payload)) == []
    assert json.loads(ha.wait_for(lambda m: m.topic == STATE).payload)["status"] == "ready"
    assert health(srv)["status"] == "ok"


def test_a_wrong_place_in_the_mqtt_section_is_shown_and_leaves_the_rest_observed(broker, globe, listeners):
    """``off = "counter#99"`` names no place of the household's map: once the kettle reported
    off, every observation of the household was refused (activity and all) and /health said
    nothing; now that state is left out, the activity is still observed, and /health names it."""
    broker.start()
    srv = globe(mqtt_config(broker, STATESTREAM.replace('off = "counter#3"', 'off = "counter#99"')))
    household(srv)
    ha = listeners(broker.port)
    ha.publish(KETTLE_TOPIC, "off", retain=True)
    ha.publish(ACTIVITY_TOPIC, "Making tea", retain=True)
    deadline = time.time() + 5
    while not [o for o in exported(srv) if (o["client_id"] or "").startswith("ha-")]:
        assert time.time() < deadline, health(srv)
        time.sleep(0.2)
    stored = [o for o in exported(srv) if (o["client_id"] or "").startswith("ha-")]
    assert stored[0]["activity"] == "breakfast" and json.loads(stored[0]["locations"]) == {}
    problems = health(srv)["mqtt"]["problems"]
    assert problems == ["home: binary_sensor.kettle_in_use state 'off' puts kettle at 'counter#99', not a place of "
                        "the household's map"]
    assert health(srv)["mqtt"]["rejected"] == 0
