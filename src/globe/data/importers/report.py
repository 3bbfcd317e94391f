"""The import report (``import.json``, beside the days): which sensor became which object column,
which annotation which activity, which days were dropped and why, and what the import noticed on
the way (silent stretches, sensors left on, records and lines left out), so a user can check an
import without rereading the log."""

from __future__ import annotations

import json
from collections import Counter
from dataclasses import dataclass, field
from datetime import date, datetime, timedelta
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from globe.data.importers.objects import HomeMap, ObjectSelection, ObjectSpec
from globe.data.importers.options import GridOptions, clock
from globe.data.importers.sensor_log import EPOCH, SensorLog
from globe.data.importers.uses import USE_RULES, ObjectUses, left_on_rule

REPORT_FILE = "import.json"
SILENCE_NOTED, SILENCE_FACTOR = timedelta(hours=6), 1.5
"""A kept day's longest stretch with no event from any sensor is listed in the report (a recorder
outage, or nobody home; the day is kept) when it lasts this long and this many times the median
day's longest."""


@dataclass
class LabelStats:
    """What the report says of an activity label, counted while its annotations are placed."""

    annotations: int = 0
    origins: set[str] = field(default_factory=set)
    on_no_row: int = 0  # annotations inside kept days that cover no step's start


def silent_stretches(sensor_log: SensorLog, kept: dict[date, datetime], options: GridOptions
                     ) -> tuple[list[dict[str, str]], float]:
    """Each kept day's longest stretch of its rows with no event from any sensor, where it is far
    longer than the home's usual one (:data:`SILENCE_FACTOR` times the median day's longest, and
    at least :data:`SILENCE_NOTED`); and that limit in hours."""
    times = np.sort(np.frombuffer(sensor_log.moments, dtype=np.float64))
    window = options.step_minutes * options.steps * 60.0
    longest: dict[date, tuple[float, float, float]] = {}  # day -> (seconds, from, to)
    for day, base in kept.items():
        lo = (base - EPOCH).total_seconds()
        inside = times[np.searchsorted(times, lo, side="right"):np.searchsorted(times, lo + window)]
        edges = np.concatenate(([lo], inside, [lo + window]))
        k = int(np.argmax(np.diff(edges)))
        longest[day] = (float(edges[k + 1] - edges[k]), float(edges[k]), float(edges[k + 1]))
    busy = [g for g, _, _ in longest.values() if g < window]  # days a sensor was heard on at all
    usual = float(np.median(busy)) if busy else 0.0
    limit = max(SILENCE_NOTED.total_seconds(), SILENCE_FACTOR * usual)
    silent = [{"date": day.isoformat(), "from": _clock_time(lo), "to": _clock_time(hi)}
              for day, (gap, lo, hi) in sorted(longest.items()) if gap >= limit]
    return silent, limit / 3600


def _clock_time(seconds: float) -> str:
    """A time of :attr:`SensorLog.moments` as the report writes times."""
    return f"{EPOCH + timedelta(seconds=seconds):%Y-%m-%d %H:%M:%S}"


def build_report(sensor_log: SensorLog, selection: ObjectSelection, objects: Sequence[ObjectSpec], home: HomeMap,
                 options: GridOptions, settings: dict[str, Any], activities: dict[date, list[str]],
                 used: dict[str, dict[date, set[int]]], per_label: dict[str, LabelStats],
                 splits: dict[str, list[date]], dropped: list[dict[str, str]], uses: dict[str, ObjectUses],
                 silent: list[dict[str, str]], left_on: list[dict[str, Any]]) -> dict[str, Any]:
    """The report of an import: ``activities`` are the kept days' rows' activities, ``used`` the
    steps each object is in use in (object -> day -> row indices)."""
    rows = Counter(a for row in activities.values() for a in row)
    activity_rows = []
    for label in sorted(set(per_label) | set(rows)):
        stats = per_label.get(label, LabelStats())
        activity_rows.append({"activity": label, "from": sorted(stats.origins) or ["unannotated time"],
                              "annotations": stats.annotations, "rows": rows.get(label, 0),
                              "annotations_on_no_row": stats.on_no_row})
    object_rows = []
    for spec in objects:
        rows_in_use = sum(len(steps) for steps in used.get(spec.object, {}).values())
        found = uses[spec.object]
        object_rows.append({"object": spec.object, "sensors": list(spec.sensors),
                            "events": sum(sensor_log.events[k] for k in spec.sensors), "uses": len(found.spans),
                            "rows_in_use": rows_in_use, "use_limit_minutes": round(found.limit / 60, 1),
                            "left_on": len(found.left_on),
                            "home": home.home_of[spec.object], "in_use": home.in_use_of[spec.object], "why": spec.why})
    left_out = [{"sensor": key, "events": sensor_log.events[key], "why": choice.why}
                for key, choice in selection.choices.items() if choice.object is None]
    return {
        "format": sensor_log.format,
        "sources": list(sensor_log.sources),
        "grid": {"step_minutes": options.step_minutes, "day_start": clock(options.day_start_minute),
                 "day_end": clock(options.day_end_minute), "rows_per_day": options.steps,
                 "activity_rule": "the annotation covering the step's start; idle where none does",
                 "use": options.use, "use_rule": USE_RULES[options.use], "left_on_rule": left_on_rule(options),
                 "overlaps": options.overlaps,
                 "until": options.until.isoformat() if options.until else None,
                 "test_from": options.test_from.isoformat() if options.test_from else None},
        "settings": settings,
        "log_span": [f"{sensor_log.first:%Y-%m-%d %H:%M:%S}", f"{sensor_log.last:%Y-%m-%d %H:%M:%S}"],
        "objects": object_rows,
        "sensors_left_out": left_out,
        "objects_rule": (f"the mapping {selection.mapping.source}" if selection.mapping is not None
                         else selection.default_help),
        "activities": activity_rows,
        "days": {split: [d.isoformat() for d in days] for split, days in splits.items()},
        "dropped_days": dropped,
        "notes": list(sensor_log.notes),
        "silent_stretches": silent,
        "far_outside": sensor_log.left_out,
        "left_on": left_on,
        "bad_lines": _bad_lines(sensor_log),
    }


def _bad_lines(sensor_log: SensorLog) -> list[dict[str, Any]]:
    """The lines left out (``--skip-bad-lines``), by file and line, for the report."""
    rows = [{"source": err.source, "line": err.line, "field": err.field, "why": err.message}
            for err in sensor_log.bad_lines]
    order = {source: i for i, source in enumerate(sensor_log.sources)}
    return sorted(rows, key=lambda r: (order.get(r["source"], len(order)), r["line"] or 0))


def write_report(folder: Path, report: dict[str, Any]) -> None:
    """Write ``report`` as :data:`REPORT_FILE` in ``folder`` (readable UTF-8, one key a line)."""
    (folder / REPORT_FILE).write_text(json.dumps(report, indent=2, ensure_ascii=False) + "\n", encoding="utf-8")
