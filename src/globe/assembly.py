"""The one assembly point: every runtime object GLOBE uses is built here from a ``GlobeConfig``.

Models, choosers, backends and assistants never read configuration themselves. Evaluation,
tuning, the service and the CLI all build through these functions, so a setting cannot reach
one front end and silently miss another (the gate's ``examples`` once missed the service).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Sequence

from globe.config import (
    DEFAULT_STEP_MINUTES,
    FilterConfig,
    GateConfig,
    GlobeConfig,
    LLMConfig,
    LookaheadConfig,
    ModelConfig,
    PolicyConfig,
)
from globe.data.csv_logs import household_step
from globe.data.records import Day, Household
from globe.errors import ConfigError
from globe.inference.activity_filter import ActivityFilter
from globe.inference.emission import MovementEmission
from globe.inference.forecast import Forecaster
from globe.inference.movements import MovementModel
from globe.models.activity import ActivityModel
from globe.models.base import ActivityModelBase
from globe.models.baselines import HourActivityObjects, PersistenceModel
from globe.models.clock import ClockModel
from globe.models.objects import ObjectModel
from globe.models.routine import RoutineModel
from globe.reasoning.backends.base import LLMBackend
from globe.reasoning.choice import NextObjectModel, ObjectChooser
from globe.reasoning.gate import UncertaintyGate
from globe.sequences.movements import Alignment
from globe.sequences.runs import TrainingSequences, object_runs, training_sequences

if TYPE_CHECKING:
    from globe.inference.fetch_policy import FetchPolicy
    from globe.noise.proposals import Scorer
    from globe.reasoning.backends.embedded import EmbeddedBackend
    from globe.reasoning.cache import AnswerCache


def step_minutes(household: Household, config: GlobeConfig) -> int:
    """The minutes between a household's steps: configured (``data.step_minutes``), else its days'
    most common gap, else the service's step (a household with no day yet)."""
    return (config.data.step_minutes or household_step(household.train) or config.service.step_minutes
            or DEFAULT_STEP_MINUTES)


def common_step(households: Sequence[Household], config: GlobeConfig) -> int:
    """The one step of ``households``, whose results are tabled together by minutes ahead."""
    found = {h.name: step_minutes(h, config) for h in households}
    if len(set(found.values())) > 1:
        raise ConfigError("households with different steps cannot be tabled together: "
                          + ", ".join(f"{name} {step} min" for name, step in found.items())
                          + "; evaluate them separately or set data.step_minutes (with data.resample = 'locf')")
    return next(iter(found.values()), config.service.step_minutes or DEFAULT_STEP_MINUTES)


def lookahead_steps(config: GlobeConfig, household: Household) -> int:
    """The lookahead's horizons (steps 1..n ahead) for ``household``: ``lookahead.horizon_minutes``."""
    return steps(config.lookahead.horizon_minutes, step_minutes(household, config))


def steps(minutes: int, step_minutes: int) -> int:
    """A duration configured in minutes as a number of steps (at least one): configuration speaks
    minutes, the models count steps, so a 1-, 5- or 10-minute grid means the same routine."""
    return max(1, round(minutes / step_minutes))


def activity_model(models: ModelConfig, step_minutes: int) -> ActivityModelBase:
    """An unfitted next-activity model for the ``models`` section, over days of ``step_minutes``."""
    if models.activity_estimator == "persistence":
        return PersistenceModel()
    if models.activity_estimator == "routine":
        return RoutineModel(order=models.routine_order, time_weight=models.routine_time_weight,
                            time_window=steps(models.routine_time_window_minutes, step_minutes),
                            shrinkage=models.routine_shrinkage,
                            duration_cap=steps(models.routine_duration_cap_minutes, step_minutes),
                            step_minutes=step_minutes)
    if models.activity_estimator == "clock":
        return ClockModel(slot_minutes=models.clock_slot_minutes, shrinkage=models.clock_shrinkage,
                          step_minutes=step_minutes, day_types=models.clock_day_types, floor=models.clock_floor,
                          by_activity=models.clock_by_activity)
    return ActivityModel(estimator=models.activity_estimator, max_order=models.activity_max_order,
                         time_weight=models.time_weight, time_window=steps(models.time_window_minutes, step_minutes))


def object_model(models: ModelConfig) -> ObjectModel | HourActivityObjects:
    """An unfitted next-object model for the ``models`` section: the n-gram, or the object
    baseline (``models.object_model``)."""
    if models.object_model == "hour_activity":
        return HourActivityObjects()
    return ObjectModel(estimator=models.object_estimator, max_order=models.object_max_order,
                       run_start_token=models.run_start_token)


def fit_object_model(models: ModelConfig, household: Household, days: Sequence[Day], alignment: Alignment,
                     seqs: TrainingSequences) -> ObjectModel | HourActivityObjects:
    """The object model of ``models`` counted on ``days`` (``seqs``: their training sequences)."""
    model = object_model(models)
    if isinstance(model, ObjectModel):
        return model.fit(seqs.runs)
    return model.fit(object_runs(days, household.objects, alignment, True, seqs.moves or None))


