"""Fixtures of the evaluation tests."""

from __future__ import annotations

import pytest

from globe import assembly


@pytest.fixture(scope="session")
def persistence_forecaster(households, config):
    """Household A's forecaster over the persistence activity model (read only)."""
    models = config.models.model_copy(update={"activity_estimator": "persistence"})
    return assembly.forecaster(households["A"], config, models=models).forecaster
