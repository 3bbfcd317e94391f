"""The model and gate searches: which activity model, object model and LLM gate to use.

The activity model's parameters are chosen on next-activity F1 over held-out training days
(:mod:`globe.evaluation.selection`). The object model's are then chosen where they matter:
object F1 under the full protocol (predicted activity, mixed over the activity distribution) on
the held-out days, with the chosen activity model. Last, the LLM gate (threshold d, replace or
combine with weight w, or not asking at all) is chosen the same way, so the LLM is used only as
far as it helped on held-out training days.
"""

from __future__ import annotations

import time
from typing import Any, Mapping, Sequence, cast

from globe import assembly
from globe.config import GateConfig, GlobeConfig, ModelConfig, SelectionConfig
from globe.data.records import Day, Household
from globe.evaluation.metrics import f1, log_loss, records_f1
from globe.evaluation.protocol import ActivityPredictor, evaluate_days
from globe.evaluation.selection import (
    Beyond,
    DataKey,
    FitKey,
    Fold,
    Memo,
    SearchKey,
    Selection,
    best_beyond_noise,
    folds,
    frozen_params,
    grid,
    select_beyond_noise,
    select_by,
    select_widening,
)
from globe.models.base import ActivityModelBase, stay_or_change
from globe.models.baselines import HourActivityObjects
from globe.models.objects import ObjectModel
from globe.reasoning.backends.base import LLMBackend
from globe.reasoning.choice import ObjectChooser
from globe.sequences.movements import Alignment
from globe.sequences.runs import TrainingSequences, training_sequences


def fold_days(household: Household, fold: Fold) -> tuple[list[Day], list[Day]]:
    """(the training part, the held-out part) of ``fold`` of ``household``'s training days."""
    train, held_out = folds(len(household.train), fold.k)[fold.index]
    return [household.train[i] for i in train], [household.train[i] for i in held_out]


def data_folds(household: Household, k: int) -> list[Fold]:
    data = DataKey.of(household)
    return [Fold(data, k, i) for i in range(len(folds(len(household.train), k)))]


def sequences(household: Household, fold: Fold | None, alignment: str, memo: Memo) -> TrainingSequences:
    """What the models count on a fold's training part (or every training day), once."""
    days = household.train if fold is None else fold_days(household, fold)[0]
    key = FitKey("sequences", DataKey.of(household), fold, (), alignment)
    return memo.get(key, lambda: training_sequences(household, days, alignment))  # type: ignore[arg-type]


def fitted_activity(household: Household, fold: Fold | None, models: ModelConfig, memo: Memo,
                    step_minutes: int) -> "ScanMemo":
    """The activity model of ``models`` on a fold (or every training day). Candidates that count
    the same share one fit; each answers with its own prediction parameters, and its scans of the
    held-out days are kept with it. Activities do not depend on the movement alignment, so every
    alignment tried shares these fits and scans."""
    model = assembly.activity_model(models, step_minutes)
    data = DataKey.of(household)
    days = household.train if fold is None else fold_days(household, fold)[0]
    counted = memo.get(FitKey(type(model).__name__, data, fold, frozen_params(model.fit_params())),
                       lambda: model.fit([d.activities for d in days], [d.weekday for d in days]))
    key = FitKey(f"{type(model).__name__}:predicting", data, fold, frozen_params(model.get_params()))
    return memo.get(key, lambda: ScanMemo(counted.with_prediction_params(**model.prediction_params())))


def fitted_objects(household: Household, fold: Fold | None, models: ModelConfig, alignment: str,
                   memo: Memo) -> ObjectModel | HourActivityObjects:
    model = assembly.object_model(models)
    key = FitKey(type(model).__name__, DataKey.of(household), fold, frozen_params(model.get_params()), alignment)

    def fit() -> ObjectModel | HourActivityObjects:
        days = household.train if fold is None else fold_days(household, fold)[0]
        return assembly.fit_object_model(models, household, days, cast(Alignment, alignment),
                                         sequences(household, fold, alignment, memo))

    return memo.get(key, fit)


class ScanMemo:
    """A fitted activity model whose scans are kept: every object and gate candidate of a fold
    scans the same held-out days with it (the protocol's activity predictor)."""

    def __init__(self, model: ActivityModelBase) -> None:
        self.model = model
        self._scans: dict[tuple[int | None, tuple[str, ...]], list[dict[str, float]]] = {}

    def scan_proba(self, day: Sequence[str], weekday: int | None = None) -> list[dict[str, float]]:
        key = (weekday, tuple(day))
        scans = self._scans.get(key)
        if scans is None:
            scans = self._scans[key] = self.model.scan_proba(day, weekday)
        return scans

    def ranked(self, distribution: dict[str, float]) -> list[str]:
        return self.model.ranked(distribution)

    def top(self, distribution: dict[str, float]) -> str | None:
        return self.model.top(distribution)


