"""What GLOBE publishes for Home Assistant and how it reads Home Assistant's states, without a
broker: the discovery payload against the documented schema, the entities' states rendered from
a prediction, statestream messages (good, unknown, malformed), binary sensors' on/off turned into
sensor activations, questions and answers' topics, and the [mqtt] section's checks."""

from __future__ import annotations

import json

import pytest

from globe.config import GlobeConfig, MqttConfig, load_config
from globe.errors import ConfigError
from globe.service.mqtt import payloads
from globe.service.mqtt.bridge import broker_address
from globe.service.mqtt.statestream import MalformedMessage, StateBook, decode_state
from globe.service.schemas import Prediction, QuestionOut, RecognisedOut
from tests.service.ha_discovery_schema import discovery_problems, entity_states

MAPPED = MqttConfig.model_validate({
    "households": {"home": {"activity": "input_select.activity", "activities": {"Making tea": "breakfast"},
                            "objects": {"binary_sensor.kettle_in_use": {"object": "kettle",
                                                                        "locations": {"on": "in_use#4",
                                                                                      "off": "counter#3"}}}}},
})


def prediction(**kw) -> Prediction:
    base = dict(status="ready", days_learned=12, day="2026-11-24", step=30, activity="breakfast",
                activity_probability=0.8125, object="kettle", object_probability=0.5, llm_consulted=False,
                llm_fallback=None, act=True, fetch_object="kettle", fetch_to="in_use#4", fetch_probability=0.7)
    return Prediction(**{**base, **kw})


@pytest.mark.parametrize("name", ["A", "home-1", "flat.2"])
def test_the_discovery_payload_follows_home_assistants_schema(name):
    config = MqttConfig()
    topic = payloads.discovery_topic(config, name)
    payload = json.loads(payloads.encode(payloads.discovery_payload(config, name)))
    assert discovery_problems(topic, payload) == []
    assert topic.startswith("homeassistant/device/globe_")
    assert payload["availability"] == [{"topic": "globe/status", "payload_available": "online",
                                        "payload_not_available": "offline"}]
    assert {c["state_topic"] for c in payload["components"].values()} == {f"globe/{name}/state", f"globe/{name}/fetch"}
    assert {c["platform"] for c in payload["components"].values()} == {"sensor", "binary_sensor", "event"}
    assert payload["components"]["fetch_request"]["event_types"] == ["fetch"]


def test_the_checker_finds_what_home_assistant_would_refuse():
    payload = payloads.discovery_payload(MqttConfig(), "A")
    broken = json.loads(json.dumps(payload))
    del broken["origin"]
    broken["components"]["fetch"]["platfrom"] = broken["components"]["fetch"].pop("platform")
    broken["components"]["status"]["unique_id"] = broken["components"]["activity"]["unique_id"]
    broken["components"]["fetch_request"]["event_types"] = []
    problems = discovery_problems("homeassistant/device/a.b/config", broken)
    assert len(problems) == 5, problems


def test_dotted_household_names_get_distinct_valid_ids():
    ids = {payloads.object_id(n) for n in ("a.b", "a_b", "a-b", "a.b.")}
    assert len(ids) == 4
    assert all(i.replace("_", "").replace("-", "").isalnum() for i in ids)


def test_the_entities_follow_a_prediction():
    payload = payloads.discovery_payload(MqttConfig(), "A")
    states = entity_states(payload, json.loads(payloads.state_payload(prediction())))
    assert states["activity"] == ("breakfast", {"probability": 0.8125, "day": "2026-11-24", "step": 30})
    assert states["activity_probability"][0] == "81.2"
    assert states["fetch"] == ("ON", {"object": "kettle", "to": "in_use#4", "probability": 0.7})
    assert states["fetch_to"][0] == "in_use#4"
    assert states["status"][0] == "ready" and states["days_learned"][0] == "12"
    idle = entity_states(payload, json.loads(payloads.state_payload(
        prediction(status="learning", act=False, fetch_object=None, fetch_to=None, fetch_probability=None))))
    assert idle["fetch"][0] == "OFF"
    assert idle["fetch_object"][0] == idle["fetch_probability"][0] == "None"  # Home Assistant's unknown
    assert idle["status"][0] in payload["components"]["status"]["options"]


