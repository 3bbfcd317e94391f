"""Only the optional C part of the build; everything else is in pyproject.toml.

``globe.models._suffix_automaton`` builds the suffix automata of the n-gram models, and
``globe.service._day_fields`` splits uploaded day texts into their cells: both in C, with the
same results as the Python code, several times faster. Both are optional: without a C compiler
the install goes on and GLOBE uses its Python code.
"""

from setuptools import Extension, setup

setup(ext_modules=[
    Extension("globe.models._suffix_automaton", ["src/globe/models/_suffix_automaton.c"], optional=True),
    Extension("globe.service._day_fields", ["src/globe/service/_day_fields.c"], optional=True),
])