@dataclass(frozen=True, slots=True)
class FittedHousehold:
    activity: ActivityModelBase
    objects: ObjectModel | HourActivityObjects
    train_s: float  # model fitting only (preprocessing excluded)
    preprocess_s: float
    sequences: TrainingSequences  # what was counted


def fit_household(household: Household, config: GlobeConfig, days: Sequence[Day] | None = None) -> FittedHousehold:
    """Preprocess the training days (``household.train`` unless ``days`` is given) and fit both
    models of ``config.models``, timing each part."""
    t0 = time.perf_counter()
    days = household.train if days is None else days
    seqs = training_sequences(household, days, config.sequences.alignment)
    t1 = time.perf_counter()
    activity = activity_model(config.models, step_minutes(household, config)).fit(seqs.activities, seqs.weekdays)
    objects = fit_object_model(config.models, household, days, config.sequences.alignment, seqs)
    return FittedHousehold(activity, objects, time.perf_counter() - t1, t1 - t0, seqs)


def fitted_activity_model(models: ModelConfig, step: int, days: Sequence[Day]) -> ActivityModelBase:
    """The activity model of ``models`` counted on ``days`` (their activities and days of the week)."""
    return activity_model(models, step).fit([d.activities for d in days], [d.weekday for d in days])


def movement_emission(filter_cfg: FilterConfig, *, previous_share: float, weight: float,
                      boundary: bool = False, switch: bool = False) -> MovementEmission:
    """An unfitted P(moved objects | activities) for the activity filter (``previous_share``,
    ``weight``, ``boundary`` and ``switch`` come from cross-validation,
    :mod:`globe.evaluation.missing_labels`)."""
    return MovementEmission(smoothing=filter_cfg.emission_smoothing, weight=weight, previous_share=previous_share,
                            boundary=boundary, switch=switch)


def activity_filter(activity: ActivityModelBase, emission: MovementEmission | None,
                    filter_cfg: FilterConfig) -> ActivityFilter:
    """The forward filter over the current activity, for days whose labels are partly missing."""
    return ActivityFilter(activity, emission, max_hypotheses=filter_cfg.max_hypotheses,
                          min_weight=filter_cfg.min_weight)


def household_emission(filter_cfg: FilterConfig) -> MovementEmission:
    """An unfitted movement evidence with the fixed ``filter.emission_*`` settings (for online use:
    no cross-validation on the request path)."""
    fc = filter_cfg
    return movement_emission(fc, previous_share=fc.emission_previous_share, weight=fc.emission_weight,
                             boundary=fc.emission_boundary, switch=fc.emission_switch)


def _answer_cache(llm: LLMConfig) -> "AnswerCache | None":
    from globe.reasoning.cache import AnswerCache

    return AnswerCache(llm.cache_dir / "llm-answers.sqlite3") if llm.cache_dir else None


def embedded_backend(llm: LLMConfig) -> "EmbeddedBackend":
    """The embedded llama.cpp backend with the ``llm`` settings (whatever ``llm.backend`` says)."""
    from globe.reasoning.backends.embedded import EmbeddedBackend

    return EmbeddedBackend(model_path=llm.model_path, n_threads=llm.n_threads, n_ctx=llm.n_ctx,
                           cache=_answer_cache(llm))


def service_llm_backend(config: GlobeConfig) -> LLMBackend | None:
    """The service's LLM backend: the embedded one with ``service.llm_timeout_s`` as the time limit
    of an answer, and loading (and probing) the model in the background from now on, so that no
    request waits for it."""
    if config.llm.backend != "embedded":
        return llm_backend(config.llm)
    from globe.reasoning.backends.embedded import EmbeddedBackend

    llm = config.llm
    backend = EmbeddedBackend(model_path=llm.model_path, n_threads=llm.n_threads, n_ctx=llm.n_ctx,
                              cache=_answer_cache(llm), timeout_s=config.service.llm_timeout_s)
    backend.start_loading()
    return backend


def llm_backend(llm: LLMConfig) -> LLMBackend | None:
    """The configured LLM backend (``none`` -> None); heavy imports happen only here."""
    if llm.backend == "none":
        return None
    if llm.backend == "embedded":
        return embedded_backend(llm)
    from globe.reasoning.backends.remote import RemoteBackend

    return RemoteBackend(model=llm.remote_model, base_url=llm.base_url, temperature=llm.temperature,
                         max_tokens=llm.max_tokens, timeout_s=llm.timeout_s, max_retries=llm.max_retries,
                         cache=_answer_cache(llm))


def object_chooser(objects: NextObjectModel, gate: GateConfig, backend: LLMBackend | None, *,
                   marginal: bool) -> ObjectChooser:
    """GLOBE's uncertainty gate over ``objects`` when there is a backend, else the plain n-gram."""
    if backend is None:
        return ObjectChooser(objects, marginal=marginal)
    return UncertaintyGate(objects, backend, threshold=gate.threshold, top_k=gate.top_k, min_prob=gate.min_prob,
                           mode=gate.mode, combine_weight=gate.combine_weight, marginal=marginal,
                           examples=gate.examples)


