"""Cross-validation over *training* days only: the one home of model and gate selection.

Test days are never looked at: a home the model has not seen (or a real routine dataset kept
outside the project) must get the same treatment. Folds are contiguous blocks of days, so a
validation fold is a stretch of days the model has not seen.

The activity model's parameters are chosen on next-activity F1 over held-out training days.
The object model's are then chosen where they matter: object F1 under the full protocol
(predicted activity, mixed over the activity distribution) on the held-out days, with the
chosen activity model. Last, the LLM gate (threshold d, replace or combine with weight w, or not
asking at all) is chosen the same way, so the LLM is used only as far as it helped on held-out
training days.
"""

from __future__ import annotations

import itertools
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Protocol, Sequence

from globe import assembly
from globe.config import GateConfig, GlobeConfig, ModelConfig
from globe.data.records import Day, Household
from globe.evaluation.metrics import f1
from globe.evaluation.protocol import evaluate_days
from globe.models.base import ActivityModelBase
from globe.reasoning.backends.base import LLMBackend
from globe.sequences.runs import training_sequences


@dataclass(frozen=True, slots=True)
class Selection:
    """The chosen parameters, every candidate's mean validation score, and the time it took."""

    best: dict[str, Any]
    scores: list[tuple[dict[str, Any], float]] = field(default_factory=list)
    seconds: float = 0.0


def grid(space: Mapping[str, Sequence[Any]]) -> list[dict[str, Any]]:
    keys = list(space)
    return [dict(zip(keys, values)) for values in itertools.product(*(space[k] for k in keys))]


def folds(n: int, k: int) -> list[tuple[list[int], list[int]]]:
    """Contiguous k-fold split of n items: (train indices, validation indices)."""
    k = max(2, min(k, n))
    bounds = [round(i * n / k) for i in range(k + 1)]
    return [([j for j in range(n) if not bounds[i] <= j < bounds[i + 1]], list(range(bounds[i], bounds[i + 1])))
            for i in range(k)]


class Fittable(Protocol):
    def fit(self, items: Sequence[Any]) -> Any: ...


def select(items: Sequence[Any], candidates: list[dict[str, Any]], make: Callable[[dict[str, Any]], Fittable],
           predict_fold: Callable[[Any, Sequence[Any]], tuple[list[str], list[str]]], k: int = 5) -> Selection:
    """Pick the candidate with the best mean weighted F1 over k folds (ties: listed first)."""
    started = time.perf_counter()
    splits = folds(len(items), k)
    scored = []
    for params in candidates:
        fold_scores: list[float] = []
        for train_idx, val_idx in splits:
            model = make(params).fit([items[i] for i in train_idx])
            true, pred = predict_fold(model, [items[i] for i in val_idx])
            fold_scores.append(f1(true, pred) or 0.0)  # a fold with nothing to score counts 0
        scored.append((params, sum(fold_scores) / len(fold_scores)))
    best = max(scored, key=lambda ps: ps[1])[0] if scored else {}
    return Selection(dict(best), scored, time.perf_counter() - started)


class _SharedFit:
    """One candidate activity model; candidates that count the same share one fit per fold."""

    def __init__(self, model: ActivityModelBase, fits: dict) -> None:
        self.model, self.fits = model, fits

    def fit(self, days: Sequence[Sequence[str]]) -> ActivityModelBase:
        m = self.model
        key = (type(m).__name__, tuple(sorted(m.fit_params().items())), tuple(map(id, days)))
        if key not in self.fits:
            self.fits[key] = m.fit(days)
        fitted = self.fits[key]
        return fitted if fitted is m else fitted.with_prediction_params(**m.prediction_params())


def activity_fold(model: ActivityModelBase, days: Sequence[Sequence[str]]) -> tuple[list[str], list[str]]:
    """Next-activity predictions at steps 1..T-1 of held-out days."""
    true, pred = [], []
    for day in days:
        for t, dist in enumerate(model.scan_proba(day)):
            if t == 0:
                continue
            true.append(day[t])
            pred.append(model.top(dist) or "<none>")
    return true, pred


class _MemoScan:
    """An activity model whose scans are memoised: every object and gate candidate of a fold
    scans the same held-out days with the same activity model."""

    def __init__(self, model: ActivityModelBase) -> None:
        self.model = model
        self._scans: dict[tuple[str, ...], list[dict[str, float]]] = {}

    def scan_proba(self, day: Sequence[str]) -> list[dict[str, float]]:
        key = tuple(day)
        if key not in self._scans:
            self._scans[key] = self.model.scan_proba(day)
        return self._scans[key]

    def ranked(self, distribution: dict[str, float]) -> list[str]:
        return self.model.ranked(distribution)

    def top(self, distribution: dict[str, float]) -> str | None:
        return self.model.top(distribution)


class _FoldModels:
    """Both models of one configuration, fitted on a fold of training days. Fits (and activity
    scans) are memoised per fold in ``memo`` by the built models' parameters, so candidates that
    differ only in the object model or the gate share one activity model."""

    def __init__(self, household: Household, config: GlobeConfig, memo: dict) -> None:
        self.household, self.config, self.memo = household, config, memo

    def fit(self, days: Sequence[Day]) -> "_FoldModels":
        fold = tuple(d.name for d in days)
        if ("sequences", fold) not in self.memo:
            self.memo[("sequences", fold)] = training_sequences(self.household, days, self.config.sequences.alignment)
        seqs = self.memo[("sequences", fold)]
        activity, objects = assembly.activity_model(self.config.models), assembly.object_model(self.config.models)
        act_key = ("activity", type(activity).__name__, tuple(sorted(activity.get_params().items())), fold)
        obj_key = ("objects", tuple(sorted(objects.get_params().items())), fold)
        if act_key not in self.memo:
            self.memo[act_key] = _MemoScan(activity.fit(seqs.activities))
        if obj_key not in self.memo:
            self.memo[obj_key] = objects.fit(seqs.runs)
        self.activity, self.objects = self.memo[act_key], self.memo[obj_key]
        return self


