# Two commands on a fresh machine: `make reproduce` (the main job) and `make test` (the checks).
# Both create .venv and install the project with every extra on first use (and again when
# pyproject.toml changes); the plain pip route is in the README. llama-cpp-python is compiled
# once per machine kind for one instruction set, x86-64-v3 where the CPU has it, into $(WHEELS)
# (tools/llama_wheel.py says why), and installed by it.

PYTHON ?= python3
VENV ?= .venv
OUT ?= results/reproduce
WHEELS ?= .wheels
STAMP := $(VENV)/.installed

.PHONY: setup reproduce test lint typecheck

setup: $(STAMP)

$(STAMP): pyproject.toml setup.py $(wildcard src/globe/*/*.c) tools/llama_wheel.py
	test -x $(VENV)/bin/python || $(PYTHON) -m venv $(VENV)
	$(VENV)/bin/python tools/llama_wheel.py $(WHEELS)
	$(VENV)/bin/python -m pip install -e ".[all,dev,docs]"
	touch $(STAMP)

reproduce: $(STAMP)
	$(VENV)/bin/globe reproduce --out $(OUT)

typecheck: $(STAMP)
	$(VENV)/bin/mypy

lint: $(STAMP)
	$(VENV)/bin/ruff check src tests benchmarks tools

test: $(STAMP) typecheck lint
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict -q -d site
	$(VENV)/bin/python -m pytest
