"""Reading a smart-home log strictly: its lines with their numbers, and the timestamps it uses.

Research logs are plain text with one record a line; a user's export may be anything. A file that
is empty, binary or not UTF-8 stops the import with its line, before any record is read, so that
a wrong file is never half-read. Timestamps are checked against the exact shapes each format
writes (``2010-11-04 00:03:50.209589``, ``25-Feb-2008 00:20:14``, ISO 8601 with an offset), not
passed to a lenient parser that would accept ``2010-11-4`` or a bare date.
"""

from __future__ import annotations

import re
from bisect import bisect_right
from datetime import datetime, timedelta, tzinfo
from pathlib import Path
from typing import Iterator, Sequence
from zoneinfo import ZoneInfo, ZoneInfoNotFoundError

from globe.data.csv_logs import _clean, _decode, _ragged, _read_bytes
from globe.errors import ConfigError, DataError

_ISO_DATE = re.compile(r"(\d{4})-(\d{2})-(\d{2})")
_CLOCK = re.compile(r"(\d{2}):(\d{2}):(\d{2})(?:\.(\d{1,6}))?")
_MONTHS = {name: i for i, name in enumerate(
    ("jan", "feb", "mar", "apr", "may", "jun", "jul", "aug", "sep", "oct", "nov", "dec"), start=1)}
_DMY_DATE = re.compile(r"(\d{1,2})-([A-Za-z]{3})-(\d{4})")
_EPOCH, _MICROSECOND = datetime(1970, 1, 1), timedelta(microseconds=1)
RESIDENT_ID = r"R\d+"  # a resident of a multi-resident log, as its labels name one
RESIDENT = re.compile(rf"({RESIDENT_ID})[_ ](.+)", re.IGNORECASE)  # R1_Sleep, R2_Meal; Cairo: R1 sleep
_ISO_8601 = re.compile(r"\d{4}-\d{2}-\d{2}[T ]\d{2}:\d{2}(?::\d{2}(?:\.\d{1,9})?)?(?:Z|[+-]\d{2}:?\d{2})?")


def time_zone(name: str) -> ZoneInfo:
    """An IANA time zone by name, or a one-line error (a name that is a folder of the zone data,
    such as ``Europe``, or too long for a file name, is no zone either)."""
    try:
        return ZoneInfo(name)
    except (ZoneInfoNotFoundError, ValueError, OSError) as err:
        raise ConfigError(f"unknown time zone {name!r}: give an IANA name such as Europe/Amsterdam (on a system "
                          "without zone data, pip install tzdata)") from err


def repeated_for(moment: datetime, zone: tzinfo) -> timedelta:
    """How long the local wall time ``moment`` comes back in ``zone`` when the clocks go back over
    it (daylight saving time ends): zero for every other time, a skipped one included."""
    first, second = (moment.replace(tzinfo=zone, fold=f).utcoffset() for f in (0, 1))
    assert first is not None and second is not None
    return max(first - second, timedelta(0))


def clocks_went_back(before: datetime, moment: datetime, zone: tzinfo) -> bool:
    """Whether local time ``moment``, logged after ``before`` but earlier on the clock, is the
    second pass of the hour the clocks went back over."""
    fold = repeated_for(moment, zone)
    return bool(fold) and bool(repeated_for(before, zone)) and timedelta(0) < before - moment <= fold


