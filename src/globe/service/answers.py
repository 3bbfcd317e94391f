"""Answers to "what are you doing?": the label of the step under way, however it comes.

A household with sensors is asked a few times a day (the prediction's ``question``). The person
answers through Home Assistant (a tapped notification, published over MQTT) or the dashboard's
Today page; either way the answer is an ordinary observation with the activity, taken by the same
path as any (:meth:`~globe.service.registry.Registry.observe`: validated, stored, then applied),
inside the step it answers. An answer that would land in a later step is refused: the person
may be doing something else by then, and a label in the wrong step teaches the recogniser wrong.
"""

from __future__ import annotations

import datetime as dt
from typing import TYPE_CHECKING

from globe.data.csv_logs import activity_label
from globe.errors import DataError
from globe.service import timepolicy

if TYPE_CHECKING:  # pragma: no cover
    from globe.service.registry import Registry
    from globe.service.schemas import ObservationAck

LATE = "came after the step it answers (a later step was observed, or the step was left)"


def answer(registry: "Registry", name: str, activity: str, *, client_id: str | None = None,
           arrived: dt.datetime | None = None, step: tuple[str, int] | None = None) -> "ObservationAck | None":
    """Label the step under way of household ``name`` with ``activity``.

    ``arrived`` (Home Assistant: the answer carries no step): the answer is observed at its arrival,
    refused where that falls after the step under way. ``step`` (the dashboard: the form names the
    ``(day, step)`` it showed): refused unless that is still the step under way, observed just after
    its last observation, so it labels that step whatever the wall clock says (a home replayed from
    its logs answers as a live one); the same answer again (a second tap) changes nothing (None)."""
    with registry.locked(name) as session:
        last = session.last_instant
        if arrived is None:
            if step is None:
                raise ValueError("an answer needs its arrival time or the step it answers")
            if last is None or (session.day, session.step) != step:
                raise DataError(f"the answer {activity[:64]!r} {LATE}", field="step")
            if session.today()[step[1]][1] == activity_label(activity):
                return None
            arrived = last + dt.timedelta(milliseconds=1)
        zone = timepolicy.zone(registry.row(name).timezone)
        if session.placement(arrived.astimezone(zone)).new_step:
            raise DataError(f"the answer {activity[:64]!r} {LATE}", field="time")
    return registry.observe(name, time=arrived, activity=activity, locations={}, client_id=client_id)
