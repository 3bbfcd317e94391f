"""Households served by one process.

Start-up only reads the list of households (fast, whatever their history); each household's
session (:class:`globe.session.HouseholdSession`) is built on first use, or by a background
warm-up (:mod:`globe.service.rebuild`: its training days counted with the models its deployment
names, its stored observations replayed), and every request drives that session.
"""

from __future__ import annotations

import bisect
import dataclasses
import datetime as dt
import json
import logging
import threading
from collections import OrderedDict
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any, Callable, Iterator, Mapping, Sequence, cast
from zoneinfo import ZoneInfo

from globe import assembly
from globe.config import Deployment, DeployMethod, GlobeConfig
from globe.data.csv_logs import activity_label
from globe.data.records import Household
from globe.data.sensors import SensorData
from globe.errors import (
    DataError,
    DuplicateHouseholdError,
    DuplicateObservationError,
    GlobeError,
    HouseholdUnavailableError,
    LimitError,
    StoreError,
    UnknownHouseholdError,
)
from globe.models.io import model_to_dict
from globe.reasoning.backends.base import LLMBackend
from globe.service import scoring, timepolicy
from globe.service.deploying import Selections, choose_recognition
from globe.service.prediction import prediction
from globe.service.rebuild import Pending, check_limits, rebuild
from globe.service.schema import FoundObservation, HouseholdRow
from globe.service.schemas import (
    FeedbackCounts,
    HouseholdInfo,
    ModelOut,
    ModelSettings,
    ObservationAck,
    OnlineScores,
    Prediction,
    ShadowOut,
    StatsOut,
    check_household_name,
)
from globe.service.store import Store
from globe.service.stored_days import DayEncoding
from globe.service.upload import household_from, parse_nodes, sensors_from
from globe.session import HouseholdSession, Observation, build_session, session_grid
from globe.session.build import deployment_summary, new_activities_rule
from globe.session.sensing import SensorEvent, settings_to_dict

log = logging.getLogger(__name__)


@dataclass(slots=True, eq=False)
class Served:
    """A household's row and, once built, its session and what only the service counts. Its lock
    serialises everything done to the household: building it, every request, its deletion, its
    eviction."""

    row: HouseholdRow
    session: HouseholdSession | None = None
    lock: threading.RLock = field(default_factory=threading.RLock)
    deleted: bool = False
    failure: str | None = None  # why it cannot be built (then it answers 503 until deleted or restarted)
    pending: list[Pending] = field(default_factory=list)  # by time
    feedback: dict[str, int] = field(default_factory=lambda: {"accepted": 0, "refused": 0})
    quarantined: int = 0
    set_aside: int = 0  # stored training days that could not be read back

    def counts(self) -> dict[str, Any]:
        """What the service counts beside the session's own statistics."""
        return {"feedback": dict(self.feedback), "quarantined": self.quarantined,
                "training_days_set_aside": self.set_aside, "pending": len(self.pending)}


