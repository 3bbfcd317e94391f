"""The Python client a robot program imports to talk to the GLOBE service (httpx).

Every call sends the bearer token; any non-2xx answer raises :class:`ServiceError` with the
status, the detail and the field the service named (also when the body is not JSON, e.g. from
a reverse proxy).
"""

from __future__ import annotations

import datetime as dt
from typing import Any, Mapping, Sequence

from globe.data.csv_logs import format_day
from globe.data.records import Household
from globe.errors import DataError, GlobeError, MissingExtraError
from globe.service.schemas import Prediction


class ServiceError(GlobeError):
    """The service answered with an error status; ``field`` names the bad input if it said."""

    def __init__(self, status: int, detail: str, field: str | None = None) -> None:
        super().__init__(f"HTTP {status}: {detail}" + (f" (field {field})" if field else ""))
        self.status, self.detail, self.field = status, detail, field


class ServiceUnreachableError(GlobeError):
    """No answer at all: the service is not running there, or the network is down."""


ServicePrediction = Prediction  # the service's own schema (kept as a name for robot code written against it)


def household_payload(household: Household) -> dict[str, Any]:
    """``nodes`` and ``days`` (the training days as day-file text) of a loaded household."""
    nodes = [{"node": n.node, "class": n.cls, "category": n.category, "movable": n.movable,
              "start_location": n.start_location} for n in household.nodes]
    out: dict[str, Any] = {"nodes": nodes, "days": [format_day(d, household.objects) for d in household.train]}
    dates = [d.calendar_date for d in household.train]
    if dates and None not in dates:  # days named by their date (imported homes): their weekdays count
        out["dates"] = [when.isoformat() for when in dates if when is not None]
    return out


class GlobeClient:
    def __init__(self, base_url: str, *, token: str | None = None, timeout_s: float = 30.0) -> None:
        try:
            import httpx
        except ImportError as err:
            raise MissingExtraError("httpx", "service") from err
        if not base_url.startswith(("http://", "https://")):
            raise DataError(f"service URL {base_url!r} must start with http:// or https:// "
                            "(e.g. http://127.0.0.1:8765)", field="url")
        headers = {"Authorization": f"Bearer {token}"} if token else {}
        self.base_url = base_url.rstrip("/")
        self._http = httpx.Client(base_url=self.base_url, timeout=timeout_s, headers=headers)

    def _request(self, method: str, path: str, **kw: Any):
        import httpx

        try:
            response = self._http.request(method, path, **kw)
        except httpx.TransportError as err:
            raise ServiceUnreachableError(f"no answer from the service at {self.base_url} ({type(err).__name__}: "
                                          f"{err or 'no detail'}); is globe serve running there?") from err
        if not 200 <= response.status_code < 300:
            try:
                body = response.json()
            except ValueError:
                body = None
            if not isinstance(body, dict):
                body = {"detail": response.text[:500] or response.reason_phrase}
            raise ServiceError(response.status_code, str(body.get("detail")), body.get("field"))
        return response

    def _call(self, method: str, path: str, **kw: Any) -> Any:
        response = self._request(method, path, **kw)
        return response.json() if response.content else None

    def health(self) -> dict:
        return self._call("GET", "/health")

    def households(self) -> list[str]:
        return self._call("GET", "/households")

    def create_household(self, name: str, nodes: Sequence[Mapping[str, Any]], days: Sequence[str] = (),
                         timezone: str | None = None, dates: Sequence[str] | None = None, *, method: str | None = None,
                         new_activities: str | None = None) -> dict:
        """Create a household from its map and, optionally, training days (admin); ``method``: how
        its models are chosen (see ``POST /households``)."""
        body: dict[str, Any] = {"name": name, "nodes": list(nodes), "days": list(days)}
        optional = {"timezone": timezone, "dates": None if dates is None else list(dates), "method": method,
                    "new_activities": new_activities}
        body |= {k: v for k, v in optional.items() if v}
        return self._call("POST", "/households", json=body)

    def set_shadow(self, name: str, shadow: bool) -> dict:
        """Shadow mode on (predict and score, never act) or off (admin)."""
        return self._call("PUT", f"/households/{name}/shadow", json={"shadow": shadow})

    def delete_household(self, name: str) -> None:
        self._call("DELETE", f"/households/{name}")

    def observe(self, household: str, time: dt.datetime, activity: str | None, locations: Mapping[str, str],
                id: str | None = None) -> dict:
        body: dict[str, Any] = {"time": time.isoformat(), "activity": activity, "locations": dict(locations)}
        if id is not None:
            body["id"] = id
        return self._call("POST", f"/households/{household}/observations", json=body)

    def prediction(self, household: str) -> Prediction:
        """The service's prediction after the last observation (``last_latency_s``: its round trip)."""
        response = self._request("GET", f"/households/{household}/prediction")
        self.last_latency_s = response.elapsed.total_seconds()
        return Prediction.model_validate(response.json())

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
