"""Activity runs (maximal stretches of one activity) and the object sequences inside them."""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass, field
from typing import Sequence

from globe.data.records import Day, Household
from globe.sequences.movements import Alignment, MovementEvent, activity_step_for, extract_movements, moved_steps


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


Moves = list[tuple[int, tuple[str, ...]]]
"""A day's :func:`~globe.sequences.movements.moved_steps`: (step, objects that moved there)."""


def run_objects(day: Day, objects: tuple[str, ...], alignment: Alignment = "previous",
                moves: Moves | None = None) -> list[tuple[str, tuple[str, ...]]]:
    """(activity, objects moved) of each run of :func:`activity_runs`, without building the
    events: what the models count, a third of the time. ``moves``: the day's moved steps, when
    the caller has them."""
    acts = day.activities
    by_step: dict[int, tuple[str, ...]] = {}
    for t, moved in moved_steps(day, objects) if moves is None else moves:
        s = activity_step_for(acts, t, alignment)
        by_step[s] = by_step[s] + moved if s in by_step else moved
    keys, i, out = sorted(by_step), 0, []
    for s, e in run_bounds(acts):
        found: tuple[str, ...] = ()
        while i < len(keys) and keys[i] <= e:
            found += by_step[keys[i]]
            i += 1
        out.append((acts[s], found))
    return out


@dataclass(frozen=True, slots=True)
class TrainingSequences:
    """What the models count: per-day activity sequences and (activity, objects) per run, and
    each day's moved steps (the movement evidence counts them too)."""

    activities: list[tuple[str, ...]]
    runs: list[tuple[str, tuple[str, ...]]]
    moves: list[Moves] = field(default_factory=list, compare=False)


def training_sequences(household: Household, days: Sequence[Day], alignment: Alignment) -> TrainingSequences:
    memo: dict = {}  # what moved, per pair of row objects (see moved_steps)
    moves = [moved_steps(d, household.objects, memo) for d in days]
    return TrainingSequences(
        [d.activities for d in days],
        [run for d, m in zip(days, moves) for run in run_objects(d, household.objects, alignment, m)],
        moves,
    )
