"""Cross-validated model configurations for the methods beyond the paper.

The activity model's parameters are chosen on next-activity F1 over held-out training days.
The object model's are then chosen where they matter: object F1 under the full protocol
(predicted activity, mixed over the activity distribution) on the held-out days, with the
chosen activity model. Last, the LLM gate (threshold d, replace or combine with weight w, or not
asking at all) is chosen the same way, so the LLM is used only as far as it helped on held-out
training days. Test days are never used.
"""

from __future__ import annotations

from typing import Any, Sequence

from globe.config import GateConfig, GlobeConfig, ModelConfig
from globe.data.records import Day, Household
from globe.evaluation.protocol import evaluate_days
from globe.models.activity import ActivityModel
from globe.models.objects import ObjectModel
from globe.models.routine import RoutineModel
from globe.models.selection import Selection, activity_fold, grid, select
from globe.pipeline import activity_model_from, object_model_from, training_sequences
from globe.reasoning.backends.base import LLMBackend
from globe.reasoning.choice import ObjectChooser
from globe.reasoning.gate import UncertaintyGate


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


class _GateJoint:
    """Fold models for one gate setting; fits are memoised per fold (they do not depend on it)."""

    def __init__(self, household: Household, models: ModelConfig, alignment: str, backend: LLMBackend,
                 params: dict[str, Any], memo: dict) -> None:
        self.household, self.models, self.alignment = household, models, alignment
        self.backend, self.params, self.memo = backend, params, memo

    def fit(self, days: Sequence[Day]) -> "_GateJoint":
        key = tuple(d.name for d in days)
        if key not in self.memo:
            seqs = training_sequences(self.household, days, self.alignment)  # type: ignore[arg-type]
            self.memo[key] = (activity_model_from(self.models).fit(seqs.activities),
                              object_model_from(self.models).fit(seqs.runs))
        self.activity_, self.objects_ = self.memo[key]
        return self


def _gate_fold(model: _GateJoint, days: Sequence[Day]) -> tuple[list[str], list[str]]:
    gate = UncertaintyGate(model.objects_, model.backend, marginal=model.models.object_marginal, **model.params)
    ev = evaluate_days(model.household, days, model.activity_, gate, alignment=model.alignment)  # type: ignore[arg-type]
    return [r.true for r in ev.objects], [r.predicted for r in ev.objects]


def tuned_gate(h: Household, cfg: GlobeConfig, models: ModelConfig, backend: LLMBackend, cache: dict,
               examples: int = 0) -> tuple[GateConfig, Selection]:
    """Gate settings chosen by k-fold CV on training days; "never ask" (d = 0) is a candidate
    and wins ties, so the LLM must earn its place on held-out days. ``examples`` recent runs of
    the activity personalise the prompt (fixed, not searched)."""
    key = (h.name, "gate", models.activity_estimator, examples)
    if key in cache:
        return cache[key]
    sel, g = cfg.selection, cfg.gate
    styles = [{"mode": "replace", "combine_weight": g.combine_weight}] + [
        {"mode": "combine", "combine_weight": w} for w in sel.combine_weights]
    space = [{"threshold": 0.0, "mode": "replace", "combine_weight": g.combine_weight}] + [
        {"threshold": d, **style} for d in sel.gate_thresholds for style in styles]
    common = {"top_k": g.top_k, "min_prob": g.min_prob, "examples": examples}
    memo: dict = {}
    chosen = select(list(h.train), space,
                    lambda p: _GateJoint(h, models, cfg.sequences.alignment, backend, p | common, memo), _gate_fold, sel.folds)
    cache[key] = (g.model_copy(update=chosen.best | {"examples": examples}), chosen)
    return cache[key]
