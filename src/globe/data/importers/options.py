"""The options every format's import shares: how a log is cut into days and steps, how objects
are in use, and which days are test days (the command line's defaults and choices come from
here, so the two cannot drift apart)."""

from __future__ import annotations

from dataclasses import dataclass
from datetime import date
from typing import Literal

from globe.data.csv_logs import DAY_MINUTES
from globe.errors import ConfigError

DEFAULT_STEP_MINUTES = 10
DEFAULT_DAY_START = 360  # 06:00, HOMER+'s first row
DEFAULT_DAY_END = 1440  # 24:00, HOMER+'s last row
DEFAULT_TEST_FRACTION = 0.2
Overlaps = Literal["error", "latest"]
UseMode = Literal["while-on", "start"]
Unlabelled = Literal["keep", "drop"]
UNLABELLED_MODES: tuple[Unlabelled, ...] = ("keep", "drop")
"""What ``--unlabelled`` accepts: a day the sensors recorded and nobody annotated is written to
``unlabelled/`` (keep: recognition learns from it and labels it) or left out (drop)."""
USE_MODES: tuple[UseMode, ...] = ("while-on", "start")
"""What ``--use`` accepts; what each means is :data:`globe.data.importers.uses.USE_RULES`."""


@dataclass(frozen=True, slots=True)
class GridOptions:
    """How a log is cut into days and steps, and which days are test days."""

    step_minutes: int = DEFAULT_STEP_MINUTES
    day_start_minute: int = DEFAULT_DAY_START
    day_end_minute: int = DEFAULT_DAY_END
    test_days: int | None = None  # None: the last test_fraction of the kept days
    test_fraction: float = DEFAULT_TEST_FRACTION
    overlaps: Overlaps = "error"
    use: UseMode = "while-on"  # an object is in use while its sensor is on, or at its start only
    max_use_minutes: float | None = None  # a use longer is a sensor left on (None: the module's rule)
    test_from: date | None = None  # the kept days from this date on are the test days
    until: date | None = None  # days after this date are left out
    unlabelled: Unlabelled = "keep"  # days with sensor records and no annotation: unlabelled/ (keep) or left out

    def check(self) -> None:
        """Called where an import starts (not in the constructor, so options stay plain values)."""
        start, end, step = self.day_start_minute, self.day_end_minute, self.step_minutes
        if not 0 <= start < end <= DAY_MINUTES:
            raise ConfigError(f"the day must start before it ends, within 00:00..24:00 (got {clock(start)} to "
                              f"{clock(end)})")
        if step < 1 or (end - start) % step:
            raise ConfigError(f"a step of {step} minutes does not divide the day {clock(start)}..{clock(end)} "
                              f"({end - start} minutes); use e.g. 1, 2, 5 or 10")
        if self.test_days is not None and self.test_days < 0:
            raise ConfigError(f"test days must be 0 or more (got {self.test_days})")
        if not 0.0 <= self.test_fraction < 1.0:
            raise ConfigError(f"the test fraction must be in [0, 1) (got {self.test_fraction})")
        if self.overlaps not in ("error", "latest"):
            raise ConfigError(f"overlaps must be 'error' or 'latest' (got {self.overlaps!r})")
        if self.use not in USE_MODES:
            raise ConfigError(f"use must be 'while-on' or 'start' (got {self.use!r})")
        if self.unlabelled not in UNLABELLED_MODES:
            raise ConfigError(f"unlabelled must be 'keep' or 'drop' (got {self.unlabelled!r})")
        if self.max_use_minutes is not None and not self.max_use_minutes > 0:
            raise ConfigError(f"the longest use must be more than 0 minutes (got {self.max_use_minutes})")
        if self.test_from is not None and self.test_days is not None:
            raise ConfigError("give the first test day (--test-from) or the number of test days (--test-days), "
                              "not both")
        if self.test_from is not None and self.until is not None and self.test_from > self.until:
            raise ConfigError(f"the first test day {self.test_from} is after the last day kept ({self.until}, "
                              "--until): there would be no test day")

    @property
    def steps(self) -> int:
        """Rows per day: one at each step's start from the day's start to its end, both included."""
        return (self.day_end_minute - self.day_start_minute) // self.step_minutes + 1


def clock(minute: int) -> str:
    """A minute of the day as ``HH:MM``, as the errors and the report write it."""
    return f"{minute // 60:02d}:{minute % 60:02d}"
