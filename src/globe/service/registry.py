"""Households served by one process: built from the store, then kept in memory."""

from __future__ import annotations

import threading
from pathlib import Path

from globe import assembly
from globe.config import GlobeConfig
from globe.data.csv_logs import load_household
from globe.data.records import Household
from globe.errors import DataError, GlobeError
from globe.reasoning.backends.base import LLMBackend
from globe.service.assistant import Observation, OnlineAssistant
from globe.service.store import Store


class UnknownHouseholdError(GlobeError, KeyError):
    def __init__(self, name: str) -> None:
        super().__init__(f"unknown household {name!r}")
        self.name = name


class DuplicateHouseholdError(GlobeError):
    pass


class Registry:
    def __init__(self, store: Store, config: GlobeConfig, backend: LLMBackend | None) -> None:
        self.store = store
        self.config = config
        self.backend = backend
        self._assistants: dict[str, OnlineAssistant] = {}
        self._lock = threading.Lock()

    def build(self, household: Household) -> OnlineAssistant:
        return assembly.assistant(household, self.config, self.backend)

    def load_all(self) -> None:
        """Rebuild every stored household: re-count training days, replay observations."""
        for name in self.store.household_names():
            assistant = self.build(self.store.load_household(name))
            for time, activity, locations in self.store.observations(name):
                assistant.observe(Observation(time, activity, locations))
            for accepted in self.store.feedback(name):
                assistant.record_feedback(accepted)
            self._assistants[name] = assistant

    def create(self, name: str, source: str) -> OnlineAssistant:
        path = Path(source)
        if not (path / "nodes.csv").is_file():
            raise DataError(f"{source!r} is not a household folder (no nodes.csv)", field="source")
        loaded = load_household(path.parent, path.name)
        household = Household(name, loaded.nodes, loaded.objects, loaded.train, (), loaded.source)
        with self._lock:
            if name in self._assistants:
                raise DuplicateHouseholdError(f"household {name!r} exists already")
            assistant = self.build(household)
            self.store.add_household(household)
            self._assistants[name] = assistant
        return assistant

    def get(self, name: str) -> OnlineAssistant:
        try:
            return self._assistants[name]
        except KeyError:
            raise UnknownHouseholdError(name) from None

    def names(self) -> list[str]:
        return sorted(self._assistants)
