"""Activity runs (maximal stretches of one activity) and the object sequences inside them."""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass, field
from typing import Sequence, TypeVar

from globe.data.records import Day, Household
from globe.sequences.movements import Alignment, MovementEvent, activity_step_for, extract_movements, moved_steps
from globe.sequences.packed_days import PackedDays

T = TypeVar("T")


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


def _per_run(activities: Sequence[str], by_step: dict[int, list[T]]) -> list[tuple[int, int, tuple[T, ...]]]:
    """(start, end, the items of steps start..end in step order) of every run of ``activities``."""
    keys, i, out = sorted(by_step), 0, []
    for s, e in run_bounds(activities):
        found: list[T] = []
        while i < len(keys) and keys[i] <= e:
            found.extend(by_step[keys[i]])
            i += 1
        out.append((s, e, tuple(found)))
    return out


def activity_runs(day: Day, objects: tuple[str, ...], alignment: Alignment = "previous") -> list[ActivityRun]:
    """Split a day into activity runs; each movement joins the run of its activity step."""
    by_step: dict[int, list[MovementEvent]] = defaultdict(list)
    for e in extract_movements(day, objects, alignment):
        by_step[e.activity_step].append(e)
    return [ActivityRun(day.name, day.activities[s], s, e, events)
            for s, e, events in _per_run(day.activities, by_step)]


Moves = list[tuple[int, tuple[str, ...]]]
"""A day's :func:`~globe.sequences.movements.moved_steps`: (step, objects that moved there)."""


def run_objects(day: Day, objects: tuple[str, ...], alignment: Alignment = "previous",
                moves: Moves | None = None) -> list[tuple[str, tuple[str, ...]]]:
    """(activity, objects moved) of each run of :func:`activity_runs`, without building the
    events: what the models count, a third of the time. ``moves``: the day's moved steps, when
    the caller has them."""
    acts = day.activities
    return [(acts[s], moved) for s, _, moved in _per_run(acts, _credited(day, objects, alignment, moves))]


def timed_run_objects(day: Day, objects: tuple[str, ...], alignment: Alignment = "previous",
                      moves: Moves | None = None) -> list[tuple[str, tuple[str, ...], tuple[int, ...]]]:
    """:func:`run_objects` with, per object, the clock minute of the step whose activity it is
    credited to: what an object model that reads the clock counts
    (:class:`~globe.models.baselines.HourActivityObjects`)."""
    acts, minutes = day.activities, day.minutes
    timed = {s: [(o, minutes[s]) for o in moved] for s, moved in _credited(day, objects, alignment, moves).items()}
    return [(acts[s], tuple(o for o, _ in used), tuple(m for _, m in used)) for s, _, used in _per_run(acts, timed)]


def object_runs(days: Sequence[Day], objects: tuple[str, ...], alignment: Alignment, timed: bool,
                moves: Sequence[Moves] | None = None) -> list[tuple]:
    """What an object model counts of ``days``: :func:`run_objects`, or :func:`timed_run_objects`
    for a model that reads the clock (``timed``); ``moves``: each day's moved steps, when known."""
    runs = timed_run_objects if timed else run_objects
    found = [None] * len(days) if moves is None else moves
    return [run for d, m in zip(days, found) for run in runs(d, objects, alignment, m)]


def _credited(day: Day, objects: tuple[str, ...], alignment: Alignment, moves: Moves | None) -> dict[int, list[str]]:
    """The objects used, by the step whose activity each is credited to."""
    by_step: dict[int, list[str]] = defaultdict(list)
    for t, moved in moved_steps(day, objects) if moves is None else moves:
        by_step[activity_step_for(day.activities, t, alignment, day.covering)].extend(moved)
    return by_step


@dataclass(frozen=True, slots=True)
class TrainingSequences:
    """What every model counts, from one walk over the training days: per-day activity sequences
    (the activity models) and each day's day of the week, (activity, objects) per run (the object
    model), each day's moved steps (the movement evidence) and the days packed, their rows of places
    numbered (the movement model)."""

    activities: list[tuple[str, ...]]
    runs: list[tuple[str, tuple[str, ...]]]
    moves: list[Moves] = field(default_factory=list, compare=False)
    packed: PackedDays = field(default_factory=PackedDays, compare=False)
    weekdays: list[int | None] = field(default_factory=list, compare=False)


def training_sequences(household: Household, days: Sequence[Day], alignment: Alignment) -> TrainingSequences:
    memo: dict = {}  # what moved, per pair of row objects (see moved_steps)
    moves = [moved_steps(d, household.objects, memo) for d in days]
    return TrainingSequences(
        [d.activities for d in days],
        [run for d, m in zip(days, moves) for run in run_objects(d, household.objects, alignment, m)],
        moves,
        PackedDays(days),
        [d.weekday for d in days],
    )
