import pytest

from globe.config import GlobeConfig, load_config
from globe.errors import ConfigError


def test_precedence_override_env_file_default(tmp_path):
    f = tmp_path / "g.toml"
    f.write_text("[gate]\nthreshold = 0.3\ntop_k = 4\n[llm]\nbackend = 'none'\n")
    env = {"GLOBE_GATE__TOP_K": "3", "GLOBE_GATE__MIN_PROB": "0.2"}
    cfg = load_config(f, {"gate.threshold": 0.25}, environ=env)
    assert cfg.gate.threshold == 0.25  # override beats file
    assert cfg.gate.top_k == 3  # env beats file
    assert cfg.gate.min_prob == 0.2  # env beats default
    assert cfg.llm.backend == "none"  # file beats default
    assert cfg.models.activity_max_order is GlobeConfig().models.activity_max_order is None  # the longest day


def test_invalid_values_name_the_field(tmp_path):
    with pytest.raises(ConfigError, match=r"gate\.top_k: .*got 0"):
        load_config(None, {"gate.top_k": 0}, environ={})
    with pytest.raises(ConfigError, match=r"gate\.colour: Extra inputs are not permitted"):
        load_config(None, {"gate.colour": "red"}, environ={})
    bad = tmp_path / "bad.toml"
    bad.write_text("[gate\n")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_config(bad, environ={})
