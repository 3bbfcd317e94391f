"""Households served by one process.

Start-up only reads the list of households (fast, whatever their history); each household's
assistant is built on first use (or by a background warm-up): its training days are re-counted
and its stored observations replayed. A stored row that cannot be replayed (written by an older
GLOBE, or damaged) is quarantined, logged and counted, and the rest loads: nothing stored can
stop the service.
"""

from __future__ import annotations

import datetime as dt
import gc
import json
import logging
import threading
from collections import OrderedDict
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Iterator

from globe.config import GlobeConfig
from globe.data.records import Household
from globe.errors import DataError, GlobeError, LimitError, StoreError
from globe.reasoning.backends.base import LLMBackend
from globe.service import timepolicy
from globe.service.assistant import Observation, OnlineAssistant, build_assistant
from globe.service.store import DayEncoding, HouseholdRow, Store, legacy_day
from globe.service.upload import DayParser

log = logging.getLogger(__name__)


_gc_lock = threading.Lock()
_gc_pauses = 0


@contextmanager
def no_gc() -> Iterator[None]:
    """Pause the cyclic garbage collector while a household is parsed and counted: the work
    allocates hundreds of thousands of long-lived objects and no cycles, and full collections
    that scan every household already built cost about a quarter of the time."""
    global _gc_pauses
    with _gc_lock:
        _gc_pauses += 1
        gc.disable()
    try:
        yield
    finally:
        with _gc_lock:
            _gc_pauses -= 1
            if _gc_pauses == 0:
                gc.enable()


class UnknownHouseholdError(GlobeError, KeyError):
    def __init__(self, name: str) -> None:
        super().__init__(f"unknown household {name!r}")
        self.name = name
        self.field = None

    def __str__(self) -> str:
        return str(self.args[0])


class DuplicateHouseholdError(GlobeError):
    field = "name"


@dataclass(slots=True)
class Served:
    """A household's row and, once built, its assistant."""

    row: HouseholdRow
    assistant: OnlineAssistant | None = None
    lock: threading.Lock = None  # type: ignore[assignment]
    deleted: bool = False

    def __post_init__(self) -> None:
        self.lock = threading.Lock()


