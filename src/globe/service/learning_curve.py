"""Learning curve through the real service: does the robot get better as it observes?

For each checkpoint k, a fresh household (a map and no training day: a cold start) is sent k
HOMER+ training days as observations, one step at a time with their times, over HTTP; a day is
learned when the next day's first observation arrives. The test days are then replayed the same
way, with a prediction asked after every step, and scored:

- *activity F1*: at step t = 1..T-1 of a test day, the activity the service predicted after
  observing step t-1, against the true a_t (weighted F1, as Table I); beside it, at the same
  steps, the two rules it must beat: *persistence F1* (a_{t-1} goes on) and *hour + activity F1*
  (the most frequent next activity given a_{t-1} and its hour, counted on the days the household
  had learned by then: :class:`~globe.models.baselines.HourActivityBaseline`);
- *object F1*: at every movement event (an object whose location at step t differs from t-1),
  the object the service named after observing step t-1 -- what a robot would fetch just before
  the person uses it -- against the object that moved (weighted F1);
- *fetch precision and recall*: :func:`globe.service.robot.replay_days` with a simulated robot,
  so the definitions are those of ``globe robot``.

No state leaks between checkpoints: each has its own household(s), deleted once scored. Test
days must not leak into each other either: at a checkpoint k <= ``isolate_up_to`` (10 by
default) every test day gets its own household, so each is scored after exactly k learned days.
Above it, where a few days more or less change little and the streaming would cost ten times
as much, the test days share one household and the service learns each as the next begins, as
a deployed robot would: test day j (from 0) is scored after k + j learned days.
"""

from __future__ import annotations

import datetime as dt
import time
from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING, Any, Callable, Mapping, Sequence

from globe.data.records import Day, Household
from globe.errors import DataError, GlobeError
from globe.evaluation.metrics import f1
from globe.models.baselines import HourActivityBaseline, mode
from globe.sequences.movements import extract_movements

if TYPE_CHECKING:  # the service extra is needed only to run the curve, not to import this module
    from globe.service.client import GlobeClient, ServicePrediction
    from globe.service.robot import AssistanceReport

CHECKPOINTS: tuple[int, ...] = (1, 2, 5, 10, 20, 40, 65)
ISOLATE_UP_TO = 10  # checkpoints up to this score each test day in its own household
NO_PREDICTION = "<none>"
COLUMNS = ("household", "days_learned", "activity_f1", "object_f1", "fetch_precision", "fetch_recall", "persistence_f1",
           "hour_activity_f1")