def activity_scores(model: ScanMemo, days: Sequence[Day], stay_margin: float = 1.0) -> dict[str, float]:
    """Log loss and weighted F1 of the next activity at steps 1..T-1 of held-out days (a fold
    with nothing to score: F1 0, log loss that of a probability of 0); the activity said is kept
    at the current one by ``stay_margin`` (:func:`~globe.models.base.stay_or_change`)."""
    true, pred, p_true = [], [], []
    for day in days:
        acts = day.activities
        for t, dist in enumerate(model.scan_proba(acts, day.weekday)):
            if t:
                true.append(acts[t])
                pred.append(stay_or_change(model.top(dist), dist, acts[t - 1], stay_margin) or "<none>")
                p_true.append(dist.get(acts[t], 0.0))
    loss = log_loss(p_true if p_true else [0.0])
    return {"log_loss": 0.0 if loss is None else loss, "f1": f1(true, pred) or 0.0}


def object_scores(household: Household, days: Sequence[Day], activity: ActivityPredictor, chooser: ObjectChooser,
                  alignment: str, rankings: dict, stay_margin: float = 1.0) -> dict[str, float]:
    """Log loss (of the object model's probability of the object that moved) and weighted F1 of
    the object at every movement of held-out days, under the full protocol."""
    ev = evaluate_days(household, days, activity, chooser, alignment=alignment,  # type: ignore[arg-type]
                       rankings=rankings, stay_margin=stay_margin)
    p_true = [r.p_true for r in ev.objects if r.p_true is not None]
    return {"log_loss": log_loss(p_true) or 0.0, "f1": records_f1(ev.objects) or 0.0}


def object_f1(household: Household, days: Sequence[Day], activity: ActivityPredictor, chooser: ObjectChooser,
              alignment: str, rankings: dict, stay_margin: float = 1.0) -> float:
    """Weighted F1 of the object at every movement of held-out days, under the full protocol."""
    return object_scores(household, days, activity, chooser, alignment, rankings, stay_margin)["f1"]


def per_fold(household: Household, k: int, score_fold: Any) -> list[Any]:
    """``score_fold(fold, held-out days)`` on each of the ``k`` folds."""
    return [score_fold(fold, fold_days(household, fold)[1]) for fold in data_folds(household, k)]


def mean_over_folds(household: Household, k: int, score_fold: Any) -> Any:
    """The mean of ``score_fold(fold, held-out days)`` over the ``k`` folds (a number, or each
    metric of a dict of them)."""
    scores = per_fold(household, k, score_fold)
    if isinstance(scores[0], dict):
        return {name: sum(s[name] for s in scores) / len(scores) for name in scores[0]}
    return sum(scores) / len(scores)


def day_types_tried(h: Household, sel: SelectionConfig) -> list[str]:
    """The clock model's day types to try on ``h``: "none" only, unless ``sel.day_types_min_days``
    of its training days (two weeks by default) are named by distinct dates, so that every day of
    the week can have been seen more than once."""
    known = {when for when in (d.calendar_date for d in h.train) if when is not None}
    tried: list[str] = list(sel.clock_day_types) if len(known) >= sel.day_types_min_days else []
    return tried if "none" in tried else ["none", *tried]


def model_search_key(h: Household, cfg: GlobeConfig, family: str) -> SearchKey:
    """Everything a model search depends on: the training days, the family, the search space, the
    base models, the folds and the alignment."""
    return SearchKey(f"models:{family}", DataKey.of(h), cfg.selection, cfg.models, cfg.selection.folds,
                     cfg.sequences.alignment)


def _clock_beyond(step_minutes: int) -> dict[str, Beyond]:
    """Past the edges of the clock model's grid: slots twice as wide (to 12 hours) or half as
    wide (to one step, at least 10 minutes), shrinkage five times stronger (to 1000) or weaker
    (to 0.1)."""
    def slot(edge: int, upward: bool) -> int | None:
        value = edge * 2 if upward else edge // 2
        return value if max(step_minutes, 10) <= value <= 720 and value != edge else None

    def shrinkage(edge: float, upward: bool) -> float | None:
        value = round(edge * 5 if upward else edge / 5, 6)
        return value if 0.1 <= value <= 1000 else None

    return {"clock_slot_minutes": slot, "clock_shrinkage": shrinkage}


