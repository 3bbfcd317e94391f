"""The ``[mqtt]`` section: Home Assistant over MQTT (see docs/home-assistant.md).

Everything the bridge needs from it is checked before the service starts: the broker's address
and port when the configuration is read, the CA file and the password file it will read by
:meth:`MqttConfig.check_files` (``globe serve`` asks), so a mistake is one line, not a traceback
from inside the running app.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated
from urllib.parse import urlsplit

from pydantic import Field, SecretStr, field_validator, model_validator

from globe.config import _Section
from globe.errors import ConfigError

_TOPIC = r"^[^#+\x00]+$"  # an MQTT topic name: no wildcard, no NUL (checked further by MqttConfig)
_ENTITY_ID = r"^[a-z0-9_]+\.[a-z0-9_]+$"  # a Home Assistant entity id: domain.object_id


class MqttObject(_Section):
    """One Home Assistant entity that tells where an object is (a binary sensor, a device tracker)."""

    object: str = Field(..., min_length=1, description="the GLOBE object (a movable node's class) the entity follows")
    locations: dict[str, str] = Field(
        ..., min_length=1, description="entity state -> node label where the object then is, e.g. on = 'in_use#4'; "
        "other states (unknown, unavailable) leave the object where it was last seen",
    )


class MqttHousehold(_Section):
    """The Home Assistant entities one household learns from (through ``mqtt_statestream``)."""

    activity: str | None = Field(
        None, pattern=_ENTITY_ID, description="entity whose state is the person's activity, e.g. input_select.activity "
        "(optional: a household with sensors has its activity recognised from them where none is given)",
    )
    activities: dict[str, str] = Field(
        {}, description="activity entity state -> GLOBE activity label (states not listed are used as they are)",
    )
    objects: dict[Annotated[str, Field(pattern=_ENTITY_ID)], MqttObject] = Field(
        {}, description="entity id -> the object it follows and where each of its states puts it",
    )
    sensors: dict[Annotated[str, Field(pattern=_ENTITY_ID)], Annotated[str, Field(min_length=1)]] = Field(
        {}, description="on/off entity (a binary_sensor) -> the household's sensor it is (a list of entity ids: "
        "each is its own sensor's name, as in a Home Assistant import's sensors.csv); its on..off spells become "
        "the household's sensor activations",
    )

    @field_validator("sensors", mode="before")
    @classmethod
    def _sensor_list(cls, value: object) -> object:
        """A list of entity ids names sensors by their entity ids (what the Home Assistant import keeps)."""
        if isinstance(value, (list, tuple)):
            return {entity: entity for entity in value}
        return value


class MqttConfig(_Section):
    """Home Assistant over MQTT: GLOBE's households as discovered devices, and observations learned
    from the states Home Assistant's ``mqtt_statestream`` publishes (see docs/home-assistant.md)."""

    enabled: bool = Field(False, description="connect to the broker when the service starts")
    broker: str = Field(
        "mqtt://127.0.0.1:1883", pattern=r"^mqtts?://[^/?#@\s]+$",
        description="broker URL: mqtt://host:port, or mqtts://host:port for TLS (port 1883 / 8883 when left out)",
    )
    username: str | None = Field(None, description="broker user name (None: connect anonymously)")
    password: SecretStr | None = Field(
        None,
        description="broker password (prefer password_file or GLOBE_MQTT__PASSWORD to a file in clear; "
        "never written out: results' config.json shows it masked)",
    )
    password_file: Path | None = Field(None, description="file whose first line is the broker password")
    ca_file: Path | None = Field(
        None, description="CA certificates (PEM) the mqtts:// broker is checked with; None = the system's"
    )
    client_id: str = Field("globe", min_length=1, max_length=64, description="MQTT client id (unique on the broker)")
    keepalive_s: int = Field(60, ge=5, le=3600, description="seconds between keep-alive pings")
    reconnect_min_s: int = Field(1, ge=1, le=3600, description="first wait before reconnecting to a lost broker")
    reconnect_max_s: int = Field(60, ge=1, le=3600, description="longest wait between reconnections (the wait doubles)")
    discovery_prefix: str = Field("homeassistant", pattern=_TOPIC, description="Home Assistant's MQTT discovery prefix")
    status_topic: str = Field(
        "homeassistant/status", pattern=_TOPIC,
        description="where Home Assistant says 'online' (discovery is sent again) or 'offline' (no observation "
                    "meanwhile)",
    )
    statestream_topic: str = Field(
        "homeassistant", pattern=_TOPIC, description="base_topic of Home Assistant's mqtt_statestream integration",
    )
    topic_prefix: str = Field(
        "globe", pattern=_TOPIC,
        description="GLOBE's own topics: <prefix>/status (online/offline) and <prefix>/<household>/state",
    )
    observe_interval_s: int | None = Field(
        None, ge=1, le=86400, description="seconds between observations made from Home Assistant's states; None = "
        "one per step of the household (observations inside one step update that step)",
    )
    households: dict[str, MqttHousehold] = Field({}, description="household name -> the entities it learns from")

    @field_validator("discovery_prefix", "status_topic", "statestream_topic", "topic_prefix")
    @classmethod
    def _no_empty_level(cls, value: str) -> str:
        if value.startswith("/") or value.endswith("/") or "//" in value:
            raise ValueError("an MQTT topic has no empty level ('/' at an end, or doubled)")
        return value

    @field_validator("broker")
    @classmethod
    def _broker(cls, value: str) -> str:
        broker_address(value)
        return value

    @model_validator(mode="after")
    def _secrets(self) -> "MqttConfig":
        if self.password is not None and self.password_file is not None:
            raise ValueError("give password or password_file, not both")
        if self.reconnect_max_s < self.reconnect_min_s:
            raise ValueError(f"reconnect_max_s {self.reconnect_max_s} is below reconnect_min_s {self.reconnect_min_s}")
        return self

    def check_files(self) -> None:
        """Where the bridge will run (``enabled``): the CA file and the password file it reads are
        there and readable (a ConfigError naming the field; ``globe serve`` asks before it starts)."""
        if not self.enabled:
            return
        if self.ca_file is not None and broker_address(self.broker)[2] and not Path(self.ca_file).is_file():
            raise ConfigError(f"mqtt.ca_file {self.ca_file}: no such file")
        self.password_text()

    def password_text(self) -> str | None:
        """The broker password: the first line of ``password_file``, else ``password``."""
        if self.password_file is None:
            return None if self.password is None else self.password.get_secret_value()
        try:
            lines = Path(self.password_file).read_text(encoding="utf-8").splitlines()
        except (OSError, UnicodeDecodeError) as err:
            raise ConfigError(f"mqtt.password_file {self.password_file}: cannot read it ({err})") from None
        return lines[0] if lines else ""


def broker_address(url: str) -> tuple[str, int, bool]:
    """``mqtt[s]://host[:port]`` -> (host, port, tls); a ValueError naming what is wrong."""
    parts = urlsplit(url)
    try:
        port = parts.port
    except ValueError:
        raise ValueError(f"broker {url!r}: the port is not a number from 1 to 65535") from None
    if parts.scheme not in ("mqtt", "mqtts") or not parts.hostname:
        raise ValueError(f"broker {url!r}: expected mqtt://host:port or mqtts://host:port")
    tls = parts.scheme == "mqtts"
    if port == 0:
        raise ValueError(f"broker {url!r}: the port is not a number from 1 to 65535")
    return parts.hostname, port or (8883 if tls else 1883), tls
