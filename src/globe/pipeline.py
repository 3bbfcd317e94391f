"""From a household and a configuration to fitted models: the one place that maps config
sections onto model constructors (models themselves never read configuration)."""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Sequence

from globe.config import ModelConfig
from globe.data.records import Day, Household
from globe.models.activity import ActivityModel
from globe.models.objects import ObjectModel
from globe.models.routine import RoutineModel
from globe.sequences.movements import Alignment
from globe.sequences.runs import activity_runs


@dataclass(frozen=True, slots=True)
class TrainingSequences:
    """What the models count: per-day activity sequences and (activity, objects) per run."""

    activities: list[tuple[str, ...]]
    runs: list[tuple[str, tuple[str, ...]]]


def training_sequences(household: Household, days: Sequence[Day], alignment: Alignment) -> TrainingSequences:
    return TrainingSequences(
        [d.activities for d in days],
        [(r.activity, r.objects) for d in days for r in activity_runs(d, household.objects, alignment)],
    )


def activity_model_from(cfg: ModelConfig) -> ActivityModel | RoutineModel:
    if cfg.activity_estimator == "routine":
        return RoutineModel(order=cfg.routine_order, time_weight=cfg.routine_time_weight,
                            time_window=cfg.routine_time_window, shrinkage=cfg.routine_shrinkage)
    return ActivityModel(estimator=cfg.activity_estimator, max_order=cfg.activity_max_order,
                         time_weight=cfg.time_weight, time_window=cfg.time_window)


def object_model_from(cfg: ModelConfig) -> ObjectModel:
    return ObjectModel(estimator=cfg.object_estimator, max_order=cfg.object_max_order,
                       run_start_token=cfg.run_start_token)


@dataclass(frozen=True, slots=True)
class FittedHousehold:
    activity: ActivityModel | RoutineModel
    objects: ObjectModel
    train_s: float  # model fitting only (preprocessing excluded)
    preprocess_s: float


def fit_household(household: Household, cfg: ModelConfig, alignment: Alignment, days: Sequence[Day] | None = None) -> FittedHousehold:
    """Preprocess the training days and fit both models, timing each part."""
    t0 = time.perf_counter()
    seqs = training_sequences(household, household.train if days is None else days, alignment)
    t1 = time.perf_counter()
    activity = activity_model_from(cfg).fit(seqs.activities)
    objects = object_model_from(cfg).fit(seqs.runs)
    return FittedHousehold(activity, objects, time.perf_counter() - t1, t1 - t0)