def tuned_models(h: Household, cfg: GlobeConfig, family: str, memo: Memo) -> tuple[ModelConfig, dict[str, Selection]]:
    """Model configuration for ``family`` ("witten_bell" or "routine") chosen by k-fold CV on
    the training days; kept in ``memo`` so methods share one search."""
    sel, alignment, step = cfg.selection, cfg.sequences.alignment, assembly.step_minutes(h, cfg)
    key = model_search_key(h, cfg, family)
    if key in memo:
        return memo.get(key, lambda: None)  # type: ignore[return-value]
    if family == "routine":
        space = grid({"activity_estimator": ["routine"], "routine_order": sel.routine_orders,
                      "routine_time_weight": sel.time_weights})
        clock: dict[str, Sequence[Any]] = {"activity_estimator": ["clock"], "clock_slot_minutes": sel.clock_slots,
                                           "clock_shrinkage": sel.clock_shrinkages}
        day_types = day_types_tried(h, sel)
        if len(day_types) > 1:  # a home without dates keeps the candidates (and their names) it had
            clock["clock_day_types"] = day_types
        space += grid(clock)
        # the clock candidates read the current activity whatever the configured models say; the
        # time of day alone is its own candidates' (below)
        base: dict[str, Any] = {"object_marginal": True, "clock_by_activity": True}
    elif family == "witten_bell":
        space = grid({"activity_estimator": ["witten_bell"], "activity_max_order": sel.activity_orders,
                      "time_weight": sel.time_weights})
        base = {}
    else:
        raise ValueError(f"unknown model family {family!r}; expected 'routine' or 'witten_bell'")
    # The simpler models are candidates too, listed first so that they win ties: a home whose
    # routine is "the activity stays the same" gets persistence, not a model that overfits; one
    # whose activity follows the clock whatever went before, the time of day alone (the clock
    # model pooled over the current activity: the time-of-day baseline's slot of one step, then
    # the clock model's slots).
    simpler: list[dict[str, Any]] = [{"activity_estimator": "persistence"}, {"activity_estimator": "longest"}]
    if family == "routine":
        simpler += grid({"activity_estimator": ["clock"], "clock_by_activity": [False],
                         "clock_slot_minutes": sorted({step, *sel.clock_slots})})

    def activity_measure(params: dict[str, Any]) -> dict[str, float]:
        models = cfg.models.model_copy(update=base | params)
        return mean_over_folds(h, sel.folds, lambda fold, days: activity_scores(
            fitted_activity(h, fold, models, memo, step), days))

    criterion = sel.criterion if family == "routine" else sel.ngram_criterion
    beyond = _clock_beyond(step) if family == "routine" else {}
    act = select_widening(simpler + space, activity_measure, criterion, beyond)
    models = cfg.models.model_copy(update=base | act.best)
    selections = {"activity": act}
    if models.activity_estimator == "clock" and len(sel.clock_floors) > 1:
        selections["floor"] = floor = select_by([{"clock_floor": f} for f in sel.clock_floors],
                                                lambda params: activity_measure(act.best | params), "log_loss")
        models = models.model_copy(update=floor.best)
    if family == "routine" and len(sel.stay_margins) > 1:
        # the decision apart from the distribution: the same folds' scans, scored by the F1 they are reported by
        chosen = models

        def decision_measure(params: dict[str, Any]) -> list[dict[str, float]]:
            return per_fold(h, sel.folds, lambda fold, days: activity_scores(
                fitted_activity(h, fold, chosen, memo, step), days, params["stay_margin"]))

        selections["decision"] = decision = select_beyond_noise([{"stay_margin": m} for m in sel.stay_margins],
                                                                decision_measure, "f1")
        models = models.model_copy(update=decision.best)

    def object_measure(params: dict[str, Any]) -> dict[str, float]:
        return object_cv_scores(h, cfg, models.model_copy(update=params), alignment, memo, step)

    obj = select_by(object_candidates(sel), object_measure, sel.object_criterion)
    models = models.model_copy(update=obj.best)
    selections["objects"] = obj
    offered = [a for a in sel.alignments if a != "most" or all(d.covering is not None for d in h.train)]
    if family == "routine" and set(offered) - {alignment}:
        # Which activity a use is credited to depends on how the log was made (HOMER+'s rows: the
        # step before; an imported sensor log: the step itself): scored through the protocol, with
        # the chosen models, so the activity a use is credited to must itself be predicted.
        best = obj.metrics[[c for c, _ in obj.scores].index(obj.best)]

        def alignment_measure(params: dict[str, Any]) -> dict[str, float]:
            if params["alignment"] == alignment:  # the object search has just scored these models so
                return best
            return object_cv_scores(h, cfg, models, params["alignment"], memo, step)

        tried = [{"alignment": a} for a in dict.fromkeys((alignment, *offered))]
        selections["alignment"] = select_by(tried, alignment_measure, sel.object_criterion)
    out = (models, selections)
    memo.put(key, out)
    return out


