"""A real service process on a free loopback port, with its SQLite file under tmp, and tokens."""

from __future__ import annotations

import datetime as dt
import time

import httpx
import pytest

from globe.service.client import GlobeClient, ServiceError, household_payload
from tests.service_process import Server

# Replays of HOMER+ days run in the past, so the replay tests widen the clock-skew window.
REPLAY_ENV = {"GLOBE_SERVICE__MAX_CLOCK_SKEW": "P400D"}
BASE = dt.datetime.combine(dt.date.today() - dt.timedelta(days=90), dt.time())


def at(day: int, minute: int) -> dt.datetime:
    return BASE + dt.timedelta(days=day, minutes=minute)


@pytest.fixture()
def make_server(tmp_path):
    started = []

    def make(env=None, db=None, start=True, preexec_fn=None) -> Server:
        srv = Server(db or tmp_path / "globe.sqlite3", tmp_path / "server.log", env, preexec_fn)
        started.append(srv)
        return srv.start() if start else srv

    yield make
    for srv in started:
        srv.stop()


@pytest.fixture()
def server(make_server):
    """A service whose clock-skew window admits HOMER+ replays."""
    return make_server(REPLAY_ENV)


def fails(call, status: int, field: str | None = None) -> ServiceError:
    """The ServiceError ``call()`` raises, checked for its HTTP status (and the field it names)."""
    with pytest.raises(ServiceError) as err:
        call()
    assert err.value.status == status, err.value
    if field is not None:
        assert err.value.field == field, err.value
    return err.value


def upload(client: GlobeClient, name: str, household, timezone: str | None = "UTC", days: bool = True) -> dict:
    payload = household_payload(household)
    return client.create_household(name, payload["nodes"], payload["days"] if days else [], timezone=timezone)


def wait_for_llm(url: str, state: str = "ready", timeout: float = 180) -> None:
    """Until the service's /health says its LLM is in ``state`` (it loads in the background)."""
    deadline = time.time() + timeout
    while (now := httpx.get(url + "/health").json()["llm"]) != state:
        assert time.time() < deadline and not now.startswith("failed"), now
        time.sleep(0.2)
