"""The Python client a robot program imports to talk to the GLOBE service (httpx)."""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass
from typing import Any, Mapping

from globe.errors import GlobeError, MissingExtraError


class ServiceError(GlobeError):
    """The service answered with an error status; ``field`` names the bad input if it said."""

    def __init__(self, status: int, detail: str, field: str | None = None) -> None:
        super().__init__(f"HTTP {status}: {detail}")
        self.status, self.detail, self.field = status, detail, field


@dataclass(frozen=True, slots=True)
class ServicePrediction:
    activity: str | None
    activity_probability: float
    object: str | None
    object_probability: float
    llm_consulted: bool
    act: bool
    fetch_to: str | None
    latency_s: float


class GlobeClient:
    def __init__(self, base_url: str, *, timeout_s: float = 30.0) -> None:
        try:
            import httpx
        except ImportError as err:
            raise MissingExtraError("httpx", "service") from err
        self._http = httpx.Client(base_url=base_url.rstrip("/"), timeout=timeout_s)

    def _call(self, method: str, path: str, **kw: Any) -> Any:
        response = self._http.request(method, path, **kw)
        if response.status_code >= 400:
            try:
                body = response.json()
            except ValueError:
                body = {"detail": response.text}
            raise ServiceError(response.status_code, str(body.get("detail")), body.get("field"))
        return response.json()

    def health(self) -> dict:
        return self._call("GET", "/health")

    def create_household(self, name: str, source: str) -> dict:
        return self._call("POST", "/households", json={"name": name, "source": source})

    def observe(self, household: str, time: dt.datetime, activity: str, locations: Mapping[str, str]) -> dict:
        return self._call("POST", f"/households/{household}/observations",
                          json={"time": time.isoformat(), "activity": activity, "locations": dict(locations)})

    def prediction(self, household: str) -> ServicePrediction:
        response = self._http.get(f"/households/{household}/prediction")
        if response.status_code >= 400:
            body = response.json()
            raise ServiceError(response.status_code, str(body.get("detail")), body.get("field"))
        p = response.json()
        return ServicePrediction(p["activity"], p["activity_probability"], p["object"], p["object_probability"],
                                 p["llm_consulted"], p["act"], p["fetch_to"], response.elapsed.total_seconds())

    def feedback(self, household: str, obj: str, accepted: bool) -> dict:
        return self._call("POST", f"/households/{household}/feedback", json={"object": obj, "accepted": accepted})

    def stats(self, household: str) -> dict:
        return self._call("GET", f"/households/{household}/stats")

    def export_model(self, household: str) -> dict:
        return self._call("GET", f"/households/{household}/model")

    def close(self) -> None:
        self._http.close()

    def __enter__(self) -> "GlobeClient":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
