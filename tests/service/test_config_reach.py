"""Every field of the ``gate`` and ``models`` sections, set through the environment, reaches the
objects built for a household served by ``globe serve`` with the real embedded backend: read
back from the built objects (``/stats``), not from the configuration."""

import pytest

from globe.config import GateConfig, ModelConfig
from tests.service.conftest import REPLAY_ENV, at, upload, wait_for_llm

pytestmark = pytest.mark.service

# field -> (environment value, where /stats shows it, the value expected there)
GATE = {
    "threshold": ("0.9", ("chooser", "threshold"), 0.9),
    "top_k": ("3", ("chooser", "top_k"), 3),
    "min_prob": ("0.05", ("chooser", "min_prob"), 0.05),
    "mode": ("combine", ("chooser", "mode"), "combine"),
    "combine_weight": ("2.5", ("chooser", "combine_weight"), 2.5),
    "examples": ("3", ("chooser", "examples"), 3),
}
NGRAM = {  # the n-gram activity model's fields (activity_estimator != routine)
    "activity_estimator": ("witten_bell", ("models", "activity", "estimator"), "witten_bell"),
    "activity_max_order": ("7", ("models", "activity", "max_order"), 7),
    "time_weight": ("1.5", ("models", "activity", "time_weight"), 1.5),
    "time_window_minutes": ("40", ("models", "activity", "time_window"), 4),  # 10-minute steps
    "object_estimator": ("witten_bell", ("models", "objects", "estimator"), "witten_bell"),
    "object_max_order": ("5", ("models", "objects", "max_order"), 5),
    "run_start_token": ("true", ("models", "objects", "run_start_token"), True),
    "object_marginal": ("true", ("chooser", "marginal"), True),
    "stay_margin": ("2.5", ("models", "activity", "stay_margin"), 2.5),
}
ROUTINE = {  # the routine model's fields
    "activity_estimator": ("routine", ("models", "activity", "kind"), "RoutineModel"),
    "routine_order": ("4", ("models", "activity", "order"), 4),
    "routine_time_weight": ("0.5", ("models", "activity", "time_weight"), 0.5),
    "routine_time_window_minutes": ("50", ("models", "activity", "time_window"), 5),
    "routine_duration_cap_minutes": ("200", ("models", "activity", "duration_cap"), 20),
    "routine_shrinkage": ("2.0", ("models", "activity", "shrinkage"), 2.0),
}
CLOCK = {  # the clock model's fields
    "activity_estimator": ("clock", ("models", "activity", "kind"), "ClockModel"),
    "clock_slot_minutes": ("30", ("models", "activity", "slot_minutes"), 30),
    "clock_shrinkage": ("2.5", ("models", "activity", "shrinkage"), 2.5),
    "clock_day_types": ("weekend", ("models", "activity", "day_types"), "weekend"),
    "clock_floor": ("0.02", ("models", "activity", "floor"), 0.02),
    "clock_by_activity": ("false", ("models", "activity", "by_activity"), False),
    "object_model": ("hour_activity", ("models", "objects", "kind"), "HourActivityObjects"),
}


def test_every_gate_and_models_field_is_covered():
    assert set(GATE) == set(GateConfig.model_fields)
    assert set(NGRAM) | set(ROUTINE) | set(CLOCK) == set(ModelConfig.model_fields)
    for table, section in ((GATE, GateConfig()), (NGRAM, ModelConfig()), (ROUTINE, ModelConfig()),
                           (CLOCK, ModelConfig())):
        for field, (_, _, expected) in table.items():
            if field != "activity_estimator" or table is NGRAM:
                assert getattr(section, field) != expected, field  # a non-default value


def env_for(section: str, table: dict) -> dict[str, str]:
    return {f"GLOBE_{section.upper()}__{field.upper()}": value for field, (value, _, _) in table.items()}


@pytest.mark.parametrize("models", [NGRAM, ROUTINE, CLOCK], ids=["ngram", "routine", "clock"])
def test_environment_reaches_the_served_objects(make_server, households, tmp_path, models):
    env = {**REPLAY_ENV, "GLOBE_LLM__BACKEND": "embedded", "GLOBE_LLM__N_THREADS": "1",
           "GLOBE_LLM__CACHE_DIR": str(tmp_path / "llm-cache"), **env_for("gate", GATE), **env_for("models", models)}
    srv = make_server(env)
    h = households["A"]
    with srv.client() as c:
        upload(c, "A", h)
        wait_for_llm(srv.url)  # the model loads in the background; meanwhile predictions fall back
        day = h.test[0]
        consulted = 0
        for t in range(40):
            c.observe("A", at(0, day.minutes[t]), day.activities[t], dict(zip(h.objects, day.locations[t])))
            if t >= 25:
                consulted += c.prediction("A").llm_consulted
        stats = c.stats("A")
        for field, (_, path, expected) in {**GATE, **models}.items():
            value = stats
            for key in path:
                value = value[key]
            assert value == expected, (field, path, value)
        assert stats["chooser"]["kind"] == "globe" and stats["chooser"]["backend"] == "embedded"
        assert consulted > 0 and c.stats("A")["llm_fallbacks"] == {}  # the real model answered prompts with examples
