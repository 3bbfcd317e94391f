"""What the dashboard tests share: the app in-process over a real database (lifespan run), a
household with HOMER+ days observed step by step with a prediction after each, and a login."""

from __future__ import annotations

import datetime as dt
import re

from fastapi.testclient import TestClient

from globe.config import GlobeConfig
from globe.service.app import create_app
from globe.service.auth import create_token
from globe.service.client import household_payload

BASE = dt.datetime.combine(dt.date.today() - dt.timedelta(days=30), dt.time())


def config(db) -> GlobeConfig:
    return GlobeConfig().with_overrides({"service.database": str(db), "llm.backend": "none", "service.preload": False,
                                         "service.max_clock_skew": "P400D", "selection.deploy": "ngram"})


def app_client(db, token: str | None = None) -> TestClient:
    """The app over ``db`` (use as a context manager: the lifespan opens the store)."""
    headers = {"Authorization": f"Bearer {token}"} if token else {}
    return TestClient(create_app(config(db)), base_url="http://127.0.0.1", headers=headers, follow_redirects=False)


def create(client: TestClient, name: str, household) -> None:
    payload = household_payload(household)
    r = client.post("/households", json={"name": name, "timezone": "UTC", **payload})
    assert r.status_code == 201, r.text


def observe_days(client: TestClient, name: str, household, days, first_index: int = 0, steps: int | None = None,
                 predict: bool = True) -> list[dict]:
    """Post each step of ``days`` (day i on BASE + first_index + i), asking for a prediction after each;
    returns the predictions."""
    out = []
    for i, day in enumerate(days):
        for t in range(len(day) if steps is None or i < len(days) - 1 else steps):
            time = BASE + dt.timedelta(days=first_index + i, minutes=day.minutes[t])
            r = client.post(f"/households/{name}/observations", json={
                "time": time.isoformat(), "activity": day.activities[t],
                "locations": dict(zip(household.objects, day.locations[t]))})
            assert r.status_code == 201, r.text
            if predict:
                out.append(client.get(f"/households/{name}/prediction").json())
    return out


CSRF = re.compile(r'name="csrf" value="([^"]+)"')


def csrf_of(html: str) -> str:
    found = CSRF.search(html)
    assert found, html[:2000]
    return found.group(1)


def login(client: TestClient, token: str):
    """Log in through the form; returns the POST's response (a 303 to the dashboard when it worked)."""
    form = client.get("/dashboard/login")
    assert form.status_code == 200
    return client.post("/dashboard/login", data={"csrf": csrf_of(form.text), "token": token},
                       headers={"Origin": "http://127.0.0.1"})


def tokens(db, *households: str) -> tuple[str, dict[str, str]]:
    return create_token(db, admin=True), {h: create_token(db, household=h) for h in households}
