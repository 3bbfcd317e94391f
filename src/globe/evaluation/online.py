"""The served robot offline: days replayed through a household's session, as the service runs it.

Each step of a day is sent to a :class:`~globe.session.HouseholdSession` as the robot would send
it (an observation at the step's wall-clock time, with the step's activity unless it is hidden,
and every object's place), and the session's decision after it is kept: the next activity, the
object, the fetches. The scores are the service's online scores, by the session's own rule
(:meth:`~globe.session.HouseholdSession.settle`): the one-step activity accuracy of the steps
closed, with persistence's and hour + activity's over the same steps, and each finished day's
fetch precision and recall. A replay may start at any hour and
skip steps (nobody watching), so what a robot starting at 18:00 gets is scored as it gets it.

The models learn each finished day when the session does (``learn=True``, as a deployed robot);
the tables of :mod:`globe.evaluation.fetch` replay test days with ``learn=False`` (models fitted
on the training days only, as every other table).
"""

from __future__ import annotations

import bisect
import datetime as dt
from dataclasses import dataclass, field
from typing import Callable, Iterator, Sequence

from globe.data.records import Day, Household
from globe.data.sensors import SensorData
from globe.inference.fetch_policy import FetchReport
from globe.session import Decision, HouseholdSession, Observation
from globe.session.records import Settled
from globe.session.sensing import SensorEvent


@dataclass(frozen=True, slots=True)
class StepRecord:
    """One replayed step: the day replayed, its row, and the session's decision after it."""

    day: str
    row: int
    decision: Decision


@dataclass(slots=True)
class OnlineScores:
    """The service's online scores, summed over days: one-step predictions scored and right,
    beside persistence's and hour + activity's right at the same steps (the rules the model must
    beat, :meth:`~globe.session.HouseholdSession.settle`), and the fetches of the days closed."""

    predictions: int = 0
    correct: int = 0
    fetch: FetchReport = field(default_factory=FetchReport)
    baseline_predictions: int = 0  # the scored steps the baselines were scored at too
    persistence_correct: int = 0
    hour_activity_correct: int = 0

    @property
    def accuracy(self) -> float | None:
        return self.correct / self.predictions if self.predictions else None

    @property
    def persistence_accuracy(self) -> float | None:
        """Persistence's one-step accuracy over the same scored steps."""
        return self.persistence_correct / self.baseline_predictions if self.baseline_predictions else None

    @property
    def hour_activity_accuracy(self) -> float | None:
        """Hour + current activity's one-step accuracy over the same scored steps."""
        return self.hour_activity_correct / self.baseline_predictions if self.baseline_predictions else None

    def add(self, settled: Settled) -> None:
        if settled.scored is not None:
            self.predictions += 1
            self.correct += settled.scored[1]
            if settled.baselines is not None:
                self.baseline_predictions += 1
                self.persistence_correct += settled.baselines[0]
                self.hour_activity_correct += settled.baselines[1]
        if settled.fetches is not None:
            add_report(self.fetch, settled.fetches)


def add_report(total: FetchReport, part: FetchReport) -> FetchReport:
    """``part``'s counts added to ``total``."""
    total.steps += part.steps
    total.fetches += part.fetches
    total.useful_fetches += part.useful_fetches
    total.used_objects += part.used_objects
    total.used_fetched_in_advance += part.used_fetched_in_advance
    total.lead_minutes.extend(part.lead_minutes)
    return total


