"""The robot side: an adapter interface, and a simulated robot that replays days through the
service as if it were watching the person, fetching what it is told to."""

from __future__ import annotations

import datetime as dt
import statistics
import time
from dataclasses import dataclass, field
from typing import Callable, Mapping, Protocol, Sequence

from globe.data.records import Day, Household
from globe.evaluation.online import day_observations, replay_dates
from globe.inference.fetch_policy import FetchReport, follow_fetches
from globe.sequences.movements import moved_objects
from globe.service.client import GlobeClient, ServicePrediction


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
    """The fetches the robot made, scored by the one rule of fetches
    (:func:`~globe.inference.fetch_policy.follow_fetches`), plus what only a run through the service
    has: days, LLM consultations and request latencies."""

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


def replay_days(client: GlobeClient, household_name: str, household: Household, days: Sequence[Day],
                robot: RobotAdapter, *, min_lead_steps: int = 1, window_steps: int = 6,
                dates: Sequence[dt.date] | None = None, progress: Callable[[int], None] | None = None,
                on_prediction: Callable[[int, int, ServicePrediction], None] | None = None) -> AssistanceReport:
    """Post every step of ``days`` as observations (day i on ``dates[i]``, by default the days up
    to the day before yesterday: :func:`~globe.evaluation.online.replay_dates`), ask for a prediction
    after each, and have ``robot`` fetch what the service says to (each of its ``fetches`` when it
    acts). The robot's fetches are scored against what then happened in each day with the policy's
    lead window (``min_lead_steps``..``window_steps`` steps). ``on_prediction(day index, row,
    prediction)`` sees every prediction."""
    report = AssistanceReport()
    if dates is None:
        dates = replay_dates(days, dt.date.today() - dt.timedelta(days=2))
    if len(dates) != len(days):
        raise ValueError(f"{len(dates)} dates for {len(days)} days")
    for d_index, (day, date) in enumerate(zip(days, dates)):
        report.days += 1
        fetched: dict[int, list[str]] = {}
        for t, obs in day_observations(household, day, date):
            started = time.perf_counter()
            client.observe(household_name, obs.time, obs.activity, obs.locations)
            pred = client.prediction(household_name)
            report.latencies_s.append(time.perf_counter() - started)
            if on_prediction:
                on_prediction(d_index, t, pred)
            report.llm_consulted += pred.llm_consulted
            for f in pred.fetches if pred.act else ():
                if robot.fetch(f.object, f.to).ok:
                    fetched.setdefault(t, []).append(f.object)
        follow_fetches(moved_objects(day, household.objects), day.minutes, _made(fetched), len(day), min_lead_steps,
                       window_steps, report)
        if progress:
            progress(1)
    return report


def _made(fetched: dict[int, list[str]]) -> Callable[[int, Mapping[str, int]], Sequence[str]]:
    """The fetches a robot made, as the decisions :func:`follow_fetches` scores."""
    return lambda t, _: fetched.get(t, ())
