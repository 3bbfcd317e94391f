"""The wall-clock grid of a household's days: when its day begins, how long a step lasts, how many
steps a day has.

A household's models count positions: step t of a day is ``day start + t * step`` on the clock,
whatever moment the robot started watching. So the grid is the household's own, read from the
days it was built from (HOMER+: 06:00, 10 minutes, 109 rows to 24:00), never the service's: an
observation at 18:00 is step 72 of a 10-minute day, not the day's first step. A service setting
that disagrees with a household's days is an error when the household is built.
"""

from __future__ import annotations

import datetime as dt
from collections import Counter
from dataclasses import dataclass
from typing import Sequence

from globe.config import DEFAULT_DAY_START, DEFAULT_STEP_MINUTES
from globe.data.records import Day
from globe.errors import ConfigError

MINUTES_PER_DAY = 1440


@dataclass(frozen=True, slots=True)
class DayGrid:
    """Steps ``0..steps-1`` of a day: step t covers the ``step_minutes`` from ``day_start_minute +
    t * step_minutes`` (minutes since the day's midnight; a day may run past midnight)."""

    step_minutes: int
    day_start_minute: int
    steps: int

    def __post_init__(self) -> None:
        if not 1 <= self.step_minutes <= MINUTES_PER_DAY:
            raise ConfigError(f"a step of {self.step_minutes} minutes; expected 1 to {MINUTES_PER_DAY}")
        if not 0 <= self.day_start_minute < MINUTES_PER_DAY:
            raise ConfigError(f"a day starting at minute {self.day_start_minute}; expected 0 to {MINUTES_PER_DAY - 1}")
        if self.steps < 1:
            raise ConfigError(f"a day of {self.steps} steps")

    @property
    def last_step(self) -> int:
        """The last step of the household's days: a fetch decided there would be for uses after the day."""
        return self.steps - 1

    def place(self, wall: dt.datetime) -> tuple[str, int]:
        """(the day a wall-clock time belongs to, as an ISO date, and its step): a day runs from its
        start to the next day's, so 00:30 belongs to the day before."""
        wall = wall.replace(tzinfo=None)
        date = (wall - dt.timedelta(minutes=self.day_start_minute)).date()
        minute = int((wall - dt.datetime.combine(date, dt.time())).total_seconds() // 60)
        return date.isoformat(), (minute - self.day_start_minute) // self.step_minutes

    def minute(self, step: int) -> int:
        """Minutes since the day's midnight at which ``step`` begins (past 1440 after midnight)."""
        return self.day_start_minute + step * self.step_minutes

    def wall(self, day: str, step: int) -> dt.datetime:
        """The naive wall-clock time at which ``step`` of ``day`` begins."""
        return dt.datetime.combine(dt.date.fromisoformat(day), dt.time()) + dt.timedelta(minutes=self.minute(step))

    def clock(self, step: int) -> str:
        """``HH:MM`` of ``step``'s start."""
        minute = self.minute(step) % MINUTES_PER_DAY
        return f"{minute // 60:02d}:{minute % 60:02d}"

    def describe(self) -> str:
        return f"{self.step_minutes}-minute steps from {self.clock(0)}, {self.steps} a day"

    def as_dict(self) -> dict[str, int]:
        return {"step_minutes": self.step_minutes, "day_start_minute": self.day_start_minute, "steps": self.steps}


def _most_common(values: Sequence[int]) -> int | None:
    """The most common value (ties: the smallest), None for none."""
    counts = Counter(values)
    if not counts:
        return None
    top = max(counts.values())
    return min(v for v, c in counts.items() if c == top)


def days_grid(days: Sequence[Day], step_minutes: int | None) -> DayGrid | None:
    """The grid of ``days`` (their step ``step_minutes``, their most common first row and number
    of rows), None without a day."""
    start = _most_common([d.minutes[0] for d in days if len(d)])
    if start is None or step_minutes is None:
        return None
    steps = _most_common([len(d) for d in days if len(d)]) or 1
    return DayGrid(step_minutes, start % MINUTES_PER_DAY, steps)


def household_grid(days: Sequence[Day], step_minutes: int | None, *, configured_step: int | None,
                   configured_start: int | None, name: str) -> DayGrid:
    """The grid household ``name`` runs on: its days' (``step_minutes``: their step), else the
    configured one, else 10-minute steps from 06:00 over the rest of the day. A configured step or
    day start that disagrees with the days is a :class:`ConfigError`: the models were counted on the
    days' grid, and slicing the clock otherwise would hand them positions they never meant."""
    found = days_grid(days, step_minutes)
    if found is None:
        step = configured_step or DEFAULT_STEP_MINUTES
        start = DEFAULT_DAY_START if configured_start is None else configured_start
        return DayGrid(step, start, max(1, (MINUTES_PER_DAY - 1) // step + 1))
    return check_grid(found, configured_step, configured_start, name)


def check_grid(grid: DayGrid, configured_step: int | None, configured_start: int | None, name: str) -> DayGrid:
    """A household's stored grid against the configured step and day start (as :func:`household_grid`)."""
    for what, configured, own in (("step_minutes", configured_step, grid.step_minutes),
                                  ("day_start_minute", configured_start, grid.day_start_minute)):
        if configured is not None and configured != own:
            raise ConfigError(f"household {name}: service.{what} = {configured}, but the household runs on "
                              f"{grid.describe()}; leave service.{what} unset to use the household's own")
    return grid