def test_each_fetch_due_is_one_event_and_none_in_shadow_mode_or_while_learning():
    two = prediction(fetches=[{"object": "kettle", "to": "in_use#4", "probability": 0.7},
                              {"object": "cup", "to": None, "probability": 0.6}])
    events = [json.loads(e) for e in payloads.fetch_events(two)]
    assert events == [{"event_type": "fetch", "object": "kettle", "to": "in_use#4", "probability": 0.7,
                       "day": "2026-11-24", "step": 30},
                      {"event_type": "fetch", "object": "cup", "to": None, "probability": 0.6,
                       "day": "2026-11-24", "step": 30}]
    assert payloads.fetch_events(prediction(act=False, shadow=True, fetches=two.fetches)) == []


def test_statestream_states_make_a_snapshot():
    book = StateBook(MAPPED)
    assert book.topics() == ["homeassistant/binary_sensor/kettle_in_use/state",
                             "homeassistant/input_select/activity/state"]
    assert not book.snapshot("home").seen
    assert book.receive("homeassistant/input_select/activity/state", b"Making tea") == 1
    assert book.receive("homeassistant/binary_sensor/kettle_in_use/state", b'"on"') == 1  # older, JSON-quoted states
    snap = book.snapshot("home")
    assert (snap.seen, snap.activity, snap.locations) == (True, "breakfast", {"kettle": "in_use#4"})
    book.receive("homeassistant/binary_sensor/kettle_in_use/state", b"unavailable")  # the kettle stays put
    book.receive("homeassistant/input_select/activity/state", b"  dinner ")
    assert (book.snapshot("home").activity, book.snapshot("home").locations) == ("dinner", {"kettle": "in_use#4"})
    book.receive("homeassistant/input_select/activity/state", b"unknown")
    assert book.snapshot("home").activity is None
    assert book.receive("homeassistant/light/other/state", b"on") == 0


@pytest.mark.parametrize("payload", [b"\xff\xfe", b"tea\x00time", b"x" * 2000, b'"unterminated\\"',
                                     "a\u202eb".encode()])
def test_malformed_states_are_refused_and_change_nothing(payload):
    book = StateBook(MAPPED)
    book.receive("homeassistant/input_select/activity/state", b"relax")
    with pytest.raises(MalformedMessage):
        book.receive("homeassistant/input_select/activity/state", payload)
    assert book.snapshot("home").activity == "relax"


def test_decode_state_limits_the_length():
    assert decode_state(b"x" * 10, 10) == "x" * 10
    with pytest.raises(MalformedMessage, match="longer than 10"):
        decode_state(b"x" * 11, 10)


