"""Only the compiled part of the build; everything else is in pyproject.toml.

``globe.models._suffix_automaton`` builds the suffix automata of the n-gram models,
``globe.inference._beam`` selects the activity filter's histories and the forecaster's paths and
``globe.inference._propagate`` moves the forecaster's objects along the activity paths. Each is
the only implementation of what it does, so the build requires a C compiler: without one the
install stops with the compiler's message.
"""

from setuptools import Extension, setup

ARRAYS = "src/globe/inference/_arrays.h"  # the two inference kernels' argument checks

setup(ext_modules=[
    Extension("globe.models._suffix_automaton", ["src/globe/models/_suffix_automaton.c"]),
    Extension("globe.inference._beam", ["src/globe/inference/_beam.c"], depends=[ARRAYS]),
    Extension("globe.inference._propagate", ["src/globe/inference/_propagate.c"], depends=[ARRAYS]),
])