class Registry:
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

    def close(self) -> None:
        """Stop the helper thread (the store is closed by its owner)."""
        self._encoder.shutdown(wait=True)

    # -- start-up ------------------------------------------------------------------------------
    def load_all(self) -> None:
        """Read the household list (assistants are built on first use or by :meth:`warm_up`)."""
        for row in self.store.households():
            self._served[row.name] = Served(row)

    def warm_up(self, stop: threading.Event | None = None) -> None:
        """Build every household now (run in a background thread after start-up)."""
        for name in list(self._served)[: self.config.service.max_built_households]:
            if stop is not None and stop.is_set():
                return
            try:
                self.get(name)
            except GlobeError:
                continue

    # -- building --------------------------------------------------------------------------------
    def _build(self, row: HouseholdRow) -> OnlineAssistant:
        nodes, objects = self.store.load_map(row.name)
        locations = frozenset(n.node for n in nodes)
        owners = {n.cls: n.node for n in nodes if n.movable}
        days = []
        parser = DayParser(objects, locations, owners)
        for i, text in enumerate(self.store.training_days(row.name)):
            try:
                days.append(legacy_day(text) if text.startswith("{") else parser.parse(text, f"days[{i}]")[0])
            except (GlobeError, ValueError, KeyError) as err:
                log.warning("household %s: stored training day %d set aside: %s", row.name, i, err)
        household = Household(row.name, nodes, objects, tuple(days), (), f"sqlite:{self.store.path}")
        assistant = build_assistant(household, self.config, self.backend)
        tz = timepolicy.zone(row.timezone)
        bad: list[int] = []
        for stored in self.store.observations(row.name):
            try:
                time = timepolicy.to_zone(dt.datetime.fromisoformat(stored.time), tz)
                received = dt.datetime.fromisoformat(stored.received_at)
                received = received if received.tzinfo else received.replace(tzinfo=dt.timezone.utc)
                timepolicy.check_bounds(time, created=row.created_at, now=received, skew=self.config.service.max_clock_skew)
                obs = Observation(time, stored.activity, json.loads(stored.locations))
                self.check_labels(obs)
                assistant.validate(obs)
                assistant.observe(obs)
            except (GlobeError, ValueError, TypeError, KeyError, OverflowError) as err:
                log.warning("household %s: stored observation %d quarantined: %s", row.name, stored.id, err)
                bad.append(stored.id)
        if bad:
            try:
                self.store.quarantine(bad)
            except StoreError as err:
                log.warning("household %s: could not mark quarantined rows: %s", row.name, err)
        assistant.quarantined = max(len(bad), self.store.quarantined(row.name))
        for accepted in self.store.feedback(row.name):
            assistant.record_feedback(accepted)
        return assistant

    def check_labels(self, obs: Observation) -> None:
        """The configured label limits (before anything is stored)."""
        s = self.config.service
        if obs.activity is not None and len(obs.activity) > s.max_label_length:
            raise LimitError(f"activity longer than {s.max_label_length} characters", field="activity")
        if len(obs.locations) > s.max_locations:
            raise LimitError(f"{len(obs.locations)} locations in one observation (at most {s.max_locations})", field="locations")

    # -- households ------------------------------------------------------------------------------
    def create(self, household: Household, timezone: str, day_texts: list[str]) -> OnlineAssistant:
        """Build, then store, a validated household (the build fails before anything is stored).
        The name is reserved while it builds, so other requests are not held up meanwhile."""
        name = household.name
        with self._lock:
            if name in self._served or name in self._creating or self.store.household(name) is not None:
                raise DuplicateHouseholdError(f"household {name!r} exists already")
            limit = self.config.service.max_households
            if self.store.count_households() + len(self._creating) >= limit:
                raise LimitError(f"this service holds {limit} households already (service.max_households)", field="name")
            self._creating.add(name)
        try:
            # The days are compressed for storage on another core while the models are counted
            # (zlib releases the GIL), then by both threads; nothing is stored unless the build succeeds.
            encoding = DayEncoding(day_texts)
            helper = self._encoder.submit(encoding.run)
            try:
                with no_gc():
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
        return assistant

    def served(self, name: str) -> Served:
        s = self._served.get(name)
        if s is None:
            row = self.store.household(name)  # imported by the CLI while the service ran
            if row is None:
                raise UnknownHouseholdError(name)
            with self._lock:
                s = self._served.setdefault(name, Served(row))
        return s

    def get(self, name: str) -> OnlineAssistant:
        s = self.served(name)
        if s.assistant is None:
            with s.lock:
                if s.assistant is None and not s.deleted:
                    try:
                        with no_gc():
                            s.assistant = self._build(s.row)
                    except GlobeError as err:
                        self.failed[name] = str(err)
                        log.error("household %s cannot be built: %s", name, err)
                        raise
        assistant = s.assistant
        if s.deleted or assistant is None:
            raise UnknownHouseholdError(name)
        self._touch(name)
        return assistant

    @contextmanager
    def locked(self, name: str) -> Iterator[OnlineAssistant]:
        """The household's current assistant, holding its lock (so it is neither evicted nor
        deleted under the request)."""
        while True:
            a = self.get(name)
            with a.lock:
                s = self._served.get(name)
                if s is None or s.deleted:
                    raise UnknownHouseholdError(name)
                if s.assistant is a:
                    yield a
                    return

    def _touch(self, name: str) -> None:
        """Mark ``name`` recently used; evict the least recently used beyond the bound (only idle
        ones: an assistant whose lock is held is skipped)."""
        with self._lock:
            self._recent[name] = None
            self._recent.move_to_end(name)
            excess = len(self._recent) - self.config.service.max_built_households
            for old in list(self._recent)[:max(0, excess)]:
                s = self._served.get(old)
                a = s.assistant if s else None
                if a is None:
                    del self._recent[old]
                elif old != name and a.lock.acquire(blocking=False):
                    try:
                        s.assistant = None  # type: ignore[union-attr]
                        del self._recent[old]
                    finally:
                        a.lock.release()

    def row(self, name: str) -> HouseholdRow:
        return self.served(name).row

    def delete(self, name: str) -> None:
        with self.locked(name):
            with self._lock:
                self.store.delete_household(name)
                s = self._served.pop(name)
                s.deleted = True
                self._recent.pop(name, None)
                self.failed.pop(name, None)

    def names(self) -> list[str]:
        """Every stored household (also those imported by the CLI while the service ran)."""
        return sorted(r.name for r in self.store.households())

    def built(self) -> int:
        return sum(s.assistant is not None for s in self._served.values())


def check_timezone(name: str | None) -> str:
    """A valid IANA name (default: the server's zone)."""
    name = name or timepolicy.server_timezone()
    timepolicy.zone(name)
    return name


__all__ = ["Registry", "UnknownHouseholdError", "DuplicateHouseholdError", "DataError", "check_timezone"]
