"""The robustness suite on HOMER-Noise (the paper's Figs. 4-6).

- Robustness: train at ``noise.train_level``, test at ``noise.test_level``, per noise type,
  beside clean HOMER+.
  Object F1 twice: on all movement events (as the paper) and on the routine ones only
  (injected movements excluded via the manifest).
- Behavioural consistency: activities split into three equal groups by how regular they are
  across training days, by two definitions (see :func:`consistency_groups`); object F1 per group.
- Ablations: every training noise level of ``noise.levels`` (tested at ``noise.test_level``);
  every threshold d of ``noise.thresholds``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Mapping, Sequence

from globe.config import GlobeConfig
from globe.data.records import Household
from globe.evaluation.methods import METHODS, families
from globe.evaluation.metrics import CONSISTENCY_DEFINITIONS, consistency_groups, mean_present, records_f1, rounded
from globe.evaluation.parallel import precompute_selections
from globe.evaluation.protocol import Evaluation, evaluate_days
from globe.evaluation.selection import Memo
from globe.evaluation.tuning import chosen_alignment, tuned_models
from globe.noise.dataset import CLEAN, Dataset, clean_dataset, noisy_dataset
from globe.reasoning.backends.base import LLMBackend
from globe.sequences.movements import Alignment


def evaluate_dataset(cfg: GlobeConfig, data: Dataset, method: str, backend: LLMBackend | None,
                     memo: Memo | None = None, alignments: Mapping[str, Alignment] | None = None) -> list[Evaluation]:
    """Train on each household's training days and score its test days, marking injected events.
    ``memo`` keeps cross-validation results and fits (keyed by the days themselves);
    ``alignments`` fixes a household's movement alignment (by name) where the routine family would
    search it; every other method counts and is scored as configured, as on the clean homes."""
    memo = Memo() if memo is None else memo
    out = []
    for h in data.households:
        fixed = (alignments or {}).get(h.name) if METHODS[method].family == "routine" else None
        run = aligned(cfg, fixed)
        prepared = METHODS[method].prepare(h, run, backend, memo)

        def injected(day: str, step: int, obj: str, household: str = h.name) -> bool:
            return (household, day, step, obj) in data.injected

        alignment = prepared.alignment or run.sequences.alignment
        out.append(evaluate_days(h, h.test, prepared.activity, prepared.chooser, alignment=alignment,
                                 injected=injected, stay_margin=prepared.stay_margin))
    return out


def aligned(cfg: GlobeConfig, alignment: Alignment | None) -> GlobeConfig:
    """``cfg`` with the movement alignment fixed to ``alignment`` (not searched), or ``cfg``."""
    if alignment is None:
        return cfg
    return cfg.with_overrides({"sequences.alignment": alignment, "selection.alignments": [alignment]})


def clean_alignments(cfg: GlobeConfig, clean: Sequence[Household], methods: Sequence[str],
                     memo: Memo) -> dict[str, Alignment]:
    """The alignment cross-validation chose on each clean household. Which activity a movement is
    credited to is a property of how the home's log is made, and a noisy copy of a home is logged
    the same way: it keeps its clean home's alignment, and only its models are chosen again."""
    if "routine" not in families(methods):
        return {}
    precompute_selections(cfg, clean, ["routine"], memo)
    return {h.name: chosen_alignment(tuned_models(h, cfg, "routine", memo)[1], cfg) for h in clean}


def score_row(dataset: str, method: str, evals: Sequence[Evaluation], **extra: object) -> dict:
    """Mean over households (those with something to score) of activity F1, object F1 (all
    events) and object F1 (routine events); absent values stay None."""
    act = mean_present(records_f1(e.activity) for e in evals)
    obj = mean_present(records_f1(e.objects) for e in evals)
    routine = mean_present(records_f1([r for r in e.objects if not r.injected]) for e in evals)
    injected = sum(r.injected for e in evals for r in e.objects)
    mean = None if act is None or obj is None else rounded((act + obj) / 2)
    return {"dataset": dataset, "method": method, **extra, "activity_f1": rounded(act), "object_f1": rounded(obj),
            "object_f1_routine": rounded(routine), "mean_f1": mean,
            "object_events": sum(len(e.objects) for e in evals), "injected_events": injected}




