"""Only the optional C part of the build; everything else is in pyproject.toml.

``globe.models._suffix_automaton`` builds the suffix automata of the n-gram models in C (the same
automaton as the Python code, several times faster). It is optional: without a C compiler the
install goes on and GLOBE uses its Python loop.
"""

from setuptools import Extension, setup

setup(ext_modules=[Extension("globe.models._suffix_automaton", ["src/globe/models/_suffix_automaton.c"], optional=True)])
