"""A stored household back in memory: its session built from its stored map, training days and
settings (grid, deployment, label rule, the recogniser's settings), with its sensors and their
training days' activations where it has them, its stored observations (and the sensor activations
they carried) replayed in time order: what the session learned online is learned again.

A stored row that cannot be replayed (written by an older GLOBE, or damaged) is quarantined,
logged and counted, and the rest loads: nothing stored can stop the service.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import json
import logging
from dataclasses import dataclass, field
from typing import Any

from globe.config import Deployment, GlobeConfig, ServiceConfig
from globe.data.csv_logs import activity_label, map_rules
from globe.data.records import Household
from globe.data.sensors import SensorData, SensorDay, day_stem, parse_events_text
from globe.errors import DataError, GlobeError, LimitError, StoreError
from globe.reasoning.backends.base import LLMBackend
from globe.service import scoring, timepolicy
from globe.service.deploying import Selections, choose_recognition
from globe.service.schema import HouseholdRow
from globe.service.store import Store
from globe.service.stored_days import legacy_day
from globe.service.upload import DayParser
from globe.session import DayGrid, HouseholdSession, Observation, build_session, session_grid
from globe.session.build import new_activities_rule
from globe.session.sensing import SensorEvent, settings_from_dict, settings_to_dict

log = logging.getLogger(__name__)


@dataclass(frozen=True, slots=True)
class Pending:
    """An observation stored and acknowledged, held until the server clock is within
    ``service.max_ahead`` of it (see :meth:`globe.service.registry.Registry.observe`)."""

    instant: dt.datetime  # UTC
    observation: Observation


@dataclass(slots=True)
class Restored:
    """A household rebuilt: its session, the observations still held, and what the service counts."""

    session: HouseholdSession
    pending: list[Pending] = field(default_factory=list)
    feedback: dict[str, int] = field(default_factory=lambda: {"accepted": 0, "refused": 0})
    quarantined: int = 0
    set_aside: int = 0  # stored training days that could not be read back


def check_limits(obs: Observation, s: ServiceConfig) -> None:
    """The configured label limits (before anything is stored)."""
    if obs.activity is not None and len(obs.activity) > s.max_label_length:
        raise LimitError(f"activity longer than {s.max_label_length} characters", field="activity")
    if len(obs.locations) > s.max_locations:
        raise LimitError(f"{len(obs.locations)} locations in one observation (at most {s.max_locations})",
                         field="locations")


def rebuild(store: Store, config: GlobeConfig, backend: LLMBackend | None, selections: Selections,
            row: HouseholdRow) -> Restored:
    """The household of ``row`` from its stored rows: training days counted, observations replayed
    in time order (those still ahead of the clock are held as pending)."""
    if row.problem:
        raise StoreError(row.problem)
    tz = timepolicy.zone(row.timezone)
    nodes, objects = store.load_map(row.name)
    parser = DayParser(objects, *map_rules(nodes))
    days, set_aside = [], 0
    listed = store.sensors(row.name)
    events: dict[str, SensorDay] = {}
    for i, kept in enumerate(store.training_days(row.name)):
        try:
            text = kept.text
            day = legacy_day(text) if text.startswith("{") else parser.parse(text, f"days[{i}]")[0]
            day = day if kept.date is None else dataclasses.replace(day, name=kept.date)
            if listed is not None and kept.events is not None:
                stem = day_stem(day.name)
                events[stem] = parse_events_text(kept.events, listed, stem, f"events[{i}]")
            days.append(day)
        except (GlobeError, ValueError, KeyError, TypeError) as err:
            log.warning("household %s: stored training day %d set aside: %s", row.name, i, err)
            set_aside += 1
    household = Household(row.name, nodes, objects, tuple(days), (), f"sqlite:{store.path}")
    sensors = None if listed is None else SensorData(listed, events)
    out = Restored(stored_session(store, config, backend, selections, household, sensors), set_aside=set_aside)
    session = out.session
    bad: list[int] = []
    replay: list[tuple[dt.datetime, int, Observation]] = []
    labels: dict[str, str] = {}  # each stored activity through the label rule once
    for stored in store.observations(row.name):
        try:
            time = timepolicy.to_zone(dt.datetime.fromisoformat(stored.time), tz)
            received = dt.datetime.fromisoformat(stored.received_at)
            received = received if received.tzinfo else received.replace(tzinfo=dt.timezone.utc)
            timepolicy.check_bounds(time, created=row.created_at, now=received, skew=config.service.max_clock_skew)
            activity = stored.activity
            if activity is not None:
                activity = labels.get(activity) or labels.setdefault(activity, activity_label(activity))
            obs = Observation(time, activity, _locations(json.loads(stored.locations)),
                              _sensor_events(stored.sensors, tz))
            check_limits(obs, config.service)
            replay.append((time.astimezone(dt.timezone.utc), stored.id, obs))
        except (GlobeError, ValueError, TypeError, KeyError, OverflowError) as err:
            log.warning("household %s: stored observation %d quarantined: %s", row.name, stored.id, err)
            bad.append(stored.id)
    # Applied observations always increase in time (held ones come after every observation
    # applied before them), so replaying in time order repeats what was applied live.
    horizon = timepolicy.utcnow() + config.service.max_ahead
    for instant, stored_id, obs in sorted(replay, key=lambda r: (r[0], r[1])):
        if instant > horizon:
            out.pending.append(Pending(instant, obs))
            continue
        try:
            session.validate(obs)  # the label rule as it stood when the observation was applied
        except DataError as err:
            log.warning("household %s: stored observation %d quarantined: %s", row.name, stored_id, err)
            bad.append(stored_id)
            continue
        settled = session.settle(session.placement(obs.time))
        session.observe(obs)
        session.remember(settled)
    if bad:
        try:
            store.quarantine(bad)
        except StoreError as err:
            log.warning("household %s: could not mark quarantined rows: %s", row.name, err)
    out.quarantined = max(len(bad), store.quarantined(row.name))
    for accepted in store.feedback(row.name):
        out.feedback["accepted" if accepted else "refused"] += 1
    scoring.restore(session, store, row.name)
    return out


def stored_session(store: Store, config: GlobeConfig, backend: LLMBackend | None, selections: Selections,
                   household: Household, sensors: SensorData | None = None) -> HouseholdSession:
    """The session of a stored household, on its stored grid and deployment. A household stored
    without them (created before households kept them, or whose selection has not ended) gets its
    days' grid and what :meth:`Selections.deployment` gives it now, stored where final; one with
    ``sensors`` stored without its recogniser's settings (imported from a folder) has them chosen
    now, and stored."""
    name = household.name
    settings = store.settings(name)
    try:
        grid = DayGrid(**settings["grid"]) if "grid" in settings else None
        deployment = Deployment.model_validate(settings["deployment"]) if settings.get("deployment") else None
        recognition = settings_from_dict(settings["recognition"]) if settings.get("recognition") else None
    except (TypeError, ValueError) as err:
        raise StoreError(f"the stored settings of household {name!r} cannot be read ({err})") from None
    if grid is None or "new_activities" not in settings:
        # stored before households kept their settings: they learned any activity then, and still do
        rule = "learn" if not settings else new_activities_rule(config, bool(household.train))
        settings |= {"grid": session_grid(household, config, grid).as_dict(), "new_activities": rule}
        store.set_settings(name, settings)
    if deployment is None:
        deployment, final = selections.deployment(household, settings.get("method") or config.selection.deploy)
        if final:
            store.set_settings(name, settings | {"deployment": deployment.model_dump(mode="json")})
    grid = DayGrid(**settings["grid"])
    if sensors is not None and recognition is None:
        recognition = choose_recognition(household, sensors, grid.step_minutes)
        settings = store.settings(name) | {"recognition": settings_to_dict(recognition)}
        store.set_settings(name, settings)
    return build_session(household, config, deployment, backend, grid=grid,
                         new_activities=settings["new_activities"], sensors=sensors, recognition=recognition)


def _sensor_events(stored: str | None, tz: Any) -> tuple[SensorEvent, ...]:
    """Stored sensor activations (JSON [[sensor, start, end], ...]; None: none) in the household's zone."""
    if stored is None:
        return ()
    rows = json.loads(stored)
    if not isinstance(rows, list):
        raise TypeError("stored sensor events are not a JSON list")
    return tuple(SensorEvent(str(n), timepolicy.to_zone(dt.datetime.fromisoformat(a), tz),
                             timepolicy.to_zone(dt.datetime.fromisoformat(b), tz)) for n, a, b in rows)


def _locations(value: Any) -> dict[str, str]:
    """Stored locations: a JSON object (anything else is a damaged row; its keys are strings, and
    :meth:`HouseholdSession.validate_labels` refuses any value that is not a known label)."""
    if not isinstance(value, dict):
        raise TypeError("stored locations are not a JSON object")
    return value