def object_candidates(sel: SelectionConfig) -> list[dict[str, Any]]:
    """The object models cross-validation tries (``selection.object_models``): the n-gram with each
    estimator and run-start setting, then the object baseline (one candidate: it has neither)."""
    out: list[dict[str, Any]] = []
    for kind in sel.object_models:
        if kind == "ngram":
            out += [{"object_model": "ngram", **c} for c in grid({"object_estimator": sel.object_estimators,
                                                                    "run_start_token": sel.run_start_token})]
        else:
            out.append({"object_model": kind})
    return out


def object_cv_scores(h: Household, cfg: GlobeConfig, models: ModelConfig, alignment: str, memo: Memo,
                     step: int) -> dict[str, float]:
    """The object model's log loss and weighted F1 under the full protocol (predicted activity),
    mean over the folds of the training days, for ``models`` counted with ``alignment``."""
    def score_fold(fold: Fold, days: Sequence[Day]) -> dict[str, float]:
        activity = fitted_activity(h, fold, models, memo, step)
        objects = fitted_objects(h, fold, models, alignment, memo)
        chooser = assembly.object_chooser(objects, cfg.gate, None, marginal=models.object_marginal)
        return object_scores(h, days, activity, chooser, alignment, _rankings(memo, fold, models, alignment),
                             models.stay_margin)

    return mean_over_folds(h, cfg.selection.folds, score_fold)


def chosen_alignment(selections: Mapping[str, Selection], cfg: GlobeConfig) -> Alignment:
    """The alignment cross-validation chose (``selections["alignment"]``), else the configured one."""
    found = selections.get("alignment")
    return cast(Alignment, found.best["alignment"]) if found is not None and found.best else cfg.sequences.alignment


def _rankings(memo: Memo, fold: Fold, models: ModelConfig, alignment: str) -> dict:
    """The n-gram rankings of a fold's held-out events under ``models``: every gate candidate
    ranks the same events with the same models."""
    return memo.get(FitKey("rankings", fold.data, fold, models, alignment), dict)


def tuned_gate(h: Household, cfg: GlobeConfig, models: ModelConfig, backend: LLMBackend, memo: Memo,
               examples: int = 0) -> tuple[GateConfig, Selection]:
    """Gate settings chosen by k-fold CV on training days; "never ask" (d = 0) is the default and
    keeps its place unless a setting beats it fold by fold beyond noise
    (:func:`~globe.evaluation.selection.best_beyond_noise`): the LLM must earn its place on
    held-out days. ``examples`` recent runs of the activity personalise the prompt (fixed, not
    searched)."""
    sel, g, alignment, step = cfg.selection, cfg.gate, cfg.sequences.alignment, assembly.step_minutes(h, cfg)
    key = SearchKey("gate", DataKey.of(h), (sel, g), (models, examples, backend.name, backend.model_name), sel.folds,
                    alignment)
    if key in memo:
        return memo.get(key, lambda: None)  # type: ignore[return-value]
    styles = [{"mode": "replace", "combine_weight": g.combine_weight}] + [
        {"mode": "combine", "combine_weight": w} for w in sel.combine_weights]
    space: list[dict[str, Any]] = [{"threshold": 0.0, "mode": "replace", "combine_weight": g.combine_weight}] + [
        {"threshold": d, **style} for d in sel.gate_thresholds for style in styles]

    def score(params: dict[str, Any]) -> list[float]:
        gate = g.model_copy(update=params | {"examples": examples})

        def score_fold(fold: Fold, days: Sequence[Day]) -> float:
            activity = fitted_activity(h, fold, models, memo, step)
            objects = fitted_objects(h, fold, models, alignment, memo)
            chooser = assembly.object_chooser(objects, gate, backend, marginal=models.object_marginal)
            return object_f1(h, days, activity, chooser, alignment, _rankings(memo, fold, models, alignment),
                             models.stay_margin)

        return per_fold(h, sel.folds, score_fold)

    # The highest threshold asks every question a lower one asks: scoring it first answers each
    # fold's questions in one batch, and the rest come from the answer cache.
    started = time.perf_counter()
    scores = {i: score(space[i]) for i in sorted(range(len(space)), key=lambda i: -float(space[i]["threshold"]))}
    scored = [(space[i], sum(scores[i]) / len(scores[i])) for i in range(len(space))]
    best = best_beyond_noise([(space[i], scores[i]) for i in range(len(space))])  # the LLM must earn its place
    chosen = Selection(dict(best), scored, time.perf_counter() - started)
    out = (g.model_copy(update=chosen.best | {"examples": examples}), chosen)
    memo.put(key, out)
    return out
