"""Session fixtures: the real HOMER+ data (resolved exactly as the CLI does) and fitted models."""

from __future__ import annotations

import os
import random

import pytest

from globe.config import GlobeConfig
from globe.data.csv_logs import load_household
from globe.data.locate import resolve_data_root
from globe.pipeline import fit_household


def pytest_report_header(config):
    seed = os.environ.get("GLOBE_TEST_SEED") or str(random.randrange(1_000_000))
    os.environ["GLOBE_TEST_SEED"] = seed
    return f"GLOBE_TEST_SEED={seed}"


@pytest.fixture(scope="session")
def seed() -> int:
    return int(os.environ.get("GLOBE_TEST_SEED", "0"))


@pytest.fixture(scope="session")
def homer_root():
    """Fails loudly (never skips) when the shipped data is missing."""
    return resolve_data_root(None)


@pytest.fixture(scope="session")
def households(homer_root):
    return {name: load_household(homer_root, name) for name in ("A", "B", "C")}


@pytest.fixture(scope="session")
def config() -> GlobeConfig:
    return GlobeConfig()


@pytest.fixture(scope="session")
def fitted(households, config):
    """Paper-configuration models per household (never mutated by tests)."""
    return {n: fit_household(h, config.models, config.sequences.alignment) for n, h in households.items()}