@dataclass(frozen=True, slots=True)
class CurvePoint:
    """The scores of one household after ``days_learned`` training days."""

    household: str
    days_learned: int
    activity_f1: float | None  # None: nothing to score (see globe.evaluation.metrics.f1)
    object_f1: float | None
    fetch_precision: float
    fetch_recall: float
    activity_steps: int  # predictions scored for the activity
    object_events: int  # movement events scored for the object
    fetches: int
    observations: int  # observations posted for this point (training and test days)
    elapsed_s: float
    persistence_f1: float | None = None  # the same steps, predicted by the activity before
    hour_activity_f1: float | None = None  # the same steps, by hour + activity counted on the days learned

    def as_row(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(slots=True)
class _Scores:
    """Pairs of (true, predicted) and the robot's fetch counts, summed over test days."""

    activity_true: list[str]
    activity_pred: list[str]
    object_true: list[str]
    object_pred: list[str]
    persistence_pred: list[str] = field(default_factory=list)  # beside activity_pred, step by step
    hour_activity_pred: list[str] = field(default_factory=list)
    fetches: int = 0
    useful_fetches: int = 0
    used_objects: int = 0
    used_fetched_in_advance: int = 0

    def add_report(self, report: AssistanceReport) -> None:
        self.fetches += report.fetches
        self.useful_fetches += report.useful_fetches
        self.used_objects += report.used_objects
        self.used_fetched_in_advance += report.used_fetched_in_advance


def required_clock_skew(household: Household, checkpoints: Sequence[int] = CHECKPOINTS) -> dt.timedelta:
    """How far back the service must accept times (``service.max_clock_skew``): the days of the
    largest checkpoint and every test day are replayed on the calendar days up to yesterday (on
    their own dates moved by whole weeks, for days named by their date: :func:`replay_dates`)."""
    from globe.evaluation.online import replay_dates

    days = [*household.train[: max(checkpoints, default=0)], *household.test]
    dates = replay_dates(days, dt.date(2000, 1, 1))
    span = (dates[-1] - dates[0]).days + 1 if dates else 0
    return dt.timedelta(days=max(span, max(checkpoints, default=0) + len(household.test)) + 2)


def _at(date: dt.date, minute: int) -> dt.datetime:
    """Wall time of ``minute`` after that date's midnight (1440 is the next midnight)."""
    return dt.datetime.combine(date, dt.time()) + dt.timedelta(minutes=minute)


def stream_days(client: GlobeClient, name: str, household: Household, days: Sequence[Day],
                dates: Sequence[dt.date]) -> int:
    """Post every step of ``days`` as observations, day i on ``dates[i]``; returns how many.

    Each step carries the true activity; the first step of a day every object's location (a new
    day starts from the map's start locations), later steps only the objects that moved (the
    others keep their last known place), as a robot reporting what it sees change. The last day
    stays open: it is learned when the next day begins."""
    posted = 0
    for date, day in zip(dates, days):
        previous: tuple[str, ...] | None = None
        for minute, activity, locations in zip(day.minutes, day.activities, day.locations):
            changed = {o: loc for j, (o, loc) in enumerate(zip(household.objects, locations))
                       if previous is None or previous[j] != loc}
            client.observe(name, _at(date, minute), activity, changed)
            previous = locations
            posted += 1
    return posted


def _score_replayed(household: Household, days: Sequence[Day], predictions: Mapping[tuple[int, int], ServicePrediction],
                    scores: _Scores, learned: Sequence[Day] = ()) -> None:
    """Add the activity and object pairs of replayed ``days``; ``predictions[(d, t)]`` is the one
    made after observing step t of day d. The baselines' predictions at the same steps: hour +
    activity counted on ``learned`` and the replayed days before (as the service learns them)."""
    missing = [(d, t) for d, day in enumerate(days) for t in range(len(day)) if (d, t) not in predictions]
    if missing:
        raise GlobeError(f"no prediction after step {missing[0][1]} of replayed day {missing[0][0]}")
    rule = HourActivityBaseline(1).fit(learned)
    for d, day in enumerate(days):
        for t in range(1, len(day)):
            before = day.activities[t - 1]
            scores.activity_true.append(day.activities[t])
            scores.activity_pred.append(predictions[(d, t - 1)].activity or NO_PREDICTION)
            scores.persistence_pred.append(before)
            scores.hour_activity_pred.append(mode(rule.proba(before, day.minutes[t - 1], 1)) or NO_PREDICTION)
        rule.partial_fit([day])
        for ev in extract_movements(day, household.objects):
            scores.object_true.append(ev.obj)
            scores.object_pred.append(predictions[(d, ev.step - 1)].object or NO_PREDICTION)


def _replay_and_score(client: GlobeClient, name: str, household: Household, days: Sequence[Day],
                      dates: Sequence[dt.date], scores: _Scores, min_lead_steps: int, window_steps: int,
                      learned: Sequence[Day] = ()) -> int:
    from globe.service.robot import SimulatedRobot, replay_days

    predictions: dict[tuple[int, int], ServicePrediction] = {}

    def keep(d: int, t: int, p: ServicePrediction) -> None:
        predictions[(d, t)] = p

    report = replay_days(client, name, household, days, SimulatedRobot(), dates=dates,
                         min_lead_steps=min_lead_steps, window_steps=window_steps, on_prediction=keep)
    _score_replayed(household, days, predictions, scores, learned)
    scores.add_report(report)
    return sum(len(d) for d in days)


def _fresh_household(client: GlobeClient, name: str, nodes: list[dict[str, Any]], timezone: str) -> None:
    """Create ``name`` with the map only (no training day), replacing a leftover of an earlier run."""
    from globe.service.client import ServiceError

    try:
        client.create_household(name, nodes=nodes, timezone=timezone)
    except ServiceError as err:
        if err.status != 409:
            raise
        client.delete_household(name)
        client.create_household(name, nodes=nodes, timezone=timezone)
    client.set_shadow(name, False)  # the simulated robot acts when told to: what the curve measures


def curve_point(client: GlobeClient, household: Household, days_learned: int, *, name_prefix: str | None = None,
                isolate_test_days: bool = True, timezone: str = "UTC", last_date: dt.date | None = None,
                min_lead_steps: int = 1, window_steps: int = 6) -> CurvePoint:
    """Score the test days after ``days_learned`` training days streamed into fresh household(s):
    one per test day if ``isolate_test_days``, else one shared by the test days in order."""
    from globe.evaluation.online import replay_dates
    from globe.service.client import household_payload

    if not 1 <= days_learned <= len(household.train):
        raise DataError(f"checkpoint {days_learned} is outside 1..{len(household.train)} (the training days of "
                        f"household {household.name})", field="checkpoints")
    if not household.test:
        raise DataError(f"household {household.name} has no test day to score", field="test")
    started = time.perf_counter()
    nodes = household_payload(household)["nodes"]
    prefix = name_prefix or f"curve-{household.name}"
    last_date = last_date or dt.datetime.now(dt.timezone.utc).date() - dt.timedelta(days=1)
    train = household.train[:days_learned]
    scores = _Scores([], [], [], [])
    posted = 0
    groups = [[d] for d in household.test] if isolate_test_days else [list(household.test)]
    for g, test_days in enumerate(groups):
        name = f"{prefix}-k{days_learned}" + (f"-t{g}" if isolate_test_days else "")
        dates = replay_dates([*train, *test_days], last_date)
        _fresh_household(client, name, nodes, timezone)
        try:
            posted += stream_days(client, name, household, train, dates[:days_learned])
            posted += _replay_and_score(client, name, household, test_days, dates[days_learned:], scores,
                                        min_lead_steps, window_steps, train)
        finally:
            client.delete_household(name)
    return CurvePoint(
        household=household.name, days_learned=days_learned,
        activity_f1=f1(scores.activity_true, scores.activity_pred),
        object_f1=f1(scores.object_true, scores.object_pred),
        fetch_precision=scores.useful_fetches / scores.fetches if scores.fetches else 0.0,
        fetch_recall=scores.used_fetched_in_advance / scores.used_objects if scores.used_objects else 0.0,
        activity_steps=len(scores.activity_true), object_events=len(scores.object_true), fetches=scores.fetches,
        observations=posted, elapsed_s=time.perf_counter() - started,
        persistence_f1=f1(scores.activity_true, scores.persistence_pred),
        hour_activity_f1=f1(scores.activity_true, scores.hour_activity_pred),
    )


def learning_curve(client: GlobeClient, household: Household, checkpoints: Sequence[int] = CHECKPOINTS, *,
                   isolate_up_to: int = ISOLATE_UP_TO, timezone: str = "UTC", name_prefix: str | None = None,
                   progress: Callable[[CurvePoint], None] | None = None) -> list[CurvePoint]:
    """One :class:`CurvePoint` per checkpoint (k learned training days), in the given order; test
    days get a household each at checkpoints up to ``isolate_up_to``."""
    bad = [k for k in checkpoints if not 1 <= k <= len(household.train)]
    if bad:
        raise DataError(f"checkpoint {bad[0]} is outside 1..{len(household.train)} (the training days of household "
                        f"{household.name})", field="checkpoints")
    points = []
    for k in checkpoints:
        point = curve_point(client, household, k, name_prefix=name_prefix, isolate_test_days=k <= isolate_up_to,
                            timezone=timezone)
        points.append(point)
        if progress:
            progress(point)
    return points


def mean_rows(points: Sequence[CurvePoint]) -> list[dict[str, Any]]:
    """``household = "mean"`` rows: each metric averaged over the households at each checkpoint."""
    rows = []
    for k in sorted({p.days_learned for p in points}):
        at_k = [p for p in points if p.days_learned == k]
        row: dict[str, Any] = {"household": "mean", "days_learned": k}
        for col in COLUMNS[2:]:
            values = [v for v in (getattr(p, col) for p in at_k) if v is not None]
            row[col] = sum(values) / len(values) if values else None
        rows.append(row)
    return rows


def table_rows(points: Sequence[CurvePoint]) -> list[dict[str, Any]]:
    """The rows of ``learning_curve.csv``: per household and checkpoint, then the means."""
    rows = [{c: p.as_row()[c] for c in COLUMNS} for p in points]
    return rows + mean_rows(points)
