"""Cross-validated model configurations for the methods beyond the paper.

The activity model's parameters are chosen on next-activity F1 over held-out training days.
The object model's are then chosen where they matter: object F1 under the full protocol
(predicted activity, mixed over the activity distribution) on the held-out days, with the
chosen activity model. Test days are never used.
"""

from __future__ import annotations

from typing import Any, Sequence

from globe.config import GlobeConfig, ModelConfig
from globe.data.records import Day, Household
from globe.evaluation.protocol import evaluate_days
from globe.models.activity import ActivityModel
from globe.models.objects import ObjectModel
from globe.models.routine import RoutineModel
from globe.models.selection import Selection, activity_fold, grid, select
from globe.pipeline import activity_model_from, training_sequences
from globe.reasoning.choice import ObjectChooser


class _Joint:
    """A (activity config, object params) pair that ``select`` can fit on a fold of days."""

    def __init__(self, household: Household, models: ModelConfig, alignment: str, params: dict[str, Any]) -> None:
        self.household, self.models, self.alignment, self.params = household, models, alignment, params

    def fit(self, days: Sequence[Day]) -> "_Joint":
        seqs = training_sequences(self.household, days, self.alignment)  # type: ignore[arg-type]
        self.activity_ = activity_model_from(self.models).fit(seqs.activities)
        self.objects_ = ObjectModel(**self.params).fit(seqs.runs)
        return self


def _joint_fold(model: _Joint, days: Sequence[Day]) -> tuple[list[str], list[str]]:
    chooser = ObjectChooser(model.objects_, marginal=model.models.object_marginal)
    ev = evaluate_days(model.household, days, model.activity_, chooser, alignment=model.alignment)  # type: ignore[arg-type]
    return [r.true for r in ev.objects], [r.predicted for r in ev.objects]


def tuned_models(h: Household, cfg: GlobeConfig, family: str, cache: dict) -> tuple[ModelConfig, dict[str, Selection]]:
    """Model configuration for ``family`` ("witten_bell" or "routine") chosen by k-fold CV on
    the training days; memoised in ``cache`` per household so methods share one search."""
    key = (h.name, family)
    if key in cache:
        return cache[key]
    sel = cfg.selection
    seqs = training_sequences(h, h.train, cfg.sequences.alignment)
    if family == "routine":
        space = grid({"order": sel.routine_orders, "time_weight": sel.time_weights})
        act = select(seqs.activities, space, lambda p: RoutineModel(**p), activity_fold, sel.folds)
        overrides: dict[str, Any] = {"activity_estimator": "routine", "routine_order": act.best["order"],
                                     "routine_time_weight": act.best["time_weight"], "object_marginal": True}
    elif family == "witten_bell":
        space = grid({"max_order": sel.activity_orders, "time_weight": sel.time_weights})
        act = select(seqs.activities, space, lambda p: ActivityModel(estimator="witten_bell", **p), activity_fold, sel.folds)
        overrides = {"activity_estimator": "witten_bell", "activity_max_order": act.best["max_order"],
                     "time_weight": act.best["time_weight"]}
    else:
        raise ValueError(f"unknown model family {family!r}; expected 'routine' or 'witten_bell'")
    models = cfg.models.model_copy(update=overrides)
    ospace = grid({"estimator": sel.object_estimators, "run_start_token": sel.run_start_token})
    obj = select(list(h.train), ospace, lambda p: _Joint(h, models, cfg.sequences.alignment, p), _joint_fold, sel.folds)
    models = models.model_copy(update={"object_estimator": obj.best["estimator"], "run_start_token": obj.best["run_start_token"]})
    cache[key] = (models, {"activity": act, "objects": obj})
    return cache[key]
