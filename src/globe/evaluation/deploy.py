"""What a household deploys: the selection ``globe evaluate`` runs, made once on its training days.

``globe train``, ``globe household import`` and ``POST /households`` call
:func:`choose_deployment`, and the result is kept with the household (the model file, the
service's database), so the models a robot is served are the models that won on its training
days, never the paper's defaults by accident. For ``selection.deploy = "routine"`` (the default)
or ``"ngram_smoothed"`` that is the family's cross-validation (:func:`globe.evaluation.tuning.tuned_models`:
the activity model, persistence and the clock model among the candidates, the object model and
the movement alignment), the movement model's settings (:func:`globe.evaluation.lookahead.choose_settings`), for
``"routine"`` the fetch policy's candidates (the movement forecast or the clock-aware uses model,
by what the fetches cost on held-out days: :func:`globe.evaluation.fetch_source.choose_fetch_source`,
as the fetch table's routine row)
and the activity filter's movement evidence (:func:`globe.evaluation.missing_labels.tune_evidence`);
``"ngram"`` and ``"persistence"`` keep the configured settings. The LLM gate stays as configured
(its cross-validation asks the LLM thousands of questions; ``globe evaluate`` reports it).
"""

from __future__ import annotations

from typing import Any, Callable

from globe.config import CV_METHODS, Deployment, DeployMethod, GlobeConfig
from globe.data.records import Household
from globe.evaluation.fetch_source import choose_fetch_source
from globe.evaluation.lookahead import CLOCK_OFFERED_TO, MOVEMENTS, choose_settings, setting_of
from globe.evaluation.selection import Memo, Selection
from globe.evaluation.tuning import chosen_alignment, tuned_models

Progress = Callable[[str], None]


def too_few_days(household: Household, config: GlobeConfig) -> str | None:
    """Why ``household`` cannot be cross-validated (fewer training days than folds), or None."""
    k, n = config.selection.folds, len(household.train)
    if n < k:
        return f"{n} training day{'s' if n != 1 else ''}: cross-validation needs at least {k} (selection.folds)"
    return None


def choose_deployment(household: Household, config: GlobeConfig, memo: Memo | None = None,
                      method: DeployMethod | None = None, progress: Progress | None = None) -> Deployment:
    """The deployment of ``household`` for ``method`` (default ``selection.deploy``): chosen by
    cross-validation on its training days where the method is chosen so and there are enough
    days, else the configured settings (with a note saying why)."""
    from globe.evaluation.missing_labels import tune_evidence

    method = method or config.selection.deploy
    family = CV_METHODS.get(method)
    if family is None:
        return Deployment.configured(config, method)
    why = too_few_days(household, config)
    if why is not None:
        return Deployment.configured(config, method, note=f"{why}; the configured models run")
    memo = Memo() if memo is None else memo
    if progress:
        progress(f"{household.name}: choosing the activity and object models (cross-validation)")
    models, selections = tuned_models(household, config, family, memo)
    alignment = chosen_alignment(selections, config)
    if progress:
        progress(f"{household.name}: choosing the movement model")
    setting = setting_of(choose_settings(household, config, models, memo).best)
    run_end, run_memory, run_next = setting
    fetch_objects = MOVEMENTS
    if method in CLOCK_OFFERED_TO:  # as the fetch table's row: by what the fetches cost on held-out days
        if progress:
            progress(f"{household.name}: choosing the fetch policy's candidates (on held-out days)")
        fetch_objects = choose_fetch_source(household, config, models, setting, memo).best["objects"]
    if progress:
        progress(f"{household.name}: choosing the activity filter's movement evidence")
    evidence = tune_evidence(household, config, models, memo, alignment).best
    return Deployment(method=method, models=models, alignment=alignment, run_end=run_end, run_memory=run_memory,
                      run_next=run_next, fetch_objects=fetch_objects,
                      emission_weight=evidence["weight"],
                      emission_previous_share=evidence["previous_share"], emission_boundary=evidence["boundary"],
                      emission_switch=evidence["switch"], cross_validated=True, scores=_scores(selections))


def _metrics(selection: Selection, params: dict[str, Any]) -> dict[str, float]:
    for (candidate, _), metrics in zip(selection.scores, selection.metrics):
        if candidate == params:
            return metrics
    return {}


def _scores(selections: dict[str, Selection]) -> dict[str, float]:
    """The chosen models' cross-validation scores beside persistence's (the simplest rule)."""
    act, obj = selections["activity"], selections["objects"]
    chosen, persistence = _metrics(act, act.best), _metrics(act, {"activity_estimator": "persistence"})
    out = {f"activity_{k}": v for k, v in chosen.items()}
    out |= {f"persistence_{k}": v for k, v in persistence.items()}
    out |= {f"object_{k}": v for k, v in _metrics(obj, obj.best).items()}
    decision = selections.get("decision")  # the activity said, with the chosen stay margin
    if decision is not None:
        out["decision_f1"] = _metrics(decision, decision.best).get("f1", 0.0)
    return {k: round(float(v), 4) for k, v in out.items()}
