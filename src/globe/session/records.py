"""What a household session takes in and gives out: an observation, where it lands, the decision
and what an observation settles (:mod:`globe.session.session`)."""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass
from typing import Literal, Mapping, Sequence

from globe.inference.fetch_policy import FetchCandidate, FetchReport
from globe.reasoning.choice import ObjectChoice
from globe.session.sensing import Question, SensorEvent

NewActivities = Literal["refuse", "learn"]


def instant(time: dt.datetime) -> dt.datetime:
    """The UTC instant of ``time`` (naive = UTC, for library callers without a zone)."""
    return time.astimezone(dt.timezone.utc) if time.tzinfo else time.replace(tzinfo=dt.timezone.utc)


@dataclass(frozen=True, slots=True)
class Observation:
    time: dt.datetime  # in the household's zone (aware), or its wall time (naive)
    activity: str | None  # None: unknown at this step
    locations: Mapping[str, str]  # object -> location (may be partial: the others keep their last place)
    sensors: Sequence[SensorEvent] = ()  # sensor activations reported with it (a household with sensors)


@dataclass(frozen=True, slots=True)
class Placement:
    """Where an observation lands: its day, its step on the clock, and whether it opens a new step."""

    day: str
    step: int
    new_step: bool


@dataclass(frozen=True, slots=True)
class Decision:
    """What the session says after the last observed step: the next activity, the object likely
    needed, and what to fetch now (most likely useful first)."""

    status: str  # "learning" until a first day is learned, then "ready"
    days_learned: int
    day: str
    step: int  # the step predicted: the one after the last observed step
    activity: str | None
    activity_probability: float
    choice: ObjectChoice | None
    fetches: tuple[FetchCandidate, ...]
    candidates: tuple[FetchCandidate, ...] = ()  # every candidate fetch (for the evaluation's cost curve)
    left_alone: frozenset[str] = frozenset()  # objects no fetch could touch (in use, just put back)
    recognised: tuple[str, float] | None = None  # the activity under way recognised (its step had no label)
    labelled_steps: int = 0  # today's steps with a label (answers included)
    recognised_steps: int = 0  # today's steps whose activity was recognised from the sensors (no label)
    question: Question | None = None  # "what are you doing?" at the last observed step


@dataclass(frozen=True, slots=True)
class Settled:
    """What one observation settles (:meth:`HouseholdSession.settle`), for the day under way
    before it (``day``): the step it closes, whether its one-step prediction was right and the
    label it had, the fetches of the day when it starts a new one, and the one-step prediction of
    the step it opens (step, activity, probability); beside the scored prediction, whether the two
    rules a model must beat were right at the same step (``baselines``: persistence, hour + activity)."""

    day: str | None
    scored: tuple[int, bool] | None = None
    observed: tuple[int, str] | None = None
    fetches: FetchReport | None = None
    opened: tuple[int, str, float] | None = None
    baselines: tuple[bool, bool] | None = None
