"""The one typed home of every tunable value (d, k, p_min, orders, backends, ...).

Precedence, applied by :func:`load_config`: explicit overrides (the CLI) > environment
(``GLOBE_<SECTION>__<FIELD>``) > TOML file > defaults. Only composition roots (CLI commands,
experiments, the service) read a :class:`GlobeConfig`; everything below takes plain arguments.
"""

from __future__ import annotations

import datetime as dt
import os
import tomllib
from pathlib import Path
from typing import Annotated, Any, Literal, Mapping

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from globe.errors import ConfigError

Alignment = Literal["previous", "current", "hybrid", "most"]
ActivityEstimator = Literal["persistence", "longest", "witten_bell", "routine", "clock"]
ObjectEstimator = Literal["longest", "witten_bell"]
ObjectModelKind = Literal["ngram", "hour_activity"]
DayTypes = Literal["none", "weekend", "weekday"]
DEFAULT_STEP_MINUTES = 10  # a household created without days (HOMER+'s step)
DEFAULT_DAY_START = 360  # 06:00, HOMER+'s first row
DeployMethod = Literal["routine", "ngram_smoothed", "ngram", "persistence"]
CV_METHODS: dict[str, str] = {"routine": "routine", "ngram_smoothed": "witten_bell"}  # deployed by CV: its family