def replay_dates(days: Sequence[Day], last: dt.date) -> list[dt.date]:
    """The calendar dates a replay puts ``days`` on, the last on or before ``last``: consecutive
    dates, unless every day is named by its date (in order): then their own dates moved by whole
    weeks, so a model that knows the day of the week sees each replayed day as it was."""
    named = [when for when in (d.calendar_date for d in days) if when is not None]
    if not named or len(named) < len(days) or any(b <= a for a, b in zip(named, named[1:])):
        return [last - dt.timedelta(days=len(days) - 1 - i) for i in range(len(days))]
    shift = dt.timedelta(days=(last - named[-1]).days // 7 * 7)
    return [when + shift for when in named]


def day_observations(household: Household, day: Day, date: dt.date, *, rows: Sequence[int] | None = None,
                     visible: Callable[[int], bool] | None = None,
                     sensors: SensorData | None = None) -> Iterator[tuple[int, Observation]]:
    """(row, observation) for each of ``rows`` of ``day`` (default: every row), at its minute on
    ``date`` (wall time), with its activity unless ``visible(row)`` says it is hidden, and every
    object's place; with ``sensors`` (the home's), also the activations that begin in the row
    (:func:`row_events`)."""
    midnight = dt.datetime.combine(date, dt.time())
    events = row_events(sensors, day, date) if sensors is not None else None
    for t in range(len(day)) if rows is None else rows:
        label = day.seen[t] if visible is None or visible(t) else None  # as GLOBE saw it (recognised, if so)
        yield t, Observation(midnight + dt.timedelta(minutes=day.minutes[t]), label,
                             dict(zip(household.objects, day.locations[t])), events[t] if events else ())


def row_events(sensors: SensorData, day: Day, date: dt.date) -> list[tuple[SensorEvent, ...]]:
    """Per row of ``day``, the sensor activations recorded for it that begin in the row (before
    the next row's minute; the first row also takes those before it), as wall times on ``date``:
    what a home's sensors report with each step's observation."""
    out: list[list[SensorEvent]] = [[] for _ in range(len(day))]
    found = sensors.of(day.name)
    if found is None or not len(day):
        return [tuple(e) for e in out]
    midnight = dt.datetime.combine(date, dt.time())
    bounds = [60.0 * m for m in day.minutes[1:]]
    for i, start, end in zip(found.sensor.tolist(), found.start.tolist(), found.end.tolist()):
        row = bisect.bisect_right(bounds, start)
        out[row].append(SensorEvent(sensors.sensors[i].name, midnight + dt.timedelta(seconds=start),
                                    midnight + dt.timedelta(seconds=end)))
    return [tuple(e) for e in out]


def replay(session: HouseholdSession, observations: Sequence[tuple[str, int, Observation]],
           scores: OnlineScores | None = None) -> tuple[list[StepRecord], OnlineScores]:
    """Send ``observations`` ((day name, row, observation), in time order) to ``session`` as the
    service does, asking for its decision after each; returns the records and the online scores
    settled (a day still under way at the end is settled by :func:`close_day`)."""
    scores = OnlineScores() if scores is None else scores
    records: list[StepRecord] = []
    for name, row, obs in observations:
        settled = session.settle(session.placement(obs.time))
        session.observe(obs)
        session.remember(settled)
        scores.add(settled)
        records.append(StepRecord(name, row, session.decide()))
    return records, scores


def close_day(session: HouseholdSession, scores: OnlineScores) -> OnlineScores:
    """Add the day under way's fetches to ``scores`` (as the next day's first observation would)."""
    if session.day is not None:
        add_report(scores.fetch, session.fetch_report())
    return scores


def replay_days(session: HouseholdSession, household: Household, days: Sequence[Day], dates: Sequence[dt.date], *,
                first_row: int = 0, skip: range = range(0)) -> tuple[list[StepRecord], OnlineScores]:
    """Every day of ``days`` on ``dates`` from row ``first_row``, leaving out the rows in ``skip``
    (nobody watching), replayed through ``session``; the last day is closed at its end."""
    if len(dates) != len(days):
        raise ValueError(f"{len(dates)} dates for {len(days)} days")
    stream = [(day.name, t, obs) for day, date in zip(days, dates)
              for t, obs in day_observations(household, day, date,
                                             rows=[t for t in range(first_row, len(day)) if t not in skip])]
    records, scores = replay(session, stream)
    return records, close_day(session, scores)
