"""The robot side: an adapter interface, and a simulated robot that replays HOMER+ days through
the service as if it were watching the person, fetching when told to act."""

from __future__ import annotations

import datetime as dt
import statistics
import time
from dataclasses import dataclass, field
from typing import Callable, Protocol, Sequence

from globe.data.records import Day, Household
from globe.evaluation.fetch import FetchReport
from globe.sequences.movements import extract_movements
from globe.service.client import GlobeClient, ServicePrediction, replay_dates


@dataclass(frozen=True, slots=True)
class FetchOutcome:
    obj: str
    to_location: str | None
    ok: bool
    message: str = ""


class RobotAdapter(Protocol):
    """What GLOBE needs from a robot: fetch an object to a place, and say how it went."""

    def fetch(self, obj: str, to_location: str | None) -> FetchOutcome: ...


class SimulatedRobot:
    """A robot that always succeeds and remembers what it fetched."""

    def __init__(self) -> None:
        self.fetched: list[tuple[str, str | None]] = []

    def fetch(self, obj: str, to_location: str | None) -> FetchOutcome:
        self.fetched.append((obj, to_location))
        return FetchOutcome(obj, to_location, True, "simulated")


@dataclass(slots=True)
class AssistanceReport(FetchReport):
    """The offline replay's fetch metrics (:class:`~globe.evaluation.fetch.FetchReport`), plus what
    only a run through the service has: days, LLM consultations and request latencies."""

    days: int = 0
    llm_consulted: int = 0
    latencies_s: list[float] = field(default_factory=list)

    def summary(self) -> dict:
        lat = sorted(self.latencies_s)
        return {
            "days": self.days, "steps": self.steps, "fetches": self.fetches,
            "precision": round(self.precision, 4), "recall": round(self.recall, 4),
            "median_lead_min": self.median_lead_min,
            "llm_consult_rate": round(self.llm_consulted / self.steps, 4) if self.steps else 0.0,
            "latency_median_ms": round(1000 * statistics.median(lat), 2) if lat else None,
            "latency_p95_ms": round(1000 * lat[int(0.95 * (len(lat) - 1))], 2) if lat else None,
        }


def _timestamp(date: dt.date, minute: int) -> dt.datetime:
    return dt.datetime.combine(date, dt.time()) + dt.timedelta(minutes=minute)


def replay_days(client: GlobeClient, household_name: str, household: Household, days: Sequence[Day],
                robot: RobotAdapter, *, base_date: dt.date | None = None, dates: Sequence[dt.date] | None = None,
                lead_window_steps: int = 6,
                progress: Callable[[int], None] | None = None,
                on_prediction: Callable[[int, int, ServicePrediction], None] | None = None) -> AssistanceReport:
    """Post every step of ``days`` as observations, ask for a prediction after each, and fetch
    when the service says to act. Returns the assistance metrics.

    A fetch at step t is *useful* if the object is used (moves) within the lead window, at one of
    the steps t+1..t+``lead_window_steps`` — the window the fetch policy decides for. A used
    object counts as *fetched in advance* if it was fetched within that window before it moved. ``on_prediction(day
    index, step, prediction)`` sees every prediction (made after observing that step).
    """
    report = AssistanceReport()
    # The days run in the past, the last one ending yesterday: the service needs a clock skew that
    # covers them (observations ahead of its clock would be held, not learned, until the clock came).
    # Day i runs on base_date + i, else on ``dates[i]``, else on :func:`replay_dates` (days named by
    # their date keep their weekday).
    if dates is None:
        dates = ([base_date + dt.timedelta(days=i) for i in range(len(days))] if base_date is not None
                 else replay_dates(days, dt.date.today() - dt.timedelta(days=2)))
    if len(dates) != len(days):
        raise ValueError(f"{len(dates)} dates for {len(days)} days")
    for d_index, day in enumerate(days):
        report.days += 1
        moves: dict[int, set[str]] = {}
        for ev in extract_movements(day, household.objects):
            moves.setdefault(ev.step, set()).add(ev.obj)
        pending: dict[str, int] = {}  # object -> step fetched (not yet used)
        for t in range(len(day)):
            for obj in moves.get(t, ()):  # the person used these objects at step t
                report.used_objects += 1
                fetched_at = pending.pop(obj, None)
                if fetched_at is not None and t - fetched_at <= lead_window_steps:
                    report.used_fetched_in_advance += 1
                    report.lead_minutes.append(day.minutes[t] - day.minutes[fetched_at])
            started = time.perf_counter()
            client.observe(household_name, _timestamp(dates[d_index], day.minutes[t]), day.activities[t],
                           dict(zip(household.objects, day.locations[t])))
            pred = client.prediction(household_name)
            report.latencies_s.append(time.perf_counter() - started)
            if on_prediction:
                on_prediction(d_index, t, pred)
            report.steps += 1
            report.llm_consulted += pred.llm_consulted
            fetch = pred.fetch_object
            if pred.act and fetch and fetch not in pending and t + 1 < len(day):
                outcome = robot.fetch(fetch, pred.fetch_to)
                if outcome.ok:
                    report.fetches += 1
                    pending[fetch] = t
                    if any(fetch in moves.get(u, ()) for u in range(t + 1, t + lead_window_steps + 1)):
                        report.useful_fetches += 1
        if progress:
            progress(1)
    return report