class _Section(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


from globe.config.mqtt import MqttConfig, MqttHousehold, MqttObject  # noqa: E402 F401 - sections built on _Section


class DataConfig(_Section):
    root: Path | None = Field(None, description="HOMER+-style data folder; None = locate it")
    households: tuple[str, ...] | None = Field(
        None, min_length=1, description="households to use; None = every household folder of the data folder "
        "(one with a nodes.csv), by name (HOMER+'s HouseholdA... as A, B, C)")
    step_minutes: int | None = Field(
        None, ge=1, le=1440, description="minutes between a day's rows; None = the household's most common gap"
    )
    resample: Literal["none", "locf"] = Field(
        "none", description="rows off the step: 'none' = an error; 'locf' = resample to the step grid, last "
        "observation carried forward"
    )


class SequenceConfig(_Section):
    alignment: Alignment = Field(
        "previous", description="which step's activity a movement at step t belongs to: 'previous' (t-1), 'current' "
        "(t), 'hybrid' (t-1 unless idle) or 'most' (the activity covering most of step t, from an imported day's "
        "covering column; else as 'current')"
    )


class ModelConfig(_Section):
    activity_estimator: ActivityEstimator = Field(
        "longest",
        description="'longest' = the paper's longest-context backoff; 'persistence' = the activity stays the same",
    )
    activity_max_order: int | None = Field(
        None, ge=1, le=10_000, description="maximum n of the activity n-gram; None = the longest training day "
        "(109 on HOMER+'s 10-minute days, the paper's n), whatever the step")
    object_model: ObjectModelKind = Field(
        "ngram", description="'ngram' = the paper's per-activity object n-gram over the run's objects; 'hour_activity' "
        "= the object baseline, the most frequent use given the clock hour and the activity (the run's earlier "
        "objects unread)")
    object_estimator: ObjectEstimator = Field("longest", description="object n-gram estimator")
    object_max_order: int = Field(109, ge=1, le=10_000, description="maximum n of the object n-gram")
    run_start_token: bool = Field(
        False, description="condition the first object of a run on the run start (not in the paper)"
    )
    time_weight: float = Field(0.0, ge=0.0, le=10.0, description="exponent of the time-of-day expert P(a | step)")
    time_window_minutes: int = Field(
        20, ge=1, le=1440, description="minutes pooled on each side for the time-of-day expert (at least one step)")
    routine_order: int = Field(3, ge=1, le=100, description="routine model: order of the n-gram over activity runs")
    routine_time_weight: float = Field(1.0, ge=0.0, le=10.0, description="routine model: weight of P(start | step)")
    routine_time_window_minutes: int = Field(
        30, ge=1, le=1440, description="routine model: minutes pooled for the start prior (at least one step)")
    routine_duration_cap_minutes: int = Field(
        300, ge=1, le=1440, description="routine model: run durations longer than this share one stay hazard")
    routine_shrinkage: float = Field(
        1.0, gt=0.0, le=1000.0, description="routine model: pseudo-count of the stay hazard")
    clock_slot_minutes: int = Field(60, ge=1, le=1440, description="clock model: width of a time-of-day slot (minutes)")
    clock_shrinkage: float = Field(
        5.0, gt=0.0, le=1000.0, description="clock model: pseudo-count pulling a slot toward the time-free bigram"
    )
    clock_floor: float = Field(
        0.0, ge=0.0, lt=1.0, description="clock model: share of the add-one unigram mixed into every row, so no "
        "transition gets less than that share of its back-off")
    clock_day_types: DayTypes = Field(
        "none", description="clock model: which days of the week it tells apart ('weekend': Monday to Friday and the "
        "weekend; 'weekday': each day; days named by their date only), each shrunk toward every day's slot")
    clock_by_activity: bool = Field(
        True, description="clock model: the next activity depends on the current one (False: on the time of day "
        "alone, the time-of-day baseline as a model that cross-validation can deploy)")
    object_marginal: bool = Field(
        False, description="mix object predictions over the activity distribution instead of its argmax"
    )
    stay_margin: float = Field(
        1.0, ge=1.0, le=1e6, description="the next activity is said to change only when the likeliest other activity "
        "is at least this many times as probable as staying (1: the plain argmax); the probabilities are the model's "
        "either way (chosen by cross-validation on weighted F1: selection.stay_margins)")


class SelectionConfig(_Section):
    folds: int = Field(5, ge=2, le=65, description="cross-validation folds over training days")
    criterion: Literal["log_loss", "f1"] = Field(
        "log_loss", description="what chooses the routine family's activity model (routine, clock, persistence): "
        "held-out log loss (a proper scoring rule: a model sure of what does not happen pays for it, as persistence "
        "does at every change) or weighted F1; both are reported"
    )
    ngram_criterion: Literal["log_loss", "f1"] = Field(
        "f1", description="what chooses the smoothed n-gram's settings (row ngram_smoothed, compared with the paper's "
        "F1 rows): weighted F1 by default; the routine family (the models for real homes) follows 'criterion'"
    )
    object_criterion: Literal["log_loss", "f1"] = Field(
        "f1", description="what chooses the object model: weighted F1 of the object picked (the protocol scores a pick "
        "among the predicted activity's objects, so its log loss mostly counts the activity's mistakes); both are "
        "reported"
    )
    activity_orders: tuple[int, ...] = Field((2, 3, 4, 6), description="n-gram orders tried (witten_bell)")
    routine_orders: tuple[int, ...] = Field((2, 3, 4), description="run n-gram orders tried (routine)")
    time_weights: tuple[float, ...] = Field((0.0, 1.0, 2.0), description="time-of-day weights tried")
    stay_margins: tuple[float, ...] = Field(
        (1.0, 1.25, 1.5, 2.0, 3.0, 5.0, 1e6), description="routine family: stay margins (models.stay_margin) tried "
        "after the models, on weighted F1 of the next activity (the first wins ties; 1e6: never predict a change)")
    clock_slots: tuple[int, ...] = Field((30, 60, 120), description="clock model: slot widths tried (minutes; a "
                                         "choice at an edge widens the grid)")
    clock_floors: tuple[float, ...] = Field(
        (0.0, 0.001, 0.003, 0.01, 0.03), description="clock model: back-off floors (models.clock_floor) tried on the "
        "chosen clock model, by log loss (the first wins ties)")
    clock_shrinkages: tuple[float, ...] = Field((2.0, 10.0), description="clock model: shrinkage pseudo-counts tried")
    clock_day_types: tuple[DayTypes, ...] = Field(
        ("none", "weekend", "weekday"), description="clock model: day types tried where at least day_types_min_days "
        "training days are named by their date")
    day_types_min_days: int = Field(
        14, ge=7, le=3660, description="training days named by distinct dates before day types are tried")
    object_estimators: tuple[str, ...] = Field(("longest", "witten_bell"), description="object estimators tried")
    object_models: tuple[ObjectModelKind, ...] = Field(
        ("ngram", "hour_activity"), description="object models tried: the n-gram (with each estimator and run-start "
        "setting) and the object baseline beside it, by selection.object_criterion")
    alignments: tuple[Alignment, ...] = Field(
        ("previous", "current", "hybrid", "most"), description="routine family: movement alignments tried after the "
        "models (sequences.alignment first, winning ties; one value = no search; 'most' only where every training day "
        "has a covering column, as imported days do)")
    run_start_token: tuple[bool, ...] = Field((False, True), description="run-start token settings tried")
    deploy: DeployMethod = Field(
        "routine", description="what globe train, globe household import and POST /households run for a household: "
        "'routine' (the routine family chosen by cross-validation on its training days, persistence and the clock "
        "model among the candidates, as globe evaluate's routine row), 'ngram_smoothed' (the smoothed n-gram, chosen "
        "the same way), 'ngram' (the paper's n-gram, the [models] section as written) or 'persistence'")
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
    examples: int = Field(
        0, ge=0, le=50, description="recent runs of the activity shown to the LLM (0 = the paper's prompt)"
    )


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
    levels: tuple[Annotated[float, Field(gt=0.0, le=1.0)], ...] = Field(
        (0.25, 0.5, 1.0), description="noise levels: fractions in (0, 1] of the generated noise"
    )
    rate: float = Field(0.35, ge=0.0, le=5.0, description="proposed disturbances per activity run")
    temperature: float = Field(2.0, gt=0.0, le=10.0, description="sampling temperature over LLM scores")
    types: tuple[Literal["person", "pet", "toddler"], ...] = Field(
        ("person", "pet", "toddler"), description="noise types"
    )
    train_level: float = Field(0.5, gt=0.0, le=1.0, description="noise level of the training days")
    test_level: float = Field(1.0, gt=0.0, le=1.0, description="noise level of the test days")
    thresholds: tuple[float, ...] = Field((0.25, 0.5, 0.75), description="gate thresholds d of the ablation")


class ServiceConfig(_Section):
    host: str = Field("127.0.0.1", description="bind address")
    port: int = Field(8765, ge=0, le=65535, description="TCP port")
    database: Path = Field(Path("globe.sqlite3"), description="SQLite file")
    day_start_minute: int | None = Field(
        None, ge=0, lt=1440, description="minute at which a household's day begins; None = its days' own (their first "
        "row; 06:00 for a household created without days). A value that disagrees with a household's days is an "
        "error when it is built, never a silent re-slicing")
    step_minutes: int | None = Field(
        None, ge=1, le=1440, description="minutes between a household's steps; None = its days' own (their most common "
        "gap; 10 for a household created without days). A value that disagrees with a household's days is an error "
        "when it is built")
    new_activities: Literal["auto", "refuse", "learn"] = Field(
        "auto", description="an activity a household has never seen: 'refuse' it (the known ones are listed), 'learn' "
        "it, or 'auto': refuse where the household was created with training days, learn where it starts from none")
    questions_per_day: int = Field(
        5, ge=0, le=1000, description="a household with sensors may ask the person 'what are you doing?' this many "
        "times a day, where the recognised activity is least sure (0: never)")
    max_clock_skew: dt.timedelta = Field(
        dt.timedelta(days=1), ge=dt.timedelta(0), le=dt.timedelta(days=36500),
        description="ISO 8601 duration (P1D, PT6H): times this far ahead of the server clock or before creation "
                    "minus this are refused",
    )
    max_ahead: dt.timedelta = Field(
        dt.timedelta(minutes=10), ge=dt.timedelta(0), le=dt.timedelta(days=36500),
        description="observations further ahead of the server clock than this (within max_clock_skew) are stored and "
                    "acknowledged but held pending until the clock is within this of them, so a glitched clock cannot "
                    "lock a household",
    )
    timezone: str | None = Field(None, description="default IANA time zone of new households; None = the server's")
    allowed_hosts: tuple[str, ...] = Field(
        ("127.0.0.1", "localhost", "::1"), description="Host header names accepted (DNS-rebinding guard); '*' = any"
    )
    cors_origins: tuple[str, ...] = Field((), description="browser origins allowed by CORS (none by default)")
    max_body_bytes: int = Field(1 << 20, ge=1024, le=1 << 30, description="request body limit (413 above it)")
    max_household_bytes: int = Field(
        32 << 20, ge=1024, le=1 << 31, description="body limit of POST /households (a map plus its training logs)"
    )
    max_header_bytes: int = Field(
        64 << 10, ge=1024, le=16 << 20,
        description="request line and headers limit (431 above it, before anything is parsed)",
    )
    header_timeout_s: float = Field(
        10.0, gt=0, le=3600, description="a connection's request line and headers must arrive within this (else closed)"
    )
    body_timeout_s: float = Field(60.0, gt=0, le=3600, description="a request body must arrive within this (else 408)")
    max_concurrent_creations: int = Field(
        2, ge=1, le=1000,
        description="POST /households read and built at once; more wait their turn (memory stays bounded)",
    )
    max_label_length: int = Field(128, ge=8, le=4096, description="longest activity, object, location or id label")
    max_locations: int = Field(512, ge=1, le=100_000, description="most object locations in one observation")
    max_nodes: int = Field(5000, ge=1, le=1_000_000, description="most nodes in a household's map")
    max_days: int = Field(1000, ge=0, le=100_000, description="most training days uploaded with a household")
    max_households: int = Field(1000, ge=1, le=1_000_000, description="most households one service holds")
    preload: bool = Field(
        True, description="build stored households in the background after start-up (else on first use)"
    )
    llm_timeout_s: float = Field(
        5.0, gt=0, le=600, description="time limit of the embedded LLM's answer to one prediction (past it, and while "
                                       "the model loads in the background after start-up, the n-gram choice is used)",
    )
    max_built_households: int = Field(
        64, ge=1, le=1_000_000, description="households kept built in memory; the least recently used are rebuilt "
        "from the database on demand"
    )
    session_minutes: int = Field(
        480, ge=1, le=60 * 24 * 30, description="a dashboard login lasts this long (then the token is asked again)"
    )
    dashboard_refresh_s: int = Field(
        30, ge=0, le=3600, description="how often an open dashboard page refreshes its live part (0: never)"
    )


class EvaluationConfig(_Section):
    methods: tuple[str, ...] = Field(
        ("persistence", "ngram", "globe", "globe_combine", "globe_personal", "llm_only", "ngram_smoothed", "routine",
         "globe_routine"),
        description="Table I rows",
    )
    calibration_bins: int = Field(10, ge=2, le=100, description="bins of the reliability diagrams")
    personal_examples: int = Field(
        4, ge=1, le=50,
        description="recent runs shown to the LLM by the personalised rows (globe_personal, globe_routine)",
    )
    workers: int | None = Field(
        None, ge=1, le=256, description="processes for the LLM-free work of the main job: cross-validations, "
        "lookahead, missing labels (None = one per core)"
    )


class LookaheadConfig(_Section):
    horizon_minutes: int = Field(
        60, ge=1, le=1440, description="how far ahead the lookahead looks: every step up to this many minutes")
    first_reference: int = Field(1, ge=1, le=100_000, description="first reference step r of the lookahead evaluation")
    last_reference: int | None = Field(
        None, ge=1, le=100_000,
        description="last reference step r; None = the last that keeps the horizon inside the day")
    min_path_probability: float = Field(
        1e-3, ge=0.0, lt=1.0, description="activity paths less likely than this are pruned from the forward pass"
    )
    max_paths: int = Field(64, ge=1, le=10_000, description="most activity paths kept per step of the forward pass")
    hazard_shrinkage: float = Field(
        2.0, gt=0.0, le=1000.0, description="pseudo-count shrinking each movement-hazard level towards the coarser one"
    )
    duration_cap_minutes: int = Field(
        80, ge=1, le=1440, description="minutes into an activity run told apart by the movement hazard")
    destination_shrinkage: float = Field(
        1.0, gt=0.0, le=1000.0,
        description="pseudo-count shrinking P(target | activity, object, source) to coarser levels",
    )
    thresholds: tuple[float, ...] = Field(
        (0.5, 0.4, 0.3, 0.25, 0.2, 0.15),
        description="change thresholds tried by cross-validation on training days, per horizon (first wins ties)"
    )
    methods: tuple[str, ...] = Field(("persistence", "ngram", "routine"), description="activity models forecast with")
    run_end: tuple[bool, ...] = Field(
        (False, True),
        description="condition movement hazards on the activity ending there: settings tried by CV (first wins ties)",
    )
    run_memory: tuple[bool, ...] = Field(
        (False, True), description="also on the object having moved earlier in the run (with run_end only): tried by CV"
    )
    run_next: tuple[bool, ...] = Field(
        (False, True), description="at a run's end also on the activity that starts (with run_end only): tried by CV"
    )
    cv_stride: int = Field(
        3, ge=1, le=100, description="cross-validation scores every n-th reference step (it only sets a threshold)"
    )


class PolicyConfig(_Section):
    cost_useless: float = Field(
        3.0, ge=0.0, le=1e6, description="cost of fetching an object that is not used in the window"
    )
    cost_missed: float = Field(1.0, ge=0.0, le=1e6, description="cost of a need the robot did not anticipate")
    min_lead_minutes: int = Field(10, ge=0, le=1440, description="a fetch must come at least this long before the use")
    lead_window_minutes: int = Field(
        60, ge=10, le=1440, description="a fetch counts for uses within this long after it"
    )
    max_fetches_per_step: int = Field(2, ge=1, le=100, description="most fetches the robot starts in one step")
    method: Literal["persistence", "ngram", "routine"] = Field(
        "routine", description="activity model the policy forecasts with ('routine': chosen by CV on training days)"
    )
    curve_ratios: tuple[float, ...] = Field(
        (0.1, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 9.0, 19.0),
        description="cost ratios useless/missed of the precision-recall curve",
    )


Share = Annotated[float, Field(ge=0.0, le=1.0)]


class FilterConfig(_Section):
    fractions: tuple[Share, ...] = Field(
        (0.0, 0.25, 0.5, 0.75, 1.0),
        description="shares of history steps whose activity label is visible (missing-label runs)",
    )
    seed: int = Field(0, description="seed of which steps hide their label (combined with the household and day names)")
    max_hypotheses: int = Field(32, ge=1, le=10_000, description="most activity histories the filter keeps per step")
    min_weight: float = Field(1e-4, ge=0.0, lt=1.0, description="histories below this share of the belief are dropped")
    emission_smoothing: float = Field(
        1.0, gt=0.0, le=1e6, description="pseudo-count shrinking P(object moves | activity) towards its overall rate"
    )
    emission_weights: tuple[Annotated[float, Field(ge=0.0, le=10.0)], ...] = Field(
        (0.5, 1.0), description="exponents of the movement likelihood tried by cross-validation on training days"
    )
    emission_previous_shares: tuple[Share, ...] = Field(
        (0.5, 0.0, 1.0),
        description="share of a movement's likelihood credited to the activity at t-1 (the rest: at t), tried by CV",
    )
    emission_boundaries: tuple[bool, ...] = Field(
        (False, True), description="whether move rates also depend on the activity changing at the step, tried by CV"
    )
    emission_switches: tuple[bool, ...] = Field(
        (False, True), description="whether, at a change, moves credited to a_{s-1} also depend on the activity that "
        "starts (with the change flag and a share credited to a_{s-1}), tried by CV"
    )
    emission_weight: float = Field(
        0.5, ge=0.0, le=10.0, description="exponent of the movement likelihood where no cross-validation runs (the "
        "service; the emission_* defaults are what cross-validation chose on every HOMER+ household's training days)"
    )
    emission_previous_share: float = Field(
        1.0, ge=0.0, le=1.0,
        description="share of a movement credited to the activity at t-1 where no cross-validation runs",
    )
    emission_boundary: bool = Field(
        True, description="move rates depend on the activity changing, where no cross-validation runs"
    )
    emission_switch: bool = Field(
        True,
        description="at a change, move rates also depend on the activity that starts, where no cross-validation runs",
    )
    forecast_hypotheses: int = Field(
        4, ge=1, le=1000,
        description="most probable filtered histories mixed in a lookahead forecast with missing labels",
    )
    change_floor: float = Field(
        1e-3, ge=0.0, lt=1.0,
        description="where a household's sensors are the evidence, the share of each step's probability the filter "
        "spreads over every activity, so a change its activity model never saw (an unsmoothed n-gram's) stays possible",
    )
    threshold_per_fraction: bool = Field(
        False, description="choose the missing-label lookahead's change threshold by CV on training days with the same "
        "share of labels visible (else: on fully labelled days; costs a filter pass over every training day per share)"
    )


class Deployment(_Section):
    """What one household runs: the models and settings its cross-validation chose on its training
    days (``globe train``, ``globe household import``, ``POST /households``), or the configured
    ones. Kept with the household (the model file, the service's database) and applied over the
    configuration by :meth:`GlobeConfig.deployed`, so what is served is what was chosen."""

    method: DeployMethod = Field("ngram", description="the deployed method (selection.deploy)")
    models: ModelConfig = Field(ModelConfig(), description="the activity and object models")
    alignment: Alignment = Field("previous", description="which step's activity a movement is credited to")
    run_end: bool = Field(True, description="the movement model's hazards know that an activity ends")
    run_memory: bool = Field(False, description="... and what moved earlier in the run")
    run_next: bool = Field(False, description="... and which activity starts")
    fetch_objects: Literal["movements", "clock"] = Field(
        "movements", description="where the fetch policy's candidates come from: the movement forecast, or the "
        "clock-aware uses model where cross-validation chose it")
    emission_weight: float = Field(0.5, ge=0.0, le=10.0, description="the activity filter's movement evidence")
    emission_previous_share: float = Field(1.0, ge=0.0, le=1.0)
    emission_boundary: bool = True
    emission_switch: bool = True
    cross_validated: bool = Field(False, description="chosen by cross-validation (else: the configured settings)")
    note: str = Field("", max_length=500, description="why the configured settings were kept, when they were")
    scores: dict[str, float] = Field(
        {}, description="cross-validation scores on the training days: the chosen model's and persistence's activity "
        "log loss and weighted F1, and the chosen object model's weighted F1")

    @classmethod
    def configured(cls, config: "GlobeConfig", method: DeployMethod | None = None, note: str = "") -> "Deployment":
        """The configured settings as a deployment (nothing cross-validated)."""
        f, method = config.filter, method or config.selection.deploy
        persistence = {"activity_estimator": "persistence"} if method == "persistence" else {}
        return cls(method=method, models=config.models.model_copy(update=persistence), note=note,
                   alignment=config.sequences.alignment, emission_weight=f.emission_weight,
                   emission_previous_share=f.emission_previous_share, emission_boundary=f.emission_boundary,
                   emission_switch=f.emission_switch)

    @property
    def movement(self) -> tuple[bool, bool, bool]:
        """The movement model's (run_end, run_memory, run_next)."""
        return self.run_end, self.run_memory, self.run_next


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
    lookahead: LookaheadConfig = LookaheadConfig()
    policy: PolicyConfig = PolicyConfig()
    filter: FilterConfig = FilterConfig()
    mqtt: MqttConfig = MqttConfig()

    def deployed(self, deployment: Deployment) -> "GlobeConfig":
        """This configuration with a household's deployment applied (its models, alignment and
        movement evidence; the rest, the gate and the fetch costs among it, stays as configured)."""
        d = deployment
        emission = {"emission_weight": d.emission_weight, "emission_previous_share": d.emission_previous_share,
                    "emission_boundary": d.emission_boundary, "emission_switch": d.emission_switch}
        return self.model_copy(update={"models": d.models,
                                       "sequences": self.sequences.model_copy(update={"alignment": d.alignment}),
                                       "filter": self.filter.model_copy(update=emission)})

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
        except UnicodeDecodeError as err:
            raise ConfigError(f"{path}: not a TOML text file (not UTF-8 at byte {err.start})") from None
        except IsADirectoryError:
            raise ConfigError(f"{path}: is a folder, not a TOML file") from None
        source = str(path)
    values = _merge(values, _env_overrides(os.environ if environ is None else environ))
    values = _merge(values, _nest(overrides or {}))
    return _build(values, source)