def _object_fold(gate: GateConfig, backend: LLMBackend | None) -> Callable[[_FoldModels, Sequence[Day]], tuple[list[str], list[str]]]:
    """Object predictions on held-out days under the full protocol, with the gate of ``gate``."""

    def predict(model: _FoldModels, days: Sequence[Day]) -> tuple[list[str], list[str]]:
        cfg = model.config
        chooser = assembly.object_chooser(model.objects, gate, backend, marginal=cfg.models.object_marginal)
        # every gate candidate of a fold ranks the same events with the same models: once
        rankings = model.memo.setdefault(("rankings", id(model.activity), id(model.objects)), {})
        ev = evaluate_days(model.household, days, model.activity, chooser, alignment=cfg.sequences.alignment,
                           rankings=rankings)
        return [r.true for r in ev.objects], [r.predicted for r in ev.objects]

    return predict


def selection_key(h: Household, cfg: GlobeConfig, family: str) -> tuple:
    """Everything a model search depends on: the household's data (a noisy variant shares its
    name), the family, the search space, the alignment and the base models."""
    return (h.name, hash(h.train), family, cfg.selection, cfg.sequences.alignment, cfg.models)


def tuned_models(h: Household, cfg: GlobeConfig, family: str, cache: dict) -> tuple[ModelConfig, dict[str, Selection]]:
    """Model configuration for ``family`` ("witten_bell" or "routine") chosen by k-fold CV on
    the training days; memoised in ``cache`` per household so methods share one search."""
    key = selection_key(h, cfg, family)
    if key in cache:
        return cache[key]
    sel = cfg.selection
    seqs = training_sequences(h, h.train, cfg.sequences.alignment)
    if family == "routine":
        space = grid({"activity_estimator": ["routine"], "routine_order": sel.routine_orders,
                      "routine_time_weight": sel.time_weights})
        base: dict[str, Any] = {"object_marginal": True}
    elif family == "witten_bell":
        space = grid({"activity_estimator": ["witten_bell"], "activity_max_order": sel.activity_orders,
                      "time_weight": sel.time_weights})
        base = {}
    else:
        raise ValueError(f"unknown model family {family!r}; expected 'routine' or 'witten_bell'")
    # The simpler models are candidates too, listed first so that they win ties: a home whose
    # routine is "the activity stays the same" gets persistence, not a model that overfits.
    simpler: list[dict[str, Any]] = [{"activity_estimator": "persistence"}, {"activity_estimator": "longest"}]
    fits: dict = {}  # one fit per fold and counting configuration: the candidates differ in how they predict
    act = select(seqs.activities, simpler + space,
                 lambda p: _SharedFit(assembly.activity_model(cfg.models.model_copy(update=base | p)), fits),
                 activity_fold, sel.folds)
    models = cfg.models.model_copy(update=base | act.best)
    ospace = grid({"object_estimator": sel.object_estimators, "run_start_token": sel.run_start_token})
    memo: dict = {}
    obj = select(list(h.train), ospace,
                 lambda p: _FoldModels(h, cfg.model_copy(update={"models": models.model_copy(update=p)}), memo),
                 _object_fold(cfg.gate, None), sel.folds)
    models = models.model_copy(update=obj.best)
    cache[key] = (models, {"activity": act, "objects": obj})
    return cache[key]


def tuned_gate(h: Household, cfg: GlobeConfig, models: ModelConfig, backend: LLMBackend, cache: dict,
               examples: int = 0) -> tuple[GateConfig, Selection]:
    """Gate settings chosen by k-fold CV on training days; "never ask" (d = 0) is a candidate
    and wins ties, so the LLM must earn its place on held-out days. ``examples`` recent runs of
    the activity personalise the prompt (fixed, not searched)."""
    key = (h.name, hash(h.train), "gate", models, examples, cfg.gate, cfg.selection, cfg.sequences.alignment,
           backend.name, backend.model_name)
    if key in cache:
        return cache[key]
    sel, g = cfg.selection, cfg.gate
    styles = [{"mode": "replace", "combine_weight": g.combine_weight}] + [
        {"mode": "combine", "combine_weight": w} for w in sel.combine_weights]
    space: list[dict[str, Any]] = [{"threshold": 0.0, "mode": "replace", "combine_weight": g.combine_weight}] + [
        {"threshold": d, **style} for d in sel.gate_thresholds for style in styles]
    fold_cfg = cfg.model_copy(update={"models": models})
    memo: dict = {}
    score: dict[int, float] = {}
    started = time.perf_counter()
    # The highest threshold asks every question a lower one asks: evaluating it first answers
    # each fold's questions in one batch, and the rest come from the answer cache.
    for i in sorted(range(len(space)), key=lambda i: -float(space[i]["threshold"])):
        gate = g.model_copy(update=space[i] | {"examples": examples})
        one = select(list(h.train), [space[i]], lambda p: _FoldModels(h, fold_cfg, memo), _object_fold(gate, backend),
                     sel.folds)
        score[i] = one.scores[0][1]
    scored = [(space[i], score[i]) for i in range(len(space))]
    best = max(scored, key=lambda ps: ps[1])[0]  # ties: listed first, so "never ask" wins them
    chosen = Selection(dict(best), scored, time.perf_counter() - started)
    cache[key] = (g.model_copy(update=chosen.best | {"examples": examples}), chosen)
    return cache[key]
