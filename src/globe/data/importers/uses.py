"""When an object is in use: its sensors' activations merged into uses, an activation far longer
than the object's usual cut as a sensor left on, and what each ``--use`` mode means.

An object's uses are its sensors' activations, those that overlap or touch merged into one (the
sensor, or another of the object's, never went off between: one use). A sensor left on, an
activation longer than its object's limit, is cut to a firing (it marks the step it began in
only, as with ``use="start"``) and listed in the report (``left_on``). The limit, per object from
all of its activations in the log, is ``max_use_minutes`` when given; else, with at least
:data:`LEFT_ON_PERCENTILE_MIN` activations, :data:`LEFT_ON_K` times their 99th percentile (with
that many, one stuck activation cannot raise the percentile to itself); with
:data:`LEFT_ON_MEDIAN_MIN` to :data:`LEFT_ON_PERCENTILE_MIN` - 1, :data:`LEFT_ON_K_FEW` times
their median (robust to a stuck one while it is not half of them); with fewer, nothing usual to
judge by, :data:`LEFT_ON_ALONE`. The rule's limit is never under two steps or
:data:`LEFT_ON_FLOOR` (an oven on for a stew is a use).

:func:`globe.data.importers.grid.write_import` marks the steps these uses reach (``while-on``) or
begin in (``start``); the report lists each object's uses, limit and activations cut.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import Any, Sequence

import numpy as np

from globe.data.importers.objects import ObjectSpec
from globe.data.importers.options import GridOptions
from globe.data.importers.sensor_log import Activation

LEFT_ON_K, LEFT_ON_PERCENTILE_MIN = 3.0, 101
"""With at least LEFT_ON_PERCENTILE_MIN activations an object's limit is LEFT_ON_K times their 99th
percentile (linear interpolation: from 101 on, it lies at or below the second longest, so one stuck
activation never sets its own limit)."""
LEFT_ON_K_FEW, LEFT_ON_MEDIAN_MIN = 10.0, 3
"""With LEFT_ON_MEDIAN_MIN to LEFT_ON_PERCENTILE_MIN - 1 activations, the limit is LEFT_ON_K_FEW times
their median (from 3 on, one stuck activation is not the median)."""
LEFT_ON_ALONE = timedelta(days=1)
"""The limit of an object with fewer activations: nothing usual to judge by, so only one on for
over a day counts as left on."""
LEFT_ON_FLOOR = timedelta(hours=1)
"""The rule's limit is never under this, nor under two steps: a long use (an oven on for a stew)
is a use, not a sensor left on. --max-use-minutes sets any limit."""
LEFT_ON_RULE = (f"an activation longer than its object's limit is a sensor left on, cut to a firing at its start; "
                f"the limit: {LEFT_ON_K:g} x the 99th percentile of the object's activations (from "
                f"{LEFT_ON_PERCENTILE_MIN} of them), else {LEFT_ON_K_FEW:g} x their median (from "
                f"{LEFT_ON_MEDIAN_MIN}), else {LEFT_ON_ALONE.total_seconds() / 3600:g} hours; never under "
                f"{LEFT_ON_FLOOR.total_seconds() / 60:g} minutes or two steps")
USE_RULES: dict[str, str] = {
    "while-on": "in use in every step in which a sensor of the object fires or is on",
    "start": "in use in the step in which a use begins (a sensor of the object goes on while none was), home "
             "again from the next step"}
"""What each ``--use`` mode means, as the report says it."""


@dataclass(frozen=True, slots=True)
class ObjectUses:
    """An object's uses (``[start, end]``, merged, in time order) and its activations cut as left on."""

    spans: list[tuple[datetime, datetime]]
    limit: float  # seconds an activation may last
    left_on: list[dict[str, Any]]


def use_limit(durations: Sequence[float], options: GridOptions) -> float:
    """Seconds an object's activation may last before it is a sensor left on, from the durations
    (seconds) of all its activations (see the module doc for the rule)."""
    if options.max_use_minutes is not None:
        return options.max_use_minutes * 60.0
    floor = max(2 * options.step_minutes * 60.0, LEFT_ON_FLOOR.total_seconds())
    if len(durations) >= LEFT_ON_PERCENTILE_MIN:
        return max(floor, LEFT_ON_K * float(np.percentile(durations, 99)))
    if len(durations) >= LEFT_ON_MEDIAN_MIN:
        return max(floor, LEFT_ON_K_FEW * float(np.median(durations)))
    return max(floor, LEFT_ON_ALONE.total_seconds())


def find_uses(spec: ObjectSpec, activations: dict[str, list[Activation]], options: GridOptions) -> ObjectUses:
    """The object's uses: its sensors' activations, those longer than its limit cut to a firing,
    then those that overlap or touch merged (the sensor never went off between: one use)."""
    stretches = [(act, key) for key in spec.sensors for act in activations.get(key, ())]
    limit = use_limit([(a.end - a.start).total_seconds() for a, _ in stretches], options)
    left_on: list[dict[str, Any]] = []
    spans: list[tuple[datetime, datetime]] = []
    for act, key in sorted(stretches, key=lambda s: (s[0].start, s[0].end)):
        seconds = (act.end - act.start).total_seconds()
        end = act.end
        if seconds > limit:
            left_on.append({"object": spec.object, "sensor": key, "start": f"{act.start:%Y-%m-%d %H:%M:%S}",
                            "end": f"{act.end:%Y-%m-%d %H:%M:%S}", "minutes": round(seconds / 60, 1),
                            "limit_minutes": round(limit / 60, 1)})
            end = act.start
        if spans and act.start <= spans[-1][1]:
            spans[-1] = (spans[-1][0], max(spans[-1][1], end))
        else:
            spans.append((act.start, end))
    return ObjectUses(spans, limit, left_on)


def left_on_rule(options: GridOptions) -> str:
    """The rule that cut activations as left on in this import, as the report says it."""
    return (f"a use longer than {options.max_use_minutes:g} minutes (--max-use-minutes)"
            if options.max_use_minutes is not None else LEFT_ON_RULE)
