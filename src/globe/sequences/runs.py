"""Activity runs (maximal stretches of one activity) and the object sequences inside them."""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass
from typing import Sequence

from globe.data.records import Day, Household
from globe.sequences.movements import Alignment, MovementEvent, extract_movements


@dataclass(frozen=True, slots=True)
class ActivityRun:
    """Steps ``start..end`` (inclusive) of one day spent in one activity, and what moved."""

    day: str
    activity: str
    start: int
    end: int
    events: tuple[MovementEvent, ...]

    @property
    def objects(self) -> tuple[str, ...]:
        return tuple(e.obj for e in self.events)


def run_bounds(activities: Sequence[str]) -> list[tuple[int, int]]:
    """(start, end) of every maximal run of equal activities."""
    bounds, start = [], 0
    for t in range(1, len(activities) + 1):
        if t == len(activities) or activities[t] != activities[start]:
            bounds.append((start, t - 1))
            start = t
    return bounds


def activity_runs(day: Day, objects: tuple[str, ...], alignment: Alignment = "previous") -> list[ActivityRun]:
    """Split a day into activity runs; each movement joins the run of its activity step."""
    by_step: dict[int, list[MovementEvent]] = defaultdict(list)
    for e in extract_movements(day, objects, alignment):
        by_step[e.activity_step].append(e)
    return [
        ActivityRun(day.name, day.activities[s], s, e,
                    tuple(ev for t in range(s, e + 1) for ev in by_step.get(t, ())))
        for s, e in run_bounds(day.activities)
    ]


@dataclass(frozen=True, slots=True)
class TrainingSequences:
    """What the models count: per-day activity sequences and (activity, objects) per run."""

    activities: list[tuple[str, ...]]
    runs: list[tuple[str, tuple[str, ...]]]


def training_sequences(household: Household, days: Sequence[Day], alignment: Alignment) -> TrainingSequences:
    return TrainingSequences(
        [d.activities for d in days],
        [(r.activity, r.objects) for d in days for r in activity_runs(d, household.objects, alignment)],
    )
