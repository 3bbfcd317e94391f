"""Importers of the logs real smart homes produce, into GLOBE's household folders.

One module per format (:mod:`.casas`, :mod:`.kasteren` for van Kasteren and Ordóñez,
:mod:`.home_assistant`) reads its log into a :class:`.sensor_log.SensorLog`; :mod:`.grid` puts any of them on
the step grid by one set of rules (:mod:`.options`; objects' uses: :mod:`.uses`) and writes the
folder with its import report (:mod:`.report`); :mod:`.objects` decides which sensors are objects
and builds the map. Each ``import_*`` function reads everything and checks it before writing anything.
"""

from globe.data.importers.casas import import_casas
from globe.data.importers.grid import ImportResult
from globe.data.importers.home_assistant import import_home_assistant
from globe.data.importers.kasteren import import_kasteren
from globe.data.importers.options import GridOptions

__all__ = ["GridOptions", "ImportResult", "import_casas", "import_home_assistant", "import_kasteren"]
