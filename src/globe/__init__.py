"""GLOBE: proactive robot assistance from a household's observed routine.

The public API is re-exported here; heavy optional parts (LLM runtimes, the HTTP service,
the torch importer) are imported only by the modules that need them.
"""

from globe.config import GlobeConfig, load_config
from globe.data.csv_logs import load_household
from globe.data.records import Day, Household
from globe.errors import DataError, GlobeError, NotFittedError
from globe.models.activity import ActivityModel
from globe.models.objects import ObjectModel

__version__ = "0.1.0"

__all__ = [
    "ActivityModel",
    "DataError",
    "Day",
    "GlobeConfig",
    "GlobeError",
    "Household",
    "NotFittedError",
    "ObjectModel",
    "__version__",
    "load_config",
    "load_household",
]
