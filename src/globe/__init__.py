"""GLOBE: proactive robot assistance from a household's observed routine.

What a user needs is importable from here (``from globe import RoutineModel``) and listed in
``__all__``. Only the configuration, the errors and the data records are imported with the
package; every other name is imported the first time it is used (module ``__getattr__``), so
``import globe`` stays fast and works without the optional extras (llama-cpp-python, openai,
fastapi, httpx): a missing extra is reported when the name that needs it is used.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from globe.config import GlobeConfig, load_config
from globe.data.csv_logs import load_household
from globe.data.locate import resolve_data_root
from globe.data.records import Day, Household, Node
from globe.errors import ConfigError, DataError, GlobeError, LLMError, NotFittedError

__version__ = "0.1.0"

# public name -> (module, attribute): imported on first use
_LAZY: dict[str, tuple[str, str]] = {
    # fitting from a configuration (the one composition root)
    "fit_household": ("globe.assembly", "fit_household"),
    "FittedHousehold": ("globe.assembly", "FittedHousehold"),
    "fit_forecaster": ("globe.assembly", "forecaster"),
    # the activity and object models
    "ActivityModel": ("globe.models.activity", "ActivityModel"),
    "RoutineModel": ("globe.models.routine", "RoutineModel"),
    "ClockModel": ("globe.models.clock", "ClockModel"),
    "PersistenceModel": ("globe.models.baselines", "PersistenceModel"),
    "ObjectModel": ("globe.models.objects", "ObjectModel"),
    "HourActivityObjects": ("globe.models.baselines", "HourActivityObjects"),
    # inference: forecasting, filtering, the robot's decision
    "Forecaster": ("globe.inference.forecast", "Forecaster"),
    "Forecast": ("globe.inference.forecast", "Forecast"),
    "MovementModel": ("globe.inference.movements", "MovementModel"),
    "ActivityFilter": ("globe.inference.activity_filter", "ActivityFilter"),
    "FetchPolicy": ("globe.inference.fetch_policy", "FetchPolicy"),
    "FetchCandidate": ("globe.inference.fetch_policy", "FetchCandidate"),
    # the LLM step
    "UncertaintyGate": ("globe.reasoning.gate", "UncertaintyGate"),
    "ObjectChooser": ("globe.reasoning.choice", "ObjectChooser"),
    "ObjectChoice": ("globe.reasoning.choice", "ObjectChoice"),
    "ChoiceContext": ("globe.reasoning.context", "ChoiceContext"),
    "LLMBackend": ("globe.reasoning.backends.base", "LLMBackend"),
    "Choice": ("globe.reasoning.backends.base", "Choice"),
    "EmbeddedBackend": ("globe.reasoning.backends.embedded", "EmbeddedBackend"),
    "RemoteBackend": ("globe.reasoning.backends.remote", "RemoteBackend"),
    # the service's client (what a robot program imports)
    "GlobeClient": ("globe.service.client", "GlobeClient"),
    "ServiceError": ("globe.service.client", "ServiceError"),
    "ServiceUnreachableError": ("globe.service.client", "ServiceUnreachableError"),
}

__all__ = [
    "__version__",
    "ActivityFilter",
    "ActivityModel",
    "Choice",
    "ChoiceContext",
    "ClockModel",
    "ConfigError",
    "DataError",
    "Day",
    "EmbeddedBackend",
    "FetchCandidate",
    "FetchPolicy",
    "fit_forecaster",
    "fit_household",
    "FittedHousehold",
    "Forecast",
    "Forecaster",
    "GlobeClient",
    "GlobeConfig",
    "GlobeError",
    "Household",
    "HourActivityObjects",
    "LLMBackend",
    "LLMError",
    "load_config",
    "load_household",
    "MovementModel",
    "Node",
    "NotFittedError",
    "ObjectChoice",
    "ObjectChooser",
    "ObjectModel",
    "PersistenceModel",
    "RemoteBackend",
    "resolve_data_root",
    "RoutineModel",
    "ServiceError",
    "ServiceUnreachableError",
    "UncertaintyGate",
]


def __getattr__(name: str) -> Any:
    """Import a public name on first use and keep it, so the next lookup is a plain attribute."""
    try:
        module, attribute = _LAZY[name]
    except KeyError:
        raise AttributeError(f"module 'globe' has no attribute {name!r}") from None
    value = getattr(importlib.import_module(module), attribute)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))


if TYPE_CHECKING:  # what type checkers and editors see for the lazy names
    from globe.assembly import FittedHousehold, fit_household
    from globe.assembly import forecaster as fit_forecaster
    from globe.inference.activity_filter import ActivityFilter
    from globe.inference.fetch_policy import FetchCandidate, FetchPolicy
    from globe.inference.forecast import Forecast, Forecaster
    from globe.inference.movements import MovementModel
    from globe.models.activity import ActivityModel
    from globe.models.baselines import HourActivityObjects, PersistenceModel
    from globe.models.clock import ClockModel
    from globe.models.objects import ObjectModel
    from globe.models.routine import RoutineModel
    from globe.reasoning.backends.base import Choice, LLMBackend
    from globe.reasoning.backends.embedded import EmbeddedBackend
    from globe.reasoning.backends.remote import RemoteBackend
    from globe.reasoning.choice import ObjectChoice, ObjectChooser
    from globe.reasoning.context import ChoiceContext
    from globe.reasoning.gate import UncertaintyGate
    from globe.service.client import GlobeClient, ServiceError, ServiceUnreachableError
