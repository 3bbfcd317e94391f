"""Only the optional C part of the build; everything else is in pyproject.toml.

``globe.models._suffix_automaton`` builds the suffix automata of the n-gram models,
``globe.models._filter_core`` runs the activity filter's steps and ``globe.models._forecast_core``
the forecaster's hazards and forward pass: all in C, with the same results as the Python code,
several times faster. All are optional: without a C compiler the install goes on and GLOBE uses
its Python code.
"""

import sys

from setuptools import Extension, setup

# The filter's and the forecaster's numbers must have the bits of the Python arithmetic: no fused
# multiply-adds (each module checks this at import and refuses to load otherwise).
EXACT_FLOATS = [] if sys.platform == "win32" else ["-ffp-contract=off"]
COMMON = "src/globe/models/_c_common.h"  # helpers both include (shipped in the sdist, rebuilds them)

setup(ext_modules=[
    Extension("globe.models._suffix_automaton", ["src/globe/models/_suffix_automaton.c"], optional=True),
    Extension("globe.models._filter_core", ["src/globe/models/_filter_core.c"], depends=[COMMON], optional=True,
              extra_compile_args=EXACT_FLOATS),
    Extension("globe.models._forecast_core", ["src/globe/models/_forecast_core.c"], depends=[COMMON], optional=True,
              extra_compile_args=EXACT_FLOATS),
])