class Registry:
    """The households one process serves, always those of the database.

    Locks, always taken in this order: a household's lock (:class:`Served`), then the registry's
    (which guards the map of households, the database rows of households, and eviction), then the
    store's. Eviction only tries other households' locks without waiting."""

    def __init__(self, store: Store, config: GlobeConfig, backend: LLMBackend | None) -> None:
        self.selections = Selections(config, self._chosen)
        self.store = store
        self.config = config
        self.backend = backend
        self._served: dict[str, Served] = {}
        self._lock = threading.Lock()
        self._recent: OrderedDict[str, None] = OrderedDict()  # built households, least recently used first
        self._creating: set[str] = set()  # names reserved by a creation under way
        self.failed: dict[str, str] = {}  # households that could not be built, and why
        self._encoder = ThreadPoolExecutor(max_workers=1, thread_name_prefix="globe-encode")
        self._listeners: list[Callable[[str], None]] = []  # told the household after each applied observation

    def close(self) -> None:
        """Stop the helper thread (the store is closed by its owner)."""
        self._encoder.shutdown(wait=True)

    # -- start-up ------------------------------------------------------------------------------
    def load_all(self) -> None:
        """Read the household list (sessions are built on first use or by :meth:`warm_up`)."""
        with self._lock:
            for row in self.store.households():
                self._served[row.name] = Served(row)

    def warm_up(self, stop: threading.Event | None = None) -> None:
        """Build every household now (run in a background thread after start-up)."""
        with self._lock:
            names = list(self._served)[: self.config.service.max_built_households]
        for name in names:
            if stop is not None and stop.is_set():
                return
            try:
                self.get(name)
            except GlobeError:
                continue

    # -- building --------------------------------------------------------------------------------
    # -- households ------------------------------------------------------------------------------
    def create_uploaded(self, name: str, timezone: str | None, node_rows: Sequence[Mapping[str, Any]],
                        day_texts: list[str], dates: Sequence[dt.date] | None = None, *, method: str | None = None,
                        new_activities: str | None = None, sensors: Sequence[Mapping[str, Any]] | None = None,
                        events: Sequence[str | None] | None = None) -> HouseholdInfo:
        """Validate a household sent over HTTP (its map's rows and its days' texts) against the
        configured limits and the rules of files on disk, then :meth:`create` it."""
        s = self.config.service
        check_household_name(name)
        if len(node_rows) > s.max_nodes:
            raise LimitError(f"{len(node_rows)} nodes (at most {s.max_nodes})", field="nodes")
        if len(day_texts) > s.max_days:
            raise LimitError(f"{len(day_texts)} days (at most {s.max_days})", field="days")
        zone = timepolicy.check_timezone(timezone or s.timezone)
        nodes = parse_nodes(node_rows, max_label=s.max_label_length)
        try:
            household = household_from(name, nodes, day_texts, max_label=s.max_label_length, dates=dates)
        except DataError as err:
            if err.source is None:  # not about one day's text (the dates): it names its own field
                raise
            where = err.source
            detail = f"{where}:{err.line}: {err.message}" if err.line else f"{where}: {err.message}"
            raise type(err)(detail, field=f"{where}.{err.field}" if err.field else where) from None
        if events is not None and sensors is None:
            raise DataError("events without sensors: send the household's sensors too", field="events")
        data = None if sensors is None else sensors_from(sensors, events, household, self.config.data.step_minutes)
        session = self.create(household, zone, day_texts, method=method, new_activities=new_activities, sensors=data)
        return HouseholdInfo(name=name, timezone=zone, objects=list(household.objects),
                             days_learned=session.days_learned, grid=session.grid.describe(),
                             deployment=deployment_summary(session.deployment), selecting=self.selecting(name),
                             sensors=0 if data is None else len(data.sensors))

    def create(self, household: Household, timezone: str, day_texts: list[str], *, method: str | None = None,
               new_activities: str | None = None, sensors: SensorData | None = None) -> HouseholdSession:
        """Build, then store, a validated household (the build fails before anything is stored).
        The name is reserved while it builds, so other requests are not held up meanwhile. Its
        models are chosen as ``method`` says (default ``selection.deploy``): in the background
        where that means cross-validation (:class:`~globe.service.deploying.Selections`). A household
        with ``sensors`` keeps them, its recogniser's settings chosen on its labelled days now."""
        name = household.name
        with self._lock:
            if name in self._served or name in self._creating or self.store.household(name) is not None:
                raise DuplicateHouseholdError(f"household {name!r} exists already")
            limit = self.config.service.max_households
            if self.store.count_households() + len(self._creating) >= limit:
                raise LimitError(f"this service holds {limit} households already (service.max_households)",
                                 field="name")
            self._creating.add(name)
        try:
            grid = session_grid(household, self.config)
            rule = new_activities or new_activities_rule(self.config, bool(household.train))
            chosen_by = cast(DeployMethod, method or self.config.selection.deploy)
            settings: dict[str, Any] = {"grid": grid.as_dict(), "new_activities": rule, "method": chosen_by}
            needs_cv = self.selections.needs_cv(household, chosen_by)
            deployment = Deployment.configured(self.config, chosen_by) if needs_cv else None
            # The days are compressed for storage on another core while the models are counted
            # (zlib releases the GIL), then by both threads; nothing is stored unless the build succeeds.
            encoding = DayEncoding(day_texts)
            helper = self._encoder.submit(encoding.run)
            try:
                if deployment is None:
                    from globe.evaluation.deploy import choose_deployment

                    deployment = choose_deployment(household, self.config, method=chosen_by)
                    settings["deployment"] = deployment.model_dump(mode="json")
                recognition = None
                if sensors is not None:
                    recognition = choose_recognition(household, sensors, grid.step_minutes)
                    settings["recognition"] = settings_to_dict(recognition)
                session = build_session(household, self.config, deployment, self.backend, grid=grid,
                                        new_activities=rule, sensors=sensors,  # type: ignore[arg-type]
                                        recognition=recognition)
            except BaseException:
                encoding.stop()
                raise
            finally:
                encoding.run()  # joins the helper (nothing left to take once stopped)
                helper.result()
            encoded = encoding.blobs
            with self._lock:
                self.store.add_household(household, timezone, day_texts, encoded, settings=settings, sensors=sensors)
                row = self.store.household(name)
                assert row is not None
                self._served[name] = Served(row, session)
        finally:
            with self._lock:
                self._creating.discard(name)
        if needs_cv:
            self.selections.deployment(household, chosen_by)
        self._touch(name)
        self._notify(name)
        return session

    def _chosen(self, name: str, deployment: Deployment) -> None:
        """A household's selection ended: its deployment is stored and it is rebuilt with it on its
        next request (the listeners are told)."""
        try:
            s = self.served(name)
            with s.lock:
                if s.deleted:
                    return
                self._write(name, s, lambda: self.store.set_settings(
                    name, self.store.settings(name) | {"deployment": deployment.model_dump(mode="json")}))
                s.session, s.pending = None, []
                log.info("household %s: deploys %s", name, deployment_summary(deployment))
        except GlobeError as err:  # deleted meanwhile, or the database refuses writes
            log.warning("household %s: its chosen models were not stored: %s", name, err)
            return
        self._notify(name)

    def selecting(self, name: str) -> bool:
        """Whether the household's models are being chosen in the background now."""
        return self.selections.running(name)

    def served(self, name: str) -> Served:
        """The household's entry: the database's row, read under the registry's lock so that no
        deletion can pass between reading it and holding it (404 if there is none)."""
        with self._lock:
            s = self._served.get(name)
            if s is None:
                row = self.store.household(name)  # e.g. imported by the CLI while the service ran
                if row is None:
                    raise UnknownHouseholdError(name)
                s = self._served[name] = Served(row)
            return s

    @contextmanager
    def _held(self, name: str) -> Iterator[Served]:
        """The household built, holding its lock (so it is neither evicted nor deleted under the
        request), its observations that came due applied."""
        while True:
            s = self.served(name)
            with s.lock:
                if s.deleted:  # deleted while this request waited: look again (it may exist anew)
                    continue
                if s.failure is not None:
                    raise HouseholdUnavailableError(self._unavailable(name, s.failure))
                if s.session is None:
                    self._build_into(name, s)
                assert s.session is not None
                self._apply_due(s)
                self._touch(name)
                yield s
                return

    def _build_into(self, name: str, s: Served) -> None:
        try:
            found = rebuild(self.store, self.config, self.backend, self.selections, s.row)
            s.session, s.pending = found.session, found.pending
            s.feedback, s.quarantined, s.set_aside = found.feedback, found.quarantined, found.set_aside
        except Exception as err:  # noqa: BLE001 - whatever a stored row holds, the household is failed, not the service
            if self.store.household(name) is None:  # deleted from the database behind the service's back
                self._forget(name, s)
                raise UnknownHouseholdError(name) from None
            reason = f"{type(err).__name__}: {err}" if not isinstance(err, GlobeError) else str(err)
            log.error("household %s cannot be built: %s", name, reason, exc_info=not isinstance(err, GlobeError))
            s.failure = reason
            with self._lock:
                self.failed[name] = reason
            raise HouseholdUnavailableError(self._unavailable(name, reason)) from None

    @staticmethod
    def _unavailable(name: str, reason: str) -> str:
        return (f"household {name!r} cannot be built from its stored data ({reason}); it can still be exported "
                f"(GET /households/{name}/export) or deleted")

    def _forget(self, name: str, s: Served) -> None:
        """Drop an entry whose household is no longer in the database."""
        with self._lock:
            s.deleted = True
            if self._served.get(name) is s:
                del self._served[name]
            self._recent.pop(name, None)
            self.failed.pop(name, None)

    def _apply_due(self, s: Served) -> None:
        """Apply the held observations the clock has come within ``service.max_ahead`` of."""
        horizon = timepolicy.utcnow() + self.config.service.max_ahead
        session = s.session
        assert session is not None
        while s.pending and s.pending[0].instant <= horizon:
            obs = s.pending.pop(0).observation
            settled = session.settle(session.placement(obs.time))
            session.observe(obs)
            session.remember(settled)

    @contextmanager
    def locked(self, name: str) -> Iterator[HouseholdSession]:
        """The household's current session, holding its lock."""
        with self._held(name) as s:
            assert s.session is not None
            yield s.session

    def get(self, name: str) -> HouseholdSession:
        """The household's session, built if needed (the caller holds no lock: for start-up and tests)."""
        with self.locked(name) as session:
            return session

    def _touch(self, name: str) -> None:
        """Mark ``name`` recently used; evict the least recently used beyond the bound (only idle
        ones: a household whose lock is held is skipped)."""
        with self._lock:
            self._recent[name] = None
            self._recent.move_to_end(name)
            excess = len(self._recent) - self.config.service.max_built_households
            for old in list(self._recent)[:max(0, excess)]:
                s = self._served.get(old)
                if s is None or s.session is None:
                    del self._recent[old]
                elif old != name and s.lock.acquire(blocking=False):
                    try:
                        s.session = None
                        s.pending = []
                        del self._recent[old]
                    finally:
                        s.lock.release()

    def row(self, name: str) -> HouseholdRow:
        return self.served(name).row

    def delete(self, name: str) -> None:
        """Delete the household and everything stored about it (built or not, failed or not)."""
        while True:
            s = self.served(name)
            with s.lock:
                if s.deleted:
                    continue
                with self._lock:
                    self.store.delete_household(name)
                    s.deleted = True
                    if self._served.get(name) is s:
                        del self._served[name]
                    self._recent.pop(name, None)
                    self.failed.pop(name, None)
                break
        self._notify(name)  # a listener finds it gone (Home Assistant's device is removed at once)

    def export(self, name: str) -> dict:
        """Everything stored about the household, as stored (also when it cannot be built)."""
        s = self.served(name)
        with s.lock:
            found = self.store.export_household(name)
        if found is None:
            raise UnknownHouseholdError(name)
        return found

    # -- a household's requests --------------------------------------------------------------------
    def subscribe(self, listener: Callable[[str], None]) -> None:
        """Call ``listener(household)`` after each observation applied and each household created,
        rebuilt with its chosen models or deleted (its lock released, so a listener may ask for the
        new prediction, or find it gone); what it raises is logged."""
        self._listeners.append(listener)

    def _notify(self, name: str) -> None:
        for listener in list(self._listeners):
            try:
                listener(name)
            except Exception:  # noqa: BLE001 - a listener never fails what it is told about
                log.exception("a listener of household %s failed", name)

    def observe(self, name: str, *, time: dt.datetime, activity: str | None, locations: Mapping[str, str],
                client_id: str | None, sensors: Sequence[tuple[str, dt.datetime, dt.datetime | None]] = ()
                ) -> ObservationAck:
        """One observation (:meth:`_observe`), then the listeners told when it was applied (not
        when it is a retry's duplicate or held pending). ``sensors``: (sensor, start, end or None)
        of the activations it carries."""
        ack = self._observe(name, time=time, activity=activity, locations=locations, client_id=client_id,
                            sensors=sensors)
        if not ack.duplicate and not ack.pending:
            self._notify(name)
        return ack

    def _observe(self, name: str, *, time: dt.datetime, activity: str | None, locations: Mapping[str, str],
                 client_id: str | None, sensors: Sequence[tuple[str, dt.datetime, dt.datetime | None]] = ()
                 ) -> ObservationAck:
        """One observation: validated completely, committed to the store, then applied, all under
        the household's lock, and only then acknowledged. A retry with a known ``client_id``
        returns the first acknowledgement (a different observation under that id is a 409).

        An observation further ahead of the server clock than ``service.max_ahead`` (but within
        ``service.max_clock_skew``) is stored and acknowledged as ``pending``, and applied once the
        clock is within ``max_ahead`` of it: one glitched clock cannot lock a household, and
        nothing acknowledged is dropped."""
        s = self.config.service
        if client_id is not None and len(client_id) > s.max_label_length:
            raise LimitError(f"id longer than {s.max_label_length} characters", field="id")
        if activity is not None:
            activity = activity_label(activity)
        check_limits(Observation(time, activity, locations), s)
        with self._held(name) as held:
            a = held.session
            assert a is not None
            tz = timepolicy.zone(held.row.timezone)
            if client_id is not None:
                found = self.store.find_observation(name, client_id)
                if found is not None:
                    if not _same_observation(found, time, activity, locations, tz):
                        raise DuplicateObservationError(f"id {client_id[:64]!r} was acknowledged for another "
                                                        f"observation (time {found.time}); use a new id for a new one")
                    return ObservationAck(id=client_id, day=found.ack.get("day", ""), step=found.ack.get("step", 0),
                                          duplicate=True)
            zoned = timepolicy.to_zone(time, tz, after=a.last_instant)
            now = timepolicy.utcnow()
            timepolicy.check_bounds(zoned, created=held.row.created_at, now=now, skew=s.max_clock_skew)
            events = tuple(SensorEvent(n, timepolicy.to_zone(a, tz), timepolicy.to_zone(a if b is None else b, tz))
                           for n, a, b in sensors)
            obs = Observation(zoned, activity, locations, events)
            instant = zoned.astimezone(dt.timezone.utc)
            held_back = instant > now + s.max_ahead
            try:
                a.validate_labels(obs) if held_back else a.validate(obs)
            except DataError as err:
                if err.field == "time" and timepolicy.is_ambiguous(time, tz):
                    raise DataError(f"{err.message}; {time.isoformat()} occurs twice in {tz.key} (clocks went back): "
                                    "send the time with its UTC offset", field="time") from None
                raise
            if held_back and any(p.instant == instant for p in held.pending):
                raise DataError(f"another observation at {zoned.isoformat()} is already held (times must differ)",
                                field="time")
            place = a.placement(zoned)
            ack = {"day": place.day, "step": place.step}
            settled = None if held_back else a.settle(place)
            statements = [] if settled is None else scoring.statements(name, settled)
            stored = self._write(name, held, lambda: self.store.add_observation(
                name, zoned, activity, dict(locations), client_id, ack, statements,
                sensors=[(e.sensor, e.start, e.end) for e in events]))
            if settled is None:
                bisect.insort(held.pending, Pending(instant, obs), key=lambda p: p.instant)
            else:
                a.observe(obs)
                a.remember(settled)
            return ObservationAck(id=client_id if client_id is not None else str(stored), duplicate=False,
                                  pending=held_back, **ack)

    def _write(self, name: str, held: Served, write: Callable[[], int]) -> int:
        """A store write for a household; if the household vanished from the database behind the
        service's back (``globe household delete`` on its file), a 404 and the entry dropped."""
        try:
            return write()
        except StoreError:
            try:
                gone = self.store.problem() is None and self.store.household(name) is None
            except StoreError:
                gone = False
            if gone:
                self._forget(name, held)
                raise UnknownHouseholdError(name) from None
            raise

    def predict(self, name: str) -> Prediction:
        """The next step's prediction; in shadow mode ``act`` stays false (the fetches decided are
        still recorded and scored)."""
        with self._held(name) as held:
            session = held.session
            assert session is not None
            decided = session.last_decision
            d = session.decide()
            shadow = self.store.shadow(name)
            if d.fetches and d is not decided and session.day is not None:  # a new decision: recorded once
                for c in d.fetches:
                    try:
                        self.store.add_fetch(name, session.day, d.step - 1, c.obj, c.to_location, c.probability,
                                             shadow)
                    except StoreError as err:  # the prediction stands; only its score is lost
                        log.warning("household %s: the fetch decision was not stored: %s", name, err)
            return prediction(d, shadow, session.grid.clock(d.question.step) if d.question else None)

    def set_shadow(self, name: str, shadow: bool) -> ShadowOut:
        """Switch the household's shadow mode (stored: it outlives a restart; the listeners are told,
        so Home Assistant's state says so at once, not at the next step)."""
        with self._held(name) as held:
            self._write(name, held, lambda: self.store.set_shadow(name, shadow))
            with self._lock:
                held.row = dataclasses.replace(held.row, shadow=shadow)
        self._notify(name)
        return ShadowOut(household=name, shadow=shadow)

    def scores(self, name: str, days: int = 28) -> OnlineScores:
        """The online scores of the last ``days`` days (today's so far included)."""
        with self.locked(name) as session:
            return scoring.online_scores(self.store, name, session, days)

    def feedback(self, name: str, obj: str, accepted: bool) -> FeedbackCounts:
        """What the person said about a fetched object: stored, then counted."""
        with self._held(name) as held:
            session = held.session
            assert session is not None
            if obj not in session.household.objects:
                raise DataError(f"unknown object {obj[:64]!r}", field="object")
            self._write(name, held, lambda: self.store.add_feedback(name, obj, accepted))
            held.feedback["accepted" if accepted else "refused"] += 1
            return FeedbackCounts(**held.feedback)

    def stats(self, name: str) -> StatsOut:
        """The household's counts, with what it runs: its grid, its deployment and the effective
        settings of its built models and chooser."""
        with self._held(name) as held:
            session = held.session
            assert session is not None
            built = assembly.describe(session.activity_model, session.chooser, session.deployment.models.stay_margin)
            scores = scoring.online_scores(self.store, name, session)
            return StatsOut(**session.stats(), **held.counts(), timezone=held.row.timezone,
                            created_at=held.row.created_at.isoformat(), chooser=built["chooser"],
                            models=ModelSettings(activity=built["activity"], objects=built["objects"]),
                            grid=session.grid.describe(), deployment=session.deployment.model_dump(mode="json"),
                            selecting=self.selecting(name), shadow=self.store.shadow(name), scores=scores)

    def export_model(self, name: str) -> ModelOut:
        """Both models as :func:`globe.models.io.model_to_dict` writes them, and the deployment."""
        with self.locked(name) as session:
            return ModelOut.model_validate({"activity": model_to_dict(session.activity_model),
                                            "objects": model_to_dict(session.chooser.model),
                                            "deployment": session.deployment.model_dump(mode="json")})

    def names(self) -> list[str]:
        """Every stored household (also those imported by the CLI while the service ran)."""
        return sorted(r.name for r in self.store.households())

    def failures(self) -> list[str]:
        """Households that could not be built (they answer 503 until deleted or the service restarts)."""
        with self._lock:
            return sorted(self.failed)

    def built(self) -> int:
        with self._lock:
            return sum(s.session is not None for s in self._served.values())


def _same_observation(found: FoundObservation, time: dt.datetime, activity: str | None, locations: Mapping[str, str],
                      tz: ZoneInfo) -> bool:
    """Whether a retry carries the observation stored under its id: the same activity, the same
    locations and the same time (the same wall time, for a naive one)."""
    try:
        stored_time = dt.datetime.fromisoformat(found.time)
        stored_locations = json.loads(found.locations)
    except ValueError:
        return False
    if time.tzinfo is None:
        same_time = stored_time.astimezone(tz).replace(tzinfo=None) == time
    else:
        same_time = stored_time == time
    return same_time and found.activity == activity and stored_locations == dict(locations)


__all__ = ["Registry", "UnknownHouseholdError", "DuplicateHouseholdError", "DataError"]
