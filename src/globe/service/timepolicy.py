"""Time in the service: each household lives in one IANA time zone.

A naive time is a wall-clock time in the household's zone; an aware time is converted to it,
so a robot may send either (or mix them). A time is refused (422, field ``time``) when it lies
more than ``max_clock_skew`` ahead of the server clock, or before the household's creation minus
that skew: one glitched clock must not lock a household's history or poison its replay.
"""

from __future__ import annotations

import datetime as dt
import os
from pathlib import Path
from zoneinfo import ZoneInfo

from globe.data.importers.text import time_zone
from globe.errors import ConfigError, DataError

UTC = dt.timezone.utc


def server_timezone() -> str:
    """The IANA name of the server's zone ($TZ, else /etc/localtime's target, else UTC)."""
    name = os.environ.get("TZ", "").lstrip(":")
    if name and _valid(name):
        return name
    try:
        target = str(Path("/etc/localtime").resolve())
        if "zoneinfo/" in target:
            name = target.split("zoneinfo/", 1)[1]
            if _valid(name):
                return name
    except OSError:
        pass
    return "UTC"


def _valid(name: str) -> bool:
    try:
        time_zone(name)
        return True
    except ConfigError:
        return False


def zone(name: str, field: str = "timezone") -> ZoneInfo:
    """The zone called ``name``; a :class:`DataError` naming ``field`` if there is none."""
    if name and len(name) <= 64:
        try:
            return time_zone(name)
        except ConfigError:
            pass
    raise DataError(f"unknown IANA time zone {name[:64]!r} (e.g. 'Europe/Paris', 'UTC')", field=field)


def to_zone(time: dt.datetime, tz: ZoneInfo, after: dt.datetime | None = None) -> dt.datetime:
    """An aware time in ``tz``: naive = wall time there. A naive time that occurs twice (the hour
    repeated when clocks go back) is the first occurrence, unless that is not after ``after`` (the
    household's last observation) and the second is: then the second, so a robot sending naive
    wall times goes through the autumn change in order."""
    try:
        if time.tzinfo is not None:
            local = time.astimezone(tz)
        else:
            local = time.replace(tzinfo=tz, fold=0)
            later = time.replace(tzinfo=tz, fold=1)
            if after is not None and later.utcoffset() != local.utcoffset() and local <= after < later:
                local = later
        local.astimezone(UTC)  # the instant must exist too (year 1 or 9999 near the edges may not)
    except (OverflowError, ValueError) as err:
        raise DataError(f"time {time.isoformat()} cannot be placed in {tz.key}: {err}", field="time") from None
    return local


def is_ambiguous(time: dt.datetime, tz: ZoneInfo) -> bool:
    """Whether naive ``time`` occurs twice in ``tz`` (the hour repeated when clocks go back)."""
    if time.tzinfo is not None:
        return False
    return time.replace(tzinfo=tz, fold=0).utcoffset() != time.replace(tzinfo=tz, fold=1).utcoffset()


def check_bounds(time: dt.datetime, *, created: dt.datetime, now: dt.datetime, skew: dt.timedelta) -> None:
    """Refuse a time outside [created - skew, now + skew] (all aware)."""
    try:
        lower, upper = created - skew, now + skew
    except OverflowError:  # pragma: no cover - skew is bounded by the configuration
        lower, upper = dt.datetime.min.replace(tzinfo=UTC), dt.datetime.max.replace(tzinfo=UTC)
    if time > upper:
        raise DataError(f"time {time.isoformat()} is more than {skew} ahead of the server clock ({now.isoformat()}); "
                        "check the robot's clock", field="time")
    if time < lower:
        raise DataError(f"time {time.isoformat()} is before the household was created ({created.isoformat()}) "
                        f"minus the allowed clock skew {skew}", field="time")


def utcnow() -> dt.datetime:
    return dt.datetime.now(UTC)


def check_timezone(name: str | None) -> str:
    """A valid IANA name (default: the server's zone)."""
    name = name or server_timezone()
    zone(name)
    return name
