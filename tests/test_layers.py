"""The package reads as the data flow: no module imports from a layer above its own, and every
estimator's defaults are the configuration's."""

from __future__ import annotations

import ast
import inspect
from pathlib import Path

import pytest

import globe

LAYERS = ("config", "errors", "data", "sequences", "models", "inference", "recognition", "reasoning", "noise",
          "assembly", "session", "evaluation", "service", "cli")
"""From the bottom up: a module may import its own layer and those below (config and errors from anywhere)."""


def _imports(path: Path) -> set[str]:
    """Every globe module ``path`` imports, at the top or inside functions."""
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found |= {node.module, *(f"{node.module}.{a.name}" for a in node.names)}
        elif isinstance(node, ast.Import):
            found |= {a.name for a in node.names}
    return {name for name in found if name.startswith("globe.")}


def test_no_module_imports_from_a_layer_above_its_own():
    root = Path(globe.__file__).parent
    upward = []
    for path in sorted(root.rglob("*.py")):
        parts = path.relative_to(root).with_suffix("").parts
        if parts[0] not in LAYERS:
            continue
        mine = LAYERS.index(parts[0])
        for name in _imports(path):
            layer = name.split(".")[1]
            if layer in LAYERS and LAYERS.index(layer) > mine and layer not in ("config", "errors"):
                upward.append(f"{'/'.join(parts)} imports {name}")
    assert not upward, "\n".join(upward)
    assert len(list(root.rglob("*.py"))) > 50  # the walk saw the package


def _default(cls: type, name: str):
    return inspect.signature(cls).parameters[name].default


@pytest.mark.parametrize("cls_path, params, section", [
    ("globe.models.activity:ActivityModel",
     {"estimator": "activity_estimator", "max_order": "activity_max_order", "time_weight": "time_weight",
      "time_window": "time_window_minutes"}, "models"),
    ("globe.models.routine:RoutineModel",
     {"order": "routine_order", "time_weight": "routine_time_weight", "time_window": "routine_time_window_minutes",
      "shrinkage": "routine_shrinkage", "duration_cap": "routine_duration_cap_minutes"}, "models"),
    ("globe.models.objects:ObjectModel", {"estimator": "object_estimator", "max_order": "object_max_order",
                                          "run_start_token": "run_start_token"}, "models"),
    ("globe.inference.emission:MovementEmission",
     {"smoothing": "emission_smoothing", "weight": "emission_weight", "previous_share": "emission_previous_share",
      "boundary": "emission_boundary", "switch": "emission_switch"}, "filter"),
    ("globe.inference.activity_filter:ActivityFilter", {"max_hypotheses": "max_hypotheses", "min_weight": "min_weight"},
     "filter"),
    ("globe.inference.movements:MovementModel",
     {"hazard_shrinkage": "hazard_shrinkage", "duration_cap": "duration_cap_minutes",
      "destination_shrinkage": "destination_shrinkage"}, "lookahead"),
    ("globe.inference.forecast:Forecaster", {"min_path_probability": "min_path_probability", "max_paths": "max_paths"},
     "lookahead"),
    ("globe.inference.fetch_policy:FetchPolicy", {"cost_useless": "cost_useless", "cost_missed": "cost_missed",
                                                  "max_fetches_per_step": "max_fetches_per_step"}, "policy"),
    ("globe.reasoning.gate:UncertaintyGate",
     {"threshold": "threshold", "top_k": "top_k", "min_prob": "min_prob", "mode": "mode",
      "combine_weight": "combine_weight", "examples": "examples"}, "gate"),
])
def test_estimator_defaults_are_the_configuration_defaults(cls_path, params, section):
    """Built without the configuration (a test, a user's script), an estimator behaves as the
    configured one: every default equals its configuration field's."""
    import importlib

    from globe.assembly import steps
    from globe.config import GlobeConfig

    module, name = cls_path.split(":")
    cls = getattr(importlib.import_module(module), name)
    configured = getattr(GlobeConfig(), section)
    for param, field in params.items():
        value = getattr(configured, field)
        if field.endswith("_minutes"):  # the estimators count steps: the default is 10 minutes' worth
            value = steps(value, 10)
        assert _default(cls, param) == value, f"{name}({param}=...) vs {section}.{field}"


def test_no_source_file_is_over_600_lines():
    """Small modules with one job: a file past 600 lines is split (issue 22's rule)."""
    root = Path(__file__).resolve().parents[1] / "src" / "globe"
    sizes = {str(p.relative_to(root)): len(p.read_text(encoding="utf-8").splitlines()) for p in root.rglob("*.py")}
    long = {name: n for name, n in sizes.items() if n > 600}
    assert not long, long
    assert len(sizes) > 50