def out_of_order(times: Sequence[datetime | None]) -> list[int]:
    """The indices of the fewest records to leave out so that the others are in time order
    (``None``: a record without a time, never counted), keeping the earlier of two records out of
    order with each other: one corrupt timestamp far ahead is left out alone, not every good record
    after it. The longest non-decreasing run, earliest records first, in O(n log n)."""
    keys = [(t - _EPOCH) // _MICROSECOND if t is not None else None for t in times]
    longest = [0] * len(keys)  # the longest in-order run starting at each record
    tails: list[int] = []  # -(latest start) of a run of each length found so far, ascending
    for i in range(len(keys) - 1, -1, -1):
        key = keys[i]
        if key is None:
            continue
        at = bisect_right(tails, -key)
        longest[i] = at + 1
        if at == len(tails):
            tails.append(-key)
        else:
            tails[at] = -key
    left, last, dropped = len(tails), None, []
    for i, key in enumerate(keys):
        if key is None:
            continue
        if left and longest[i] == left and (last is None or key >= last):
            left, last = left - 1, key
        else:
            dropped.append(i)
    return dropped


def show(text: str, limit: int = 48) -> str:
    """A value for a message: repr, cut when long."""
    return repr(text if len(text) <= limit else text[:limit] + "...")


def read_text(path: Path) -> str:
    """A log's text: UTF-8 (a byte-order mark is dropped), not empty, with no NUL byte (a binary
    file, or a log cut off mid-write, shows them)."""
    source = str(path)
    data = _read_bytes(path, "log file")
    nul = data.find(b"\x00")
    if nul >= 0:
        line = data.count(b"\n", 0, nul) + 1
        raise DataError(f"binary data (a NUL byte at byte {nul}): not a text log", source=source, line=line)
    text = _decode(data, source)
    if not text.strip():
        raise DataError("empty file (no records)", source=source, line=1)
    return text


def read_lines(path: Path) -> list[tuple[int, str]]:
    """The non-blank lines of a text log, each with its 1-based line number (``\\r`` dropped).

    Lines are split on ``\\n`` only, so numbers match what an editor shows even when a line
    holds a form feed or a Unicode line separator; a file with ``\\r`` and no ``\\n`` (old Mac
    line endings) is split on ``\\r``.
    """
    text = read_text(path)
    lines = enumerate(text.split("\n" if "\n" in text or "\r" not in text else "\r"), start=1)
    return [(number, line.rstrip("\r")) for number, line in lines if line.strip()]


def _clock(text: str, source: str, line: int, field: str) -> tuple[int, int, int, int]:
    match = _CLOCK.fullmatch(text)
    if match is None:
        raise DataError(f"{show(text)} is not a time of day (HH:MM:SS, optionally .ffffff)",
                        source=source, line=line, field=field)
    hour, minute, second, fraction = match.groups()
    micro = int((fraction or "0").ljust(6, "0"))
    return int(hour), int(minute), int(second), micro


def _build(parts: tuple[int, int, int, int, int, int, int], text: str, source: str, line: int, field: str) -> datetime:
    try:
        return datetime(*parts)
    except ValueError as err:  # month 13, 25:00, 30 February
        raise DataError(f"{show(text)} is not a valid date and time ({err})", source=source, line=line,
                        field=field) from None


def parse_date_time(date: str, clock: str, *, source: str, line: int, date_field: str = "date",
                    time_field: str = "time") -> datetime:
    """``2010-11-04`` and ``00:03:50[.209589]`` (CASAS, Ordóñez) as a naive local datetime."""
    match = _ISO_DATE.fullmatch(date)
    if match is None:
        raise DataError(f"{show(date)} is not a date (YYYY-MM-DD)", source=source, line=line, field=date_field)
    year, month, day = (int(g) for g in match.groups())
    return _build((year, month, day, *_clock(clock, source, line, time_field)), f"{date} {clock}", source, line,
                  date_field)


def parse_day_month_year(date: str, clock: str, *, source: str, line: int, field: str) -> datetime:
    """``25-Feb-2008`` and ``00:20:14`` (van Kasteren's logs); month names are English."""
    match = _DMY_DATE.fullmatch(date)
    month = _MONTHS.get(match.group(2).lower()) if match is not None else None
    if match is None or month is None:
        raise DataError(f"{show(date)} is not a date (DD-Mon-YYYY, e.g. 25-Feb-2008)", source=source, line=line,
                        field=field)
    return _build((int(match.group(3)), month, int(match.group(1)), *_clock(clock, source, line, field)),
                  f"{date} {clock}", source, line, field)


def parse_iso_8601(text: str, *, source: str, line: int, field: str) -> datetime:
    """A full ISO 8601 timestamp (Home Assistant's ``2024-03-01T06:12:09.123+00:00`` or ``...Z``);
    naive when it carries no offset. Nanoseconds are cut to microseconds."""
    if _ISO_8601.fullmatch(text) is None:
        raise DataError(f"{show(text)} is not an ISO 8601 timestamp (e.g. 2024-03-01T06:12:09+00:00)",
                        source=source, line=line, field=field)
    trimmed = re.sub(r"(\.\d{6})\d+", r"\1", text)
    try:
        return datetime.fromisoformat(trimmed)
    except ValueError as err:
        raise DataError(f"{show(text)} is not a valid date and time ({err})", source=source, line=line,
                        field=field) from None


def parse_clock(text: str) -> int:
    """``HH:MM`` (an option's value) as minutes after midnight; ``24:00`` is 1440. ValueError if not."""
    match = re.fullmatch(r"(\d{1,2}):(\d{2})", text.strip())
    minutes = int(match.group(1)) * 60 + int(match.group(2)) if match is not None else -1
    if match is None or int(match.group(2)) > 59 or not 0 <= minutes <= 1440:
        raise ValueError(f"{show(text)} is not a time of day HH:MM between 00:00 and 24:00")
    return minutes


def slug(text: str) -> str:
    """A sensor or place name as a class name: lower case, runs of other characters as ``_``
    (``Hall-Toilet door`` -> ``hall_toilet_door``)."""
    return re.sub(r"[^0-9a-z]+", "_", text.lower()).strip("_")


def table_cells(rows: Sequence[tuple[int, list[str]]], header: list[str],
                source: str) -> Iterator[tuple[int, dict[str, str]]]:
    """The data lines of a mapping or listing CSV (``rows[0]`` is its header) as (line, {column:
    cleaned value}); a line with another number of fields than the header is an error."""
    for line, row in rows[1:]:
        if len(row) != len(header):
            raise _ragged(source, line, row, header)
        yield line, {name: _clean(value) for name, value in zip(header, row)}
