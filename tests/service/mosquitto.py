"""A real Mosquitto broker (Debian's ``mosquitto`` package) on a free loopback port, and an MQTT
client that records what it receives: what the Home Assistant tests run against.

``system_binary`` is the rule for tests that need a program of the system: skipped with the
package to install on a developer's machine, failed under ``CI=true`` (CI installs it)."""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import paho.mqtt.client as paho
import pytest

from tests.helpers import absent, free_port


def system_binary(path: str, package: str) -> str:
    """``path`` if it is an executable program; else the test is skipped saying what to install
    (failed when ``CI=true``, where its absence is a broken set-up, not a choice)."""
    found = path if os.access(path, os.X_OK) else shutil.which(os.path.basename(path))
    if found:
        return found
    absent(f"{path} is missing: install Debian's {package} package (sudo apt-get install {package})")


class Mosquitto:
    """``mosquitto -c <conf>`` listening on 127.0.0.1 only, anonymous, nothing persisted (a restart
    forgets retained messages, so what arrives after one was published again)."""

    def __init__(self, folder: Path, port: int | None = None) -> None:
        self.binary = system_binary("/usr/sbin/mosquitto", "mosquitto")
        self.port = port or free_port()
        self.folder = folder
        self.proc: subprocess.Popen | None = None

    @property
    def url(self) -> str:
        return f"mqtt://127.0.0.1:{self.port}"

    def start(self) -> "Mosquitto":
        conf = self.folder / "mosquitto.conf"
        conf.write_text(f"listener {self.port} 127.0.0.1\nallow_anonymous true\npersistence false\n")
        with open(self.folder / "mosquitto.log", "a") as log:
            self.proc = subprocess.Popen([self.binary, "-c", str(conf)], stdout=log, stderr=subprocess.STDOUT)
        deadline = time.time() + 10
        while time.time() < deadline:
            if self.proc.poll() is not None:
                pytest.fail(f"mosquitto exited: {(self.folder / 'mosquitto.log').read_text()[-2000:]}")
            try:
                socket.create_connection(("127.0.0.1", self.port), timeout=0.2).close()
                return self
            except OSError:
                time.sleep(0.05)
        pytest.fail("mosquitto did not listen within 10 s")

    def kill(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(timeout=10)


@dataclass(frozen=True)
class Received:
    topic: str
    payload: bytes
    retain: bool
    at: float  # time.perf_counter() when it arrived


class Listener:
    """An MQTT client that subscribes to ``topics`` and keeps every message it receives."""

    def __init__(self, port: int, topics: tuple[str, ...] = ("#",)) -> None:
        self.messages: list[Received] = []
        self._cond = threading.Condition()
        self._subscribed = threading.Event()
        self.client = paho.Client(paho.CallbackAPIVersion.VERSION2)
        self.client.on_connect = lambda c, u, f, rc, p: c.subscribe([(t, 1) for t in topics])
        self.client.on_subscribe = lambda *a: self._subscribed.set()
        self.client.on_message = self._message
        self.client.connect("127.0.0.1", port)
        self.client.loop_start()
        assert self._subscribed.wait(5), "the test's MQTT client did not subscribe"

    def _message(self, client, userdata, msg) -> None:
        with self._cond:
            self.messages.append(Received(msg.topic, msg.payload, bool(msg.retain), time.perf_counter()))
            self._cond.notify_all()

    def wait_for(self, match: Callable[[Received], bool], timeout: float = 5.0, after: int = 0) -> Received:
        """The first message from index ``after`` on that ``match`` accepts (fails after ``timeout``)."""
        deadline = time.time() + timeout
        with self._cond:
            while True:
                for m in self.messages[after:]:
                    if match(m):
                        return m
                left = deadline - time.time()
                if left <= 0:
                    topics = sorted({m.topic for m in self.messages})
                    pytest.fail(f"no matching MQTT message within {timeout} s; topics seen: {topics}")
                self._cond.wait(left)

    def publish(self, topic: str, payload: bytes | str, retain: bool = False) -> None:
        self.client.publish(topic, payload, qos=1, retain=retain).wait_for_publish(timeout=5)

    def close(self) -> None:
        self.client.disconnect()
        self.client.loop_stop()


def mqtt_config(broker: Mosquitto, extra: str = "") -> str:
    """GLOBE's ``[mqtt]`` section for ``broker`` (quick reconnects for tests), then ``extra``."""
    return f"""
[mqtt]
enabled = true
broker = "{broker.url}"
client_id = "globe-test"
reconnect_min_s = 1
reconnect_max_s = 2
{extra}
"""
