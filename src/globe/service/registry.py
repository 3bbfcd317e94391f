"""Households served by one process.

Start-up only reads the list of households (fast, whatever their history); each household's
assistant is built on first use (or by a background warm-up): its training days are re-counted
and its stored observations replayed. A stored row that cannot be replayed (written by an older
GLOBE, or damaged) is quarantined, logged and counted, and the rest loads: nothing stored can
stop the service.
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
from typing import Any, Callable, Iterator, Mapping, Sequence
from zoneinfo import ZoneInfo

from globe import assembly
from globe.config import GlobeConfig
from globe.data.csv_logs import activity_label
from globe.data.records import Household
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
from globe.service.assistant import Observation, OnlineAssistant, build_assistant
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
from globe.service.stored_days import DayEncoding, legacy_day
from globe.service.upload import DayParser, household_from, parse_nodes

log = logging.getLogger(__name__)


@dataclass(frozen=True, slots=True)
class Pending:
    """An observation stored and acknowledged, held until the server clock is within
    ``service.max_ahead`` of it (see :meth:`Registry.observe`)."""

    instant: dt.datetime  # UTC
    observation: Observation


@dataclass(slots=True, eq=False)
class Served:
    """A household's row and, once built, its assistant. Its lock serialises everything done to the
    household: building it, every request, its deletion, its eviction."""

    row: HouseholdRow
    assistant: OnlineAssistant | None = None
    lock: threading.RLock = field(default_factory=threading.RLock)
    deleted: bool = False
    failure: str | None = None  # why it cannot be built (then it answers 503 until deleted or restarted)
    pending: list[Pending] = field(default_factory=list)  # by time


class Registry:
    """The households one process serves, always those of the database.

    Locks, always taken in this order: a household's lock (:class:`Served`), then the registry's
    (which guards the map of households, the database rows of households, and eviction), then the
    store's. Eviction only tries other households' locks without waiting."""

    def __init__(self, store: Store, config: GlobeConfig, backend: LLMBackend | None) -> None:
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
        """Read the household list (assistants are built on first use or by :meth:`warm_up`)."""
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
    def _build(self, row: HouseholdRow) -> tuple[OnlineAssistant, list[Pending]]:
        """The household's assistant from its stored rows: training days counted, observations
        replayed in time order (those still ahead of the clock are returned as pending)."""
        if row.problem:
            raise StoreError(row.problem)
        tz = timepolicy.zone(row.timezone)
        nodes, objects = self.store.load_map(row.name)
        locations = frozenset(n.node for n in nodes)
        owners = {n.cls: n.node for n in nodes if n.movable}
        days = []
        parser = DayParser(objects, locations, owners)
        set_aside = 0
        for i, kept in enumerate(self.store.training_days(row.name)):
            try:
                text = kept.text
                day = legacy_day(text) if text.startswith("{") else parser.parse(text, f"days[{i}]")[0]
                days.append(day if kept.date is None else dataclasses.replace(day, name=kept.date))
            except (GlobeError, ValueError, KeyError, TypeError) as err:
                log.warning("household %s: stored training day %d set aside: %s", row.name, i, err)
                set_aside += 1
        household = Household(row.name, nodes, objects, tuple(days), (), f"sqlite:{self.store.path}")
        assistant = build_assistant(household, self.config, self.backend)
        assistant.training_days_set_aside = set_aside
        bad: list[int] = []
        replay: list[tuple[dt.datetime, int, Observation]] = []
        labels: dict[str, str] = {}  # each stored activity through the label rule once
        for stored in self.store.observations(row.name):
            try:
                time = timepolicy.to_zone(dt.datetime.fromisoformat(stored.time), tz)
                received = dt.datetime.fromisoformat(stored.received_at)
                received = received if received.tzinfo else received.replace(tzinfo=dt.timezone.utc)
                timepolicy.check_bounds(time, created=row.created_at, now=received,
                                        skew=self.config.service.max_clock_skew)
                activity = stored.activity
                if activity is not None:
                    activity = labels.get(activity) or labels.setdefault(activity, activity_label(activity))
                obs = Observation(time, activity, _locations(json.loads(stored.locations)))
                self.check_labels(obs)
                assistant.validate_labels(obs)
                replay.append((time.astimezone(dt.timezone.utc), stored.id, obs))
            except (GlobeError, ValueError, TypeError, KeyError, OverflowError) as err:
                log.warning("household %s: stored observation %d quarantined: %s", row.name, stored.id, err)
                bad.append(stored.id)
        # Applied observations always increase in time (held ones come after every observation
        # applied before them), so replaying in time order repeats what was applied live.
        horizon = timepolicy.utcnow() + self.config.service.max_ahead
        pending: list[Pending] = []
        for instant, stored_id, obs in sorted(replay, key=lambda r: (r[0], r[1])):
            if instant > horizon:
                pending.append(Pending(instant, obs))
                continue
            try:
                assistant.validate_time(obs)  # its labels were checked above
            except DataError as err:
                log.warning("household %s: stored observation %d quarantined: %s", row.name, stored_id, err)
                bad.append(stored_id)
                continue
            assistant.observe(obs)
        if bad:
            try:
                self.store.quarantine(bad)
            except StoreError as err:
                log.warning("household %s: could not mark quarantined rows: %s", row.name, err)
        assistant.quarantined = max(len(bad), self.store.quarantined(row.name))
        assistant.pending = len(pending)
        for accepted in self.store.feedback(row.name):
            assistant.record_feedback(accepted)
        scoring.restore(assistant, self.store, row.name)
        return assistant, pending

    def check_labels(self, obs: Observation) -> None:
        """The configured label limits (before anything is stored)."""
        s = self.config.service
        if obs.activity is not None and len(obs.activity) > s.max_label_length:
            raise LimitError(f"activity longer than {s.max_label_length} characters", field="activity")
        if len(obs.locations) > s.max_locations:
            raise LimitError(f"{len(obs.locations)} locations in one observation (at most {s.max_locations})",
                             field="locations")

    # -- households ------------------------------------------------------------------------------
    def create_uploaded(self, name: str, timezone: str | None, node_rows: Sequence[Mapping[str, Any]],
                        day_texts: list[str], dates: Sequence[dt.date] | None = None) -> HouseholdInfo:
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
        assistant = self.create(household, zone, day_texts)
        return HouseholdInfo(name=name, timezone=zone, objects=list(household.objects),
                             days_learned=assistant.days_learned)

    def create(self, household: Household, timezone: str, day_texts: list[str]) -> OnlineAssistant:
        """Build, then store, a validated household (the build fails before anything is stored).
        The name is reserved while it builds, so other requests are not held up meanwhile."""
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
            # The days are compressed for storage on another core while the models are counted
            # (zlib releases the GIL), then by both threads; nothing is stored unless the build succeeds.
            encoding = DayEncoding(day_texts)
            helper = self._encoder.submit(encoding.run)
            try:
                assistant = build_assistant(household, self.config, self.backend)
            except BaseException:
                encoding.stop()
                raise
            finally:
                encoding.run()  # joins the helper (nothing left to take once stopped)
                helper.result()
            encoded = encoding.blobs
            with self._lock:
                self.store.add_household(household, timezone, day_texts, encoded)
                row = self.store.household(name)
                assert row is not None
                self._served[name] = Served(row, assistant)
        finally:
            with self._lock:
                self._creating.discard(name)
        self._touch(name)
        self._notify(name)
        return assistant

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
                if s.assistant is None:
                    self._build_into(name, s)
                assert s.assistant is not None
                self._apply_due(s)
                self._touch(name)
                yield s
                return

    def _build_into(self, name: str, s: Served) -> None:
        try:
            s.assistant, s.pending = self._build(s.row)
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
        a = s.assistant
        assert a is not None
        while s.pending and s.pending[0].instant <= horizon:
            a.observe(s.pending.pop(0).observation)
        a.pending = len(s.pending)

    @contextmanager
    def locked(self, name: str) -> Iterator[OnlineAssistant]:
        """The household's current assistant, holding its lock."""
        with self._held(name) as s:
            assert s.assistant is not None
            yield s.assistant

    def get(self, name: str) -> OnlineAssistant:
        """The household's assistant, built if needed (the caller holds no lock: for start-up and tests)."""
        with self.locked(name) as a:
            return a

    def _touch(self, name: str) -> None:
        """Mark ``name`` recently used; evict the least recently used beyond the bound (only idle
        ones: a household whose lock is held is skipped)."""
        with self._lock:
            self._recent[name] = None
            self._recent.move_to_end(name)
            excess = len(self._recent) - self.config.service.max_built_households
            for old in list(self._recent)[:max(0, excess)]:
                s = self._served.get(old)
                if s is None or s.assistant is None:
                    del self._recent[old]
                elif old != name and s.lock.acquire(blocking=False):
                    try:
                        s.assistant = None
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
                return

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
        """Call ``listener(household)`` after each observation applied and each household created
        (its lock released, so a listener may ask for the new prediction); what it raises is logged."""
        self._listeners.append(listener)

    def _notify(self, name: str) -> None:
        for listener in list(self._listeners):
            try:
                listener(name)
            except Exception:  # noqa: BLE001 - a listener never fails what it is told about
                log.exception("a listener of household %s failed", name)

    def observe(self, name: str, *, time: dt.datetime, activity: str | None, locations: Mapping[str, str],
                client_id: str | None) -> ObservationAck:
        """One observation (:meth:`_observe`), then the listeners told when it was applied (not
        when it is a retry's duplicate or held pending)."""
        ack = self._observe(name, time=time, activity=activity, locations=locations, client_id=client_id)
        if not ack.duplicate and not ack.pending:
            self._notify(name)
        return ack

    def _observe(self, name: str, *, time: dt.datetime, activity: str | None, locations: Mapping[str, str],
                 client_id: str | None) -> ObservationAck:
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
        self.check_labels(Observation(time, activity, locations))
        with self._held(name) as held:
            a = held.assistant
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
            obs = Observation(zoned, activity, locations)
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
            settled = scoring.Settled() if held_back else scoring.before_observe(name, a, place, self.config.policy)
            stored = self._write(name, held, lambda: self.store.add_observation(name, zoned, activity, dict(locations),
                                                                               client_id, ack, settled.statements))
            if held_back:
                bisect.insort(held.pending, Pending(instant, obs), key=lambda p: p.instant)
                a.pending = len(held.pending)
            else:
                a.observe(obs)
                scoring.after_observe(a, settled)
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
        """The next step's prediction; in shadow mode ``act`` stays false (the fetch decided is
        still recorded and scored)."""
        with self._held(name) as held:
            a = held.assistant
            assert a is not None
            decided = a.last_prediction
            p = a.predict()
            shadow = self.store.shadow(name)
            if p.fetch_object is not None and p is not decided:  # a new decision: recorded once
                step = scoring.record_fetch(a, p.fetch_object, self.config.policy)
                if step is not None and a.day is not None:
                    try:
                        self.store.add_fetch(name, a.day, step, p.fetch_object, p.fetch_to, p.fetch_probability,
                                             shadow)
                    except StoreError as err:  # the prediction stands; only its score is lost
                        log.warning("household %s: the fetch decision was not stored: %s", name, err)
            if shadow:
                p = p.model_copy(update={"act": False, "shadow": True})
            return p

    def set_shadow(self, name: str, shadow: bool) -> ShadowOut:
        """Switch the household's shadow mode (stored: it outlives a restart)."""
        with self._held(name) as held:
            self._write(name, held, lambda: self.store.set_shadow(name, shadow))
            with self._lock:
                held.row = dataclasses.replace(held.row, shadow=shadow)
            return ShadowOut(household=name, shadow=shadow)

    def scores(self, name: str, days: int = 28) -> OnlineScores:
        """The online scores of the last ``days`` days (today's so far included)."""
        with self._held(name) as held:
            a = held.assistant
            assert a is not None
            return scoring.online_scores(self.store, name, a, self.config, days)

    def feedback(self, name: str, obj: str, accepted: bool) -> FeedbackCounts:
        """What the person said about a fetched object: stored, then counted."""
        with self._held(name) as held:
            a = held.assistant
            assert a is not None
            if obj not in a.household.objects:
                raise DataError(f"unknown object {obj[:64]!r}", field="object")
            self._write(name, held, lambda: self.store.add_feedback(name, obj, accepted))
            a.record_feedback(accepted)
            return FeedbackCounts(**a.stats()["feedback"])

    def stats(self, name: str) -> StatsOut:
        """The household's counts, with the effective settings of its built models and chooser."""
        with self._held(name) as held:
            a = held.assistant
            assert a is not None
            built = assembly.describe(a.activity_model, a.chooser)
            scores = scoring.online_scores(self.store, name, a, self.config)
            return StatsOut(**a.stats(), timezone=held.row.timezone, created_at=held.row.created_at.isoformat(),
                            chooser=built["chooser"], models=ModelSettings(activity=built["activity"],
                                                                           objects=built["objects"]),
                            shadow=self.store.shadow(name), scores=scores)

    def export_model(self, name: str) -> ModelOut:
        """Both models as :func:`globe.models.io.model_to_dict` writes them."""
        with self.locked(name) as a:
            return ModelOut.model_validate({"activity": model_to_dict(a.activity_model),
                                            "objects": model_to_dict(a.chooser.model)})

    def names(self) -> list[str]:
        """Every stored household (also those imported by the CLI while the service ran)."""
        return sorted(r.name for r in self.store.households())

    def failures(self) -> list[str]:
        """Households that could not be built (they answer 503 until deleted or the service restarts)."""
        with self._lock:
            return sorted(self.failed)

    def built(self) -> int:
        with self._lock:
            return sum(s.assistant is not None for s in self._served.values())


def _locations(value: Any) -> dict[str, str]:
    """Stored locations: a JSON object (anything else is a damaged row; its keys are strings, and
    :meth:`OnlineAssistant.validate_labels` refuses any value that is not a known label)."""
    if not isinstance(value, dict):
        raise TypeError("stored locations are not a JSON object")
    return value


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