def test_mqtt_is_off_by_default_and_its_section_is_checked(tmp_path):
    assert GlobeConfig().mqtt.enabled is False
    bad = {"broker": "http://broker", "discovery_prefix": "home/+", "status_topic": "ha/status/",
           "households": {"A": {"activity": "Activity"}}}
    for key, value in bad.items():
        with pytest.raises(ConfigError, match=f"mqtt.{key}"):
            load_config(overrides={f"mqtt.{key}": value}, environ={})
    with pytest.raises(ConfigError, match="password or password_file"):
        load_config(overrides={"mqtt.password": "x", "mqtt.password_file": str(tmp_path / "p")}, environ={})
    assert broker_address("mqtts://broker.lan") == ("broker.lan", 8883, True)
    assert broker_address("mqtt://[::1]:1884") == ("::1", 1884, False)
    for broker in ("mqtt://broker:99999", "mqtt://broker:0"):  # found only when the bridge started, once
        with pytest.raises(ConfigError, match="mqtt.broker: .*the port is not a number from 1 to 65535"):
            load_config(overrides={"mqtt.broker": broker}, environ={})
    tls = {"mqtt.enabled": True, "mqtt.broker": "mqtts://broker.lan", "mqtt.ca_file": str(tmp_path / "no-ca.pem")}
    with pytest.raises(ConfigError, match="mqtt.ca_file .*no-ca.pem: no such file"):
        load_config(overrides=tls, environ={}).mqtt.check_files()
    load_config(overrides=tls | {"mqtt.enabled": False}, environ={}).mqtt.check_files()  # not used: fine
    with pytest.raises(ConfigError, match="mqtt.password_file .*: cannot read it"):
        load_config(overrides={"mqtt.enabled": True, "mqtt.username": "u", "mqtt.password_file": str(tmp_path)},
                    environ={}).mqtt.check_files()
    assert "secret" not in repr(MqttConfig(password="secret"))
    configured = load_config(overrides={"mqtt.password": "secret"}, environ={})
    assert "secret" not in json.dumps(configured.model_dump(mode="json"))  # what results' config.json holds
    assert configured.with_overrides({"gate.threshold": 0.3}).mqtt.password.get_secret_value() == "secret"


def test_the_home_assistant_page_shows_valid_yaml_toml_and_globe_commands():
    """docs/home-assistant.md: each yaml block parses, each toml block is a valid GLOBE
    configuration, each bash line is a globe command, and the entity ids it names are those the
    discovery makes (Home Assistant joins the device's and the entity's names)."""
    import re
    import tomllib
    from pathlib import Path

    import yaml

    text = (Path(__file__).parents[2] / "docs" / "home-assistant.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```(\w*)\n(.*?)```", text, flags=re.S)
    assert {lang for lang, _ in blocks} == {"yaml", "toml", "bash"}
    for lang, body in blocks:
        if lang == "yaml":
            assert isinstance(yaml.safe_load(body), dict)
        elif lang == "toml":
            config = GlobeConfig.model_validate(tomllib.loads(body))
            assert config.mqtt.enabled and config.mqtt.households
        else:
            assert all(line.startswith("globe ") for line in body.strip().splitlines())
    payload = payloads.discovery_payload(MqttConfig(), "home", sensors=True)  # every entity, a home with sensors
    slug = lambda s: re.sub(r"[^a-z0-9]+", "_", s.lower()).strip("_")  # noqa: E731
    made = {f"{c['platform']}.{slug(payload['device']['name'] + ' ' + c['name'])}"
            for c in payload["components"].values()}
    named = set(re.findall(r"`((?:binary_sensor|sensor|event)\.globe_home_\w+)`", text))
    assert named == made


SENSED = MqttConfig.model_validate({"households": {
    "home": {"sensors": {"binary_sensor.kitchen_motion": "M_kitchen", "binary_sensor.fridge_door": "C_fridge"}},
    "flat": {"sensors": ["binary_sensor.hall_motion"]},  # entity ids as the household's sensor names
}})


def topic(entity: str) -> str:
    return f"homeassistant/{entity.replace('.', '/')}/state"


