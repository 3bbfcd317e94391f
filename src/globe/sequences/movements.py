"""Object movement events: an object is used at step t when its location differs from t-1.

Every relocation counts (HOMER+'s protocol, as SLaTe-PRO), except one out of a place of class
``in_use`` (:func:`~globe.data.records.is_use_place`): the importers and Home Assistant put an
object there while its sensor is on, and its return home is no use a person would name. A home
with no such place (HOMER+) is scored as published."""

from __future__ import annotations

from dataclasses import dataclass
from itertools import compress
from operator import ne
from typing import Literal, Sequence

from globe.data.records import Day, is_use_place

Alignment = Literal["previous", "current", "hybrid", "most"]
ALIGNMENTS: tuple[Alignment, ...] = ("previous", "current", "hybrid", "most")
IDLE = "idle"


@dataclass(frozen=True, slots=True)
class MovementEvent:
    """One object changing location, attached to the activity it is credited to."""

    day: str
    step: int  # row t at which the new location is first observed
    minute: int
    obj: str
    source: str
    target: str
    activity_step: int  # the step whose activity this movement belongs to
    activity: str


def activity_step_for(activities: tuple[str, ...], step: int, alignment: Alignment,
                      covering: tuple[str, ...] | None = None) -> int:
    """Which step's activity a movement observed at ``step`` belongs to.

    ``previous`` (default, as SLaTe-PRO): the activity in progress when the ten-minute interval
    began (t-1). ``current``: the activity at t. ``hybrid``: t-1 unless that is ``idle``.
    ``most``: the activity covering most of step t (``covering``, written by the importers, whose
    rows mark a use inside their own step): t + 1 when the activity that began during step t
    covers most of it, else t (``current``, also for a day without ``covering``).
    """
    if alignment == "previous":
        return step - 1
    if alignment == "current":
        return step
    if alignment == "hybrid":
        return step if activities[step - 1] == IDLE else step - 1
    if alignment == "most":
        later = covering is not None and step + 1 < len(activities) and covering[step] != activities[step] \
            and covering[step] == activities[step + 1]
        return step + 1 if later else step
    raise ValueError(f"unknown alignment {alignment!r}; expected one of {', '.join(ALIGNMENTS)}")


def used_between(objects: Sequence[str], before: Sequence[str], after: Sequence[str]) -> tuple[str, ...]:
    """The objects (in column order) whose place in row ``after`` differs from row ``before``,
    less those put back from a use place (module doc): what was used between two steps."""
    changed = list(map(ne, before, after))
    moved = tuple(compress(objects, changed))
    if moved and any(map(is_use_place, compress(before, changed))):  # only what moved is looked at
        return tuple(o for o, b, c in zip(objects, before, changed) if c and not is_use_place(b))
    return moved


def moved_steps(day: Day, objects: Sequence[str],
                memo: dict[tuple[int, int], tuple] | None = None) -> list[tuple[int, tuple[str, ...]]]:
    """(t, :func:`used_between` rows t-1 and t) for every step t at which something was used.
    Most steps move nothing, and the rows of such steps are often the same tuple (the parser
    shares them), so those cost one identity check. ``memo``, shared by
    calls over the days of one household, keeps the answer per pair of row objects (routines
    repeat the same changes day after day); it holds the rows, so their ids stay theirs."""
    rows = day.locations
    memo = {} if memo is None else memo
    out = []
    for t in range(1, len(rows)):
        before, after = rows[t - 1], rows[t]
        if before is after or before == after:
            continue
        key = (id(before), id(after))
        hit = memo.get(key)
        if hit is None:
            hit = memo[key] = (before, after, used_between(objects, before, after))
        if hit[2]:
            out.append((t, hit[2]))
    return out


def extract_movements(day: Day, objects: tuple[str, ...], alignment: Alignment = "previous") -> list[MovementEvent]:
    """Every movement of the day (returns from a use place left out, see the module doc), by step,
    then by column order (deterministic)."""
    events: list[MovementEvent] = []
    rows = day.locations
    for t in range(1, len(day)):
        before, after = rows[t - 1], rows[t]
        if before is after or before == after:  # most steps: nothing moved
            continue
        s = activity_step_for(day.activities, t, alignment, day.covering)
        name, minute, activity = day.name, day.minutes[t], day.activities[s]
        events.extend(MovementEvent(name, t, minute, obj, b, a, s, activity)
                      for obj, b, a in zip(objects, before, after) if b != a and not is_use_place(b))
    return events


def moved_objects(day: Day, objects: Sequence[str]) -> list[frozenset[str]]:
    """Per step, the objects whose location differs from the step before (empty at step 0): what
    moved, for everything that asks (the filter's evidence, the fetch scores, the replays)."""
    out: list[frozenset[str]] = [frozenset()] * len(day)
    for t, moved in moved_steps(day, objects):
        out[t] = frozenset(moved)
    return out
