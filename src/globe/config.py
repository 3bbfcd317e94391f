"""The one typed home of every tunable value (d, k, p_min, orders, backends, ...).

Precedence, applied by :func:`load_config`: explicit overrides (the CLI) > environment
(``GLOBE_<SECTION>__<FIELD>``) > TOML file > defaults. Only composition roots (CLI commands,
experiments, the service) read a :class:`GlobeConfig`; everything below takes plain arguments.
"""

from __future__ import annotations

import os
import tomllib
from pathlib import Path
from typing import Any, Literal, Mapping

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from globe.errors import ConfigError

Alignment = Literal["previous", "current", "hybrid"]
ActivityEstimator = Literal["persistence", "longest", "witten_bell", "routine"]
ObjectEstimator = Literal["longest", "witten_bell"]


class _Section(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


class DataConfig(_Section):
    root: Path | None = Field(None, description="HOMER+-style data folder; None = locate it")
    households: tuple[str, ...] = Field(("A", "B", "C"), description="households to use")


class SequenceConfig(_Section):
    alignment: Alignment = Field(
        "previous", description="which step's activity a movement at step t belongs to"
    )


class ModelConfig(_Section):
    activity_estimator: ActivityEstimator = Field(
        "longest", description="'longest' = the paper's longest-context backoff; 'persistence' = the activity stays the same"
    )
    activity_max_order: int = Field(109, ge=1, le=10_000, description="maximum n of the activity n-gram")
    object_estimator: ObjectEstimator = Field("longest", description="object n-gram estimator")
    object_max_order: int = Field(109, ge=1, le=10_000, description="maximum n of the object n-gram")
    run_start_token: bool = Field(
        False, description="condition the first object of a run on the run start (not in the paper)"
    )
    time_weight: float = Field(0.0, ge=0.0, le=10.0, description="exponent of the time-of-day expert P(a | step)")
    time_window: int = Field(2, ge=1, le=200, description="steps pooled on each side for the time-of-day expert")
    routine_order: int = Field(3, ge=1, le=100, description="routine model: order of the n-gram over activity runs")
    routine_time_weight: float = Field(1.0, ge=0.0, le=10.0, description="routine model: weight of P(start | step)")
    routine_time_window: int = Field(3, ge=1, le=200, description="routine model: steps pooled for the start prior")
    routine_shrinkage: float = Field(1.0, gt=0.0, le=1000.0, description="routine model: pseudo-count of the stay hazard")
    object_marginal: bool = Field(
        False, description="mix object predictions over the activity distribution instead of its argmax"
    )


class SelectionConfig(_Section):
    folds: int = Field(5, ge=2, le=65, description="cross-validation folds over training days")
    activity_orders: tuple[int, ...] = Field((2, 3, 4, 6), description="n-gram orders tried (witten_bell)")
    routine_orders: tuple[int, ...] = Field((2, 3, 4), description="run n-gram orders tried (routine)")
    time_weights: tuple[float, ...] = Field((0.0, 1.0, 2.0), description="time-of-day weights tried")
    object_estimators: tuple[str, ...] = Field(("longest", "witten_bell"), description="object estimators tried")
    run_start_token: tuple[bool, ...] = Field((False, True), description="run-start token settings tried")
    gate_thresholds: tuple[float, ...] = Field((0.25, 0.5), description="gate thresholds d tried")
    combine_weights: tuple[float, ...] = Field((1.0, 4.0), description="weights of n-gram log p tried (combine)")


class GateConfig(_Section):
    threshold: float = Field(0.5, ge=0.0, le=1.0, description="d: ask the LLM below this top probability")
    top_k: int = Field(5, ge=2, le=100, description="k: candidates sent to the LLM")
    min_prob: float = Field(0.1, ge=0.0, le=1.0, description="candidates need p above this")
    mode: Literal["replace", "combine"] = Field(
        "replace", description="'replace' = LLM picks; 'combine' = LLM score + n-gram log p"
    )
    combine_weight: float = Field(1.0, ge=0.0, le=100.0, description="weight of n-gram log p in 'combine'")
    examples: int = Field(0, ge=0, le=50, description="recent runs of the activity shown to the LLM (0 = the paper's prompt)")


class LLMConfig(_Section):
    backend: Literal["embedded", "remote", "none"] = Field("embedded", description="LLM backend")
    model_path: Path | None = Field(None, description="GGUF file; None = the packaged Gemma 3 270M")
    n_threads: int = Field(2, ge=1, le=256, description="llama.cpp threads (pin it: oversubscription is slow)")
    n_ctx: int = Field(512, ge=64, le=131072, description="llama.cpp context length")
    remote_model: str = Field("gpt-4.1", description="model name for the remote backend")
    base_url: str | None = Field(None, description="OpenAI-compatible base URL (else OPENAI_BASE_URL)")
    temperature: float = Field(0.5, ge=0.0, le=2.0, description="remote sampling temperature")
    max_tokens: int = Field(10, ge=1, le=4096, description="remote answer length limit")
    timeout_s: float = Field(30.0, gt=0, le=600, description="remote request timeout")
    max_retries: int = Field(2, ge=0, le=10, description="remote retries on connection errors")
    cache_dir: Path | None = Field(
        Path(".globe-cache"), description="on-disk answer cache; None disables it"
    )


class NoiseConfig(_Section):
    seed: int = Field(0, description="random seed of the generator")
    levels: tuple[float, ...] = Field((0.25, 0.5, 1.0), description="noise levels")
    rate: float = Field(0.35, ge=0.0, le=5.0, description="proposed disturbances per activity run")
    temperature: float = Field(2.0, gt=0.0, le=10.0, description="sampling temperature over LLM scores")
    types: tuple[Literal["person", "pet", "toddler"], ...] = Field(("person", "pet", "toddler"), description="noise types")
    train_level: float = Field(0.5, gt=0.0, le=1.0, description="noise level of the training days")
    test_level: float = Field(1.0, gt=0.0, le=1.0, description="noise level of the test days")
    thresholds: tuple[float, ...] = Field((0.25, 0.5, 0.75), description="gate thresholds d of the ablation")


class ServiceConfig(_Section):
    host: str = Field("127.0.0.1", description="bind address")
    port: int = Field(8765, ge=0, le=65535, description="TCP port")
    database: Path = Field(Path("globe.sqlite3"), description="SQLite file")
    action_threshold: float = Field(0.5, ge=0.0, le=1.0, description="fetch when object p >= this")
    day_start_minute: int = Field(360, ge=0, lt=1440, description="minute at which a new day begins")
    step_minutes: int = Field(10, ge=1, le=1440, description="minutes between observations (one step)")
    max_gap_steps: int = Field(36, ge=0, le=1000, description="longer gaps restart the day's history")


class EvaluationConfig(_Section):
    methods: tuple[str, ...] = Field(
        ("persistence", "ngram", "globe", "globe_combine", "globe_personal", "llm_only", "ngram_smoothed", "routine",
         "globe_routine"),
        description="Table I rows",
    )
    calibration_bins: int = Field(10, ge=2, le=100, description="bins of the reliability diagrams")
    personal_examples: int = Field(
        4, ge=1, le=50, description="recent runs shown to the LLM by the personalised rows (globe_personal, globe_routine)"
    )


class GlobeConfig(_Section):
    data: DataConfig = DataConfig()
    sequences: SequenceConfig = SequenceConfig()
    models: ModelConfig = ModelConfig()
    selection: SelectionConfig = SelectionConfig()
    gate: GateConfig = GateConfig()
    llm: LLMConfig = LLMConfig()
    noise: NoiseConfig = NoiseConfig()
    service: ServiceConfig = ServiceConfig()
    evaluation: EvaluationConfig = EvaluationConfig()

    def with_overrides(self, overrides: Mapping[str, Any]) -> "GlobeConfig":
        """Return a copy with dotted-key overrides (``{"gate.threshold": 0.25}``) applied."""
        return _build(_merge(self.model_dump(), _nest(overrides)))


ENV_PREFIX = "GLOBE_"


def _nest(flat: Mapping[str, Any]) -> dict[str, Any]:
    nested: dict[str, Any] = {}
    for key, value in flat.items():
        if value is None:
            continue
        parts = key.split(".")
        node = nested
        for part in parts[:-1]:
            node = node.setdefault(part, {})
        node[parts[-1]] = value
    return nested


def _merge(base: dict[str, Any], extra: Mapping[str, Any]) -> dict[str, Any]:
    out = dict(base)
    for key, value in extra.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), dict):
            out[key] = _merge(out[key], value)
        else:
            out[key] = value
    return out