def test_binary_sensors_on_and_off_become_activations_taken_once():
    book = StateBook(SENSED)
    assert topic("binary_sensor.hall_motion") in book.topics()
    assert book.receive(topic("binary_sensor.kitchen_motion"), b"on", now=100.0) == 1
    assert book.snapshot("home").seen and book.snapshot("home").activity is None
    book.receive(topic("binary_sensor.kitchen_motion"), b"on", now=101.0)  # no change
    book.receive(topic("binary_sensor.kitchen_motion"), b"off", now=130.0)
    book.receive(topic("binary_sensor.fridge_door"), b"off", now=140.0)  # off never seen on: a firing
    book.receive(topic("binary_sensor.fridge_door"), b"unavailable", now=141.0)  # no state of a sensor
    taken = book.take_activations("home")
    assert [(a.sensor, a.start, a.end) for a in taken] == [("M_kitchen", 100.0, 130.0), ("C_fridge", 140.0, 140.0)]
    assert book.take_activations("home") == [] and book.take_activations("flat") == []
    # a switch-on observed before its switch-off: a firing at once, then the whole activation
    book.receive(topic("binary_sensor.kitchen_motion"), b"on", now=200.0)
    assert [(a.start, a.end) for a in book.take_activations("home")] == [(200.0, 200.0)]
    book.receive(topic("binary_sensor.kitchen_motion"), b"off", now=260.0)
    assert [(a.start, a.end) for a in book.take_activations("home")] == [(200.0, 260.0)]
    # a retained state (sent on subscribing, of unknown age) says where the sensor stands, no change
    book.receive(topic("binary_sensor.hall_motion"), b"on", now=300.0, retained=True)
    assert book.take_activations("flat") == []
    book.receive(topic("binary_sensor.hall_motion"), b"off", now=360.0)
    assert [(a.sensor, a.start, a.end) for a in book.take_activations("flat")] == [
        ("binary_sensor.hall_motion", 300.0, 360.0)]
    book.receive(topic("binary_sensor.hall_motion"), b"off", now=400.0, retained=True)
    assert book.take_activations("flat") == []


def test_pending_activations_are_bounded():
    from globe.service.mqtt.statestream import MAX_PENDING_EVENTS

    book = StateBook(SENSED)
    for i in range(MAX_PENDING_EVENTS + 5):
        book.receive(topic("binary_sensor.fridge_door"), b"off", now=float(i))
    kept = book.take_activations("home")
    assert len(kept) == MAX_PENDING_EVENTS and kept[0].start == 5.0  # the oldest went first


def test_a_household_with_sensors_has_the_recognised_activity_and_a_question_event():
    config = MqttConfig()
    payload = json.loads(payloads.encode(payloads.discovery_payload(config, "home", sensors=True)))
    assert discovery_problems(payloads.discovery_topic(config, "home"), payload) == []
    assert set(payload["components"]) == set(payloads.COMPONENTS) | set(payloads.SENSOR_COMPONENTS)
    assert payload["components"]["question"]["state_topic"] == "globe/home/question"
    asked = prediction(recognised=RecognisedOut(activity="breakfast", probability=0.625), labelled_steps=3,
                       recognised_steps=40, question=QuestionOut(day="2026-11-24", step=29, time="10:50", activities=[
                           RecognisedOut(activity="breakfast", probability=0.625),
                           RecognisedOut(activity="lunch", probability=0.25)]))
    state = json.loads(payloads.state_payload(asked))
    value, attributes = entity_states(payload, state)["recognised"]
    assert value == "breakfast" and attributes == {"probability": 0.625, "labelled_steps": 3, "recognised_steps": 40}
    assert entity_states(payload, json.loads(payloads.state_payload(prediction())))["recognised"][0] == "None"
    event = json.loads(payloads.question_event(config, "home", asked) or "")
    assert event == {"event_type": "question", "household": "home", "activities": ["breakfast", "lunch"],
                     "probabilities": [0.625, 0.25], "day": "2026-11-24", "step": 29, "time": "10:50",
                     "answer_topic": "globe/home/answer"}
    assert payloads.question_event(config, "home", prediction()) is None
    assert payloads.answer_household(config, "globe/flat.2/answer") == "flat.2"
    assert payloads.answer_household(config, "globe/home/state") is None
    assert payloads.answer_household(config, "globe//answer") is None


def test_a_missing_broker_program_skips_here_and_fails_in_ci(monkeypatch, tmp_path):
    from tests.service.mosquitto import system_binary

    missing = str(tmp_path / "no-such-mosquitto")
    monkeypatch.delenv("CI", raising=False)
    with pytest.raises(pytest.skip.Exception, match="apt-get install mosquitto"):
        system_binary(missing, "mosquitto")
    monkeypatch.setenv("CI", "true")
    with pytest.raises(pytest.fail.Exception, match="apt-get install mosquitto"):
        system_binary(missing, "mosquitto")