def noise_scorer(config: GlobeConfig) -> "Scorer":
    """What scores HOMER-Noise proposals: the embedded model (PMI), or uniform without an LLM."""
    from globe.errors import ConfigError
    from globe.noise.proposals import LLMScorer, UniformScorer

    if config.llm.backend == "none":
        return UniformScorer()
    if config.llm.backend != "embedded":
        raise ConfigError("the noise generator scores sentences: use llm.backend 'embedded' "
                          "(or 'none' for uniform proposals)")
    return LLMScorer(embedded_backend(config.llm))


def describe(activity: ActivityModelBase, chooser: ObjectChooser,
             stay_margin: float = 1.0) -> dict[str, dict[str, Any]]:
    """The effective settings of built objects, read from the objects themselves (not from the
    configuration), so results folders and the service show what really ran (``stay_margin``:
    the decision's, which lives beside the model)."""
    out: dict[str, dict[str, Any]] = {
        "activity": {"kind": type(activity).__name__, **activity.get_params(), "stay_margin": stay_margin},
        "objects": {"kind": type(chooser.model).__name__, **getattr(chooser.model, "get_params", dict)()},
        "chooser": {"kind": chooser.name, "marginal": chooser.marginal},
    }
    if isinstance(chooser, UncertaintyGate):
        out["chooser"] |= {"threshold": chooser.threshold, "top_k": chooser.top_k, "min_prob": chooser.min_prob,
                           "mode": chooser.mode, "combine_weight": chooser.combine_weight, "examples": chooser.examples,
                           "backend": None if chooser.backend is None else chooser.backend.name}
    return out


@dataclass(frozen=True, slots=True)
class FittedForecaster:
    forecaster: Forecaster
    train_s: float  # both models' fitting (the activity model's included)


def movement_model(lookahead: LookaheadConfig, step_minutes: int, run_end: bool = True, run_memory: bool = False,
                   run_next: bool = False) -> MovementModel:
    """An unfitted movement-hazard and destination model for the ``lookahead`` section
    (``run_end``, ``run_memory``, ``run_next``: of ``lookahead.run_end`` / ``run_memory`` /
    ``run_next``, chosen by cross-validation)."""
    return MovementModel(hazard_shrinkage=lookahead.hazard_shrinkage,
                         duration_cap=steps(lookahead.duration_cap_minutes, step_minutes),
                         destination_shrinkage=lookahead.destination_shrinkage, run_end=run_end, run_memory=run_memory,
                         run_next=run_next)


def forecaster(household: Household, config: GlobeConfig, days: Sequence[Day] | None = None,
               models: ModelConfig | None = None, run_end: bool = True, run_memory: bool = False,
               run_next: bool = False) -> FittedForecaster:
    """A forecaster over ``household``'s training days (or ``days``): the activity model of
    ``models`` (default ``config.models``) and the movement model of ``config.lookahead``."""
    days = tuple(household.train if days is None else days)
    la = config.lookahead
    t0 = time.perf_counter()
    step = step_minutes(household, config)
    activity = fitted_activity_model(models or config.models, step, days)
    movements = movement_model(la, step, run_end, run_memory, run_next).fit(days, household.objects)
    train_s = time.perf_counter() - t0
    return FittedForecaster(forecaster_over(activity, movements, la), train_s)


def forecaster_over(activity: ActivityModelBase, movements: MovementModel, lookahead: LookaheadConfig) -> Forecaster:
    """A forecaster over fitted ``activity`` and ``movements`` models, pruned as ``lookahead`` says."""
    return Forecaster(activity, movements, min_path_probability=lookahead.min_path_probability,
                      max_paths=lookahead.max_paths)


def fetch_policy(forecaster: Forecaster, policy: PolicyConfig, step_minutes: int,
                 uses_days: Sequence[Day] | None = None) -> "FetchPolicy":
    """The robot's fetch decision over ``forecaster`` with the ``policy`` costs and lead times;
    with ``uses_days`` (where cross-validation chose the clock-aware uses model:
    ``Deployment.fetch_objects``), its candidates from that model counted on those days
    (:func:`~globe.models.baselines.fit_uses_ahead`) instead of the forecast."""
    from globe.inference.fetch_policy import FetchPolicy
    from globe.models.baselines import fit_uses_ahead

    lead, window = lead_steps(policy, step_minutes)
    uses = None
    if uses_days is not None:
        uses = fit_uses_ahead(uses_days, forecaster.movements.objects_, lead, window, clock=True)
    return FetchPolicy(forecaster, cost_useless=policy.cost_useless, cost_missed=policy.cost_missed,
                       min_lead_steps=lead, window_steps=window, max_fetches_per_step=policy.max_fetches_per_step,
                       uses=uses)


def lead_steps(policy: PolicyConfig, step_minutes: int) -> tuple[int, int]:
    """The fetch policy's minimum lead and lead window in steps: a fetch counts for uses from
    ``min_lead_minutes`` (rounded up to a step) to ``lead_window_minutes`` after it."""
    return -(-policy.min_lead_minutes // step_minutes), max(1, policy.lead_window_minutes // step_minutes)