def consistency_rows(dataset: str, method: str, evals: Sequence[Evaluation], groups: dict[str, dict[str, str]],
                     definition: str) -> list[dict]:
    rows = []
    for group in ("more", "moderate", "less"):
        recs = [r for e in evals for r in e.objects if groups.get(r.household, {}).get(r.true_activity) == group]
        rows.append({"dataset": dataset, "method": method, "definition": definition, "consistency": group,
                     "object_f1": rounded(records_f1(recs)), "object_events": len(recs)})
    return rows


@dataclass(slots=True)
class RobustnessResults:
    robustness: list[dict]
    consistency: list[dict]
    train_level: list[dict]
    threshold: list[dict]


def run_suite(cfg: GlobeConfig, clean: Sequence[Household], noise_root: Path, backend: LLMBackend | None,
              methods: Sequence[str] = ("ngram", "globe", "globe_personal", "routine"),
              progress: Callable[[str], None] | None = None, memo: Memo | None = None,
              loaded: dict[tuple[Path, str], Household] | None = None) -> RobustnessResults:
    """Robustness per noise type, consistency groups, and the two ablations (see the module doc).

    Each (dataset, training level, method, threshold) is evaluated once and reused by every table
    that needs it; ``memo`` holds cross-validation results already computed (on ``clean``, say);
    ``loaded`` the noisy households already in memory (by folder and name)."""
    names = [h.name for h in clean]
    n = cfg.noise
    methods = [m for m in methods if backend is not None or not METHODS[m].needs_llm]
    gate_method = "globe" if backend is not None else "ngram"
    groups = {d: consistency_groups(clean, d) for d in CONSISTENCY_DEFINITIONS}
    memo = Memo() if memo is None else memo
    done: dict[tuple[str, float, str, float], list[Evaluation]] = {}

    def evaluated(data: Dataset, level: float, method: str, threshold: float) -> list[Evaluation]:
        key = (data.name, level, method, threshold)
        if key not in done:
            if progress:
                progress(f"{data.name} (train level {level:g}): {method}, d = {threshold:g}")
            run_cfg = cfg if threshold == cfg.gate.threshold else cfg.with_overrides({"gate.threshold": threshold})
            done[key] = evaluate_dataset(run_cfg, data, method, backend, memo, None if data.name == CLEAN else fixed)
        return done[key]

    res = RobustnessResults([], [], [], [])
    loaded = {} if loaded is None else loaded  # noisy households, shared by the datasets built from them
    datasets = [(clean_dataset(clean), 0.0)] + [
        (noisy_dataset(noise_root, t, n.train_level, n.test_level, names, loaded), n.train_level) for t in n.types]
    fixed, clean_ids = clean_alignments(cfg, clean, methods, memo), {id(h) for h in clean}
    # every dataset's cross-validations at once, on several processes
    precompute_selections(cfg, [h for data, _ in datasets for h in data.households], families(methods), memo,
                          lambda h, family: cfg if id(h) in clean_ids or family != "routine"
                          else aligned(cfg, fixed.get(h.name)))
    for data, level in datasets:
        for method in methods:
            evals = evaluated(data, level, method, cfg.gate.threshold)
            res.robustness.append(score_row(data.name, method, evals))
            for definition, by_home in groups.items():
                res.consistency.extend(consistency_rows(data.name, method, evals, by_home, definition))
        for d in dict.fromkeys((cfg.gate.threshold, *n.thresholds)) if backend is not None else (cfg.gate.threshold,):
            res.threshold.append(score_row(data.name, gate_method, evaluated(data, level, gate_method, d), threshold=d))
    for t in n.types:
        for level in n.levels:
            data = noisy_dataset(noise_root, t, level, n.test_level, names, loaded)
            for method in dict.fromkeys(("ngram", gate_method)):
                evals = evaluated(data, level, method, cfg.gate.threshold)
                res.train_level.append(score_row(t, method, evals, train_level=level))
    res.threshold.sort(key=lambda r: (r["dataset"], r["threshold"]))
    return res