def _env_overrides(environ: Mapping[str, str]) -> dict[str, Any]:
    """``GLOBE_GATE__THRESHOLD=0.25`` -> ``{"gate": {"threshold": "0.25"}}``."""
    flat = {}
    for name, value in environ.items():
        if name.startswith(ENV_PREFIX) and "__" in name:
            section, _, field = name[len(ENV_PREFIX):].lower().partition("__")
            flat[f"{section}.{field}"] = value
    return _nest(flat)


def _build(values: Mapping[str, Any], source: str = "configuration") -> GlobeConfig:
    try:
        return GlobeConfig.model_validate(values)
    except ValidationError as err:
        lines = [
            f"{'.'.join(str(p) for p in e['loc'])}: {e['msg']} (got {e.get('input')!r})"
            for e in err.errors()
        ]
        raise ConfigError(f"invalid {source}:\n  " + "\n  ".join(lines)) from err


def load_config(
    path: Path | None = None,
    overrides: Mapping[str, Any] | None = None,
    environ: Mapping[str, str] | None = None,
) -> GlobeConfig:
    """Resolve the configuration: overrides > environment > TOML file > defaults."""
    values: dict[str, Any] = {}
    source = "configuration"
    if path is not None:
        try:
            values = tomllib.loads(Path(path).read_text(encoding="utf-8"))
        except FileNotFoundError as err:
            raise ConfigError(f"{path}: configuration file not found") from err
        except tomllib.TOMLDecodeError as err:
            raise ConfigError(f"{path}: not valid TOML: {err}") from err
        source = str(path)
    values = _merge(values, _env_overrides(os.environ if environ is None else environ))
    values = _merge(values, _nest(overrides or {}))
    return _build(values, source)
