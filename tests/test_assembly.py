"""Every gate and model setting reaches the objects that run, through the real command line.

For each field of the ``gate`` and ``models`` sections a non-default value is set in the
environment (as a user would: ``GLOBE_GATE__THRESHOLD=...``), ``globe evaluate`` runs with the
real embedded LLM (on HOMER+ B, one of its test days; the gate's and the n-gram's fields in one
run), and ``built.json`` (read from the built
objects, not from the config) must show it. The service side of the same check lives in ``tests/service``.
"""

import json
import os
import subprocess
import sys

import pytest

from globe.config import GateConfig, ModelConfig
from globe.data.locate import household_dir

# config field -> (non-default value as the environment spells it, part of built.json, key, expected value)
GATE = {
    "threshold": ("0.35", "chooser", "threshold", 0.35),
    "top_k": ("3", "chooser", "top_k", 3),
    "min_prob": ("0.05", "chooser", "min_prob", 0.05),
    "mode": ("combine", "chooser", "mode", "combine"),
    "combine_weight": ("2.5", "chooser", "combine_weight", 2.5),
    "examples": ("3", "chooser", "examples", 3),
}
NGRAM_MODELS = {
    "activity_estimator": ("witten_bell", "activity", "estimator", "witten_bell"),
    "activity_max_order": ("5", "activity", "max_order", 5),
    "time_weight": ("1.5", "activity", "time_weight", 1.5),
    "time_window_minutes": ("40", "activity", "time_window", 4),  # HOMER+'s steps are 10 minutes
    "object_estimator": ("witten_bell", "objects", "estimator", "witten_bell"),
    "object_max_order": ("7", "objects", "max_order", 7),
    "run_start_token": ("true", "objects", "run_start_token", True),
    "object_marginal": ("true", "chooser", "marginal", True),
    "stay_margin": ("2.5", "activity", "stay_margin", 2.5),
}
ROUTINE_MODELS = {
    "activity_estimator": ("routine", "activity", "kind", "RoutineModel"),
    "routine_order": ("2", "activity", "order", 2),
    "routine_time_weight": ("0.5", "activity", "time_weight", 0.5),
    "routine_time_window_minutes": ("50", "activity", "time_window", 5),
    "routine_duration_cap_minutes": ("200", "activity", "duration_cap", 20),
    "routine_shrinkage": ("3.0", "activity", "shrinkage", 3.0),
}
CLOCK_MODELS = {
    "activity_estimator": ("clock", "activity", "kind", "ClockModel"),
    "clock_slot_minutes": ("30", "activity", "slot_minutes", 30),
    "clock_shrinkage": ("2.5", "activity", "shrinkage", 2.5),
    "clock_day_types": ("weekend", "activity", "day_types", "weekend"),
    "clock_floor": ("0.02", "activity", "floor", 0.02),
    "clock_by_activity": ("false", "activity", "by_activity", False),
    "object_model": ("hour_activity", "objects", "kind", "HourActivityObjects"),
}


def test_every_field_is_covered():
    assert set(GATE) == set(GateConfig.model_fields)
    assert set(NGRAM_MODELS) | set(ROUTINE_MODELS) | set(CLOCK_MODELS) == set(ModelConfig.model_fields)
    for table, section in ((GATE, GateConfig()), (NGRAM_MODELS, ModelConfig()), (ROUTINE_MODELS, ModelConfig()),
                           (CLOCK_MODELS, ModelConfig())):
        for field, (_, _, _, expected) in table.items():
            if field != "activity_estimator":
                assert getattr(section, field) != expected, f"{field}: the test value must differ from the default"


@pytest.fixture(scope="module")
def one_test_day(homer_root, tmp_path_factory):
    """HOMER+ household B with all its training days and its first test day (links to the real
    files): what is built comes from the training days and the settings, and one test day still
    asks the LLM, in a tenth of the time of all ten."""
    home = household_dir(homer_root, "B")
    copy = tmp_path_factory.mktemp("data") / home.name
    (copy / "test").mkdir(parents=True)
    (copy / "nodes.csv").symlink_to(home / "nodes.csv")
    (copy / "train").symlink_to(home / "train", target_is_directory=True)
    for day in sorted((home / "test").glob("*.csv"))[:1]:
        (copy / "test" / day.name).symlink_to(day)
    return copy.parent


def _built(tmp_path, data, tables: dict, extra_env: dict) -> dict:
    env = dict(os.environ, **extra_env, GLOBE_LLM__CACHE_DIR=str(tmp_path / "cache"))
    for section, table in tables.items():
        env |= {f"GLOBE_{section.upper()}__{k.upper()}": v for k, (v, *_) in table.items()}
    res = subprocess.run([sys.executable, "-m", "globe", "evaluate", "--methods", "globe", "--households", "B",
                          "--no-activity-ahead", "--data", str(data), "--out", str(tmp_path)], capture_output=True,
                         text=True, env=env,
                         timeout=900)
    assert res.returncode == 0, res.stderr
    return json.loads((tmp_path / "built.json").read_text())["globe"]["B"]


@pytest.mark.llm
@pytest.mark.slow
@pytest.mark.parametrize("tables", [{"gate": GATE, "models": NGRAM_MODELS}, {"models": ROUTINE_MODELS},
                                    {"models": CLOCK_MODELS}],
                         ids=["gate-and-ngram-models", "routine-models", "clock-models"])
def test_settings_reach_the_built_objects_through_globe_evaluate(tmp_path, one_test_day, tables):
    built = _built(tmp_path, one_test_day, tables, {"GLOBE_LLM__BACKEND": "embedded"})
    assert built["chooser"]["kind"] == "globe" and built["chooser"]["backend"] == "embedded"
    for section, table in tables.items():
        for field, (_, part, key, expected) in table.items():
            assert built[part][key] == expected, f"{section}.{field} did not reach {part}.{key}: {built[part]}"
