"""The robustness suite on HOMER-Noise (the paper's Figs. 4-6).

- Robustness: train at noise level 0.5, test at 1.0, per noise type, beside clean HOMER+.
  Object F1 twice: on all movement events (as the paper) and on the routine ones only
  (injected movements excluded via the manifest).
- Behavioural consistency: activities split into three equal groups by how regular they are
  across training days, by two definitions (see :func:`consistency_groups`); object F1 per group.
- Ablations: training noise level 0.25 / 0.5 / 1.0 (test 1.0); threshold d 0.25 / 0.5 / 0.75.
"""

from __future__ import annotations

import statistics
from collections import Counter
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable, Sequence

from globe.config import GlobeConfig
from globe.data.csv_logs import load_household
from globe.data.records import Household
from globe.evaluation.methods import METHODS
from globe.evaluation.metrics import f1
from globe.evaluation.protocol import Evaluation, ObjectRecord, evaluate_days
from globe.noise.dataset import level_dir, read_manifest
from globe.reasoning.backends.base import LLMBackend
from globe.sequences.runs import activity_runs

CLEAN = "clean"


@dataclass(frozen=True, slots=True)
class Dataset:
    """Households to train and test on, and the injected test movements."""

    name: str
    households: list[Household]
    injected: set[tuple[str, str, int, str]]


def clean_dataset(households: Sequence[Household]) -> Dataset:
    return Dataset(CLEAN, list(households), set())


def noisy_dataset(root: Path, noise_type: str, train_level: float, test_level: float, names: Sequence[str]) -> Dataset:
    out = []
    for name in names:
        train = load_household(level_dir(root, noise_type, train_level), name)
        test = load_household(level_dir(root, noise_type, test_level), name)
        out.append(replace(train, test=test.test))
    return Dataset(noise_type, out, read_manifest(level_dir(root, noise_type, test_level) / "manifest.csv"))


def evaluate_dataset(cfg: GlobeConfig, data: Dataset, method: str, backend: LLMBackend | None) -> list[Evaluation]:
    cache: dict = {}  # CV results are per dataset (households share names across datasets)
    out = []
    for h in data.households:
        prepared = METHODS[method].prepare(h, cfg, backend, cache)
        out.append(evaluate_days(h, h.test, prepared.activity, prepared.chooser, alignment=cfg.sequences.alignment,
                                 injected=lambda day, step, obj, _h=h.name: (_h, day, step, obj) in data.injected))
    return out


def _obj_f1(records: Sequence[ObjectRecord]) -> float:
    return f1([r.true for r in records], [r.predicted for r in records])


def score_row(dataset: str, method: str, evals: Sequence[Evaluation], **extra: object) -> dict:
    """Mean over households of activity F1, object F1 (all events), object F1 (routine events)."""
    act = statistics.fmean(f1([r.true for r in e.activity], [r.predicted for r in e.activity]) for e in evals)
    obj = statistics.fmean(_obj_f1(e.objects) for e in evals)
    routine = statistics.fmean(_obj_f1([r for r in e.objects if not r.injected]) for e in evals)
    injected = sum(r.injected for e in evals for r in e.objects)
    return {"dataset": dataset, "method": method, **extra, "activity_f1": round(act, 4), "object_f1": round(obj, 4),
            "object_f1_routine": round(routine, 4), "mean_f1": round((act + obj) / 2, 4),
            "object_events": sum(len(e.objects) for e in evals), "injected_events": injected}


def _tertiles(spread: dict[str, float]) -> dict[str, str]:
    """Lowest third of spread -> 'more' consistent, middle -> 'moderate', top -> 'less'."""
    ordered = sorted(spread, key=lambda a: (spread[a], a))
    n = len(ordered)
    return {a: ("more" if i < n / 3 else "moderate" if i < 2 * n / 3 else "less") for i, a in enumerate(ordered)}


def consistency_groups(households: Sequence[Household], definition: str = "start_time") -> dict[str, dict[str, str]]:
    """Per household: activity -> 'more' / 'moderate' / 'less' consistent, from training days.

    ``start_time``: standard deviation of the activity's first start step across the days it
    occurs in. ``object_sequence``: 1 - the share of the activity's runs (with movements) whose
    object sequence is its most common one.
    """
    groups: dict[str, dict[str, str]] = {}
    for h in households:
        spread: dict[str, float] = {}
        if definition == "start_time":
            starts: dict[str, list[int]] = {}
            for day in h.train:
                seen = set()
                for t, a in enumerate(day.activities):
                    if a not in seen:
                        seen.add(a)
                        starts.setdefault(a, []).append(t)
            spread = {a: statistics.pstdev(s) for a, s in starts.items()}
        elif definition == "object_sequence":
            by_activity: dict[str, Counter[tuple[str, ...]]] = {}
            for day in h.train:
                for run in activity_runs(day, h.objects):
                    if run.objects:
                        by_activity.setdefault(run.activity, Counter())[run.objects] += 1
            spread = {a: 1 - c.most_common(1)[0][1] / sum(c.values()) for a, c in by_activity.items()}
        else:
            raise ValueError(f"unknown consistency definition {definition!r}; expected start_time or object_sequence")
        groups[h.name] = _tertiles(spread)
    return groups


CONSISTENCY_DEFINITIONS = ("start_time", "object_sequence")


def consistency_rows(dataset: str, method: str, evals: Sequence[Evaluation], groups: dict[str, dict[str, str]],
                     definition: str) -> list[dict]:
    rows = []
    for group in ("more", "moderate", "less"):
        recs = [r for e in evals for r in e.objects if groups.get(r.household, {}).get(r.true_activity) == group]
        rows.append({"dataset": dataset, "method": method, "definition": definition, "consistency": group,
                     "object_f1": round(_obj_f1(recs), 4) if recs else None, "object_events": len(recs)})
    return rows


@dataclass(slots=True)
class RobustnessResults:
    robustness: list[dict]
    consistency: list[dict]
    train_level: list[dict]
    threshold: list[dict]


def run_suite(cfg: GlobeConfig, clean: Sequence[Household], noise_root: Path, backend: LLMBackend | None,
              methods: Sequence[str] = ("ngram", "globe", "globe_personal", "routine"),
              progress: Callable[[str], None] | None = None) -> RobustnessResults:
    names = [h.name for h in clean]
    n = cfg.noise
    methods = [m for m in methods if backend is not None or not METHODS[m].needs_llm]
    gate_method = "globe" if backend is not None else "ngram"
    datasets = [clean_dataset(clean)] + [noisy_dataset(noise_root, t, n.train_level, n.test_level, names) for t in n.types]
    groups = {d: consistency_groups(clean, d) for d in CONSISTENCY_DEFINITIONS}
    res = RobustnessResults([], [], [], [])
    for data in datasets:
        for method in methods:
            if progress:
                progress(f"{data.name}: {method}")
            evals = evaluate_dataset(cfg, data, method, backend)
            res.robustness.append(score_row(data.name, method, evals))
            for definition, by_home in groups.items():
                res.consistency.extend(consistency_rows(data.name, method, evals, by_home, definition))
            if method == gate_method:
                res.threshold.append(score_row(data.name, method, evals, threshold=cfg.gate.threshold))
        for d in n.thresholds:
            if d == cfg.gate.threshold or backend is None:
                continue
            if progress:
                progress(f"{data.name}: threshold {d}")
            evals = evaluate_dataset(cfg.with_overrides({"gate.threshold": d}), data, gate_method, backend)
            res.threshold.append(score_row(data.name, gate_method, evals, threshold=d))
    for t in n.types:
        for level in n.levels:
            if progress:
                progress(f"{t}: train level {level}")
            data = noisy_dataset(noise_root, t, level, n.test_level, names)
            for method in ("ngram", gate_method) if gate_method != "ngram" else ("ngram",):
                evals = evaluate_dataset(cfg, data, method, backend)
                res.train_level.append(score_row(t, method, evals, train_level=level))
    res.threshold.sort(key=lambda r: (r["dataset"], r["threshold"]))
    return res


def write_robustness_results(out_dir: Path, res: RobustnessResults) -> None:
    """CSV tables, Markdown and PNG plots of the robustness suite."""
    from globe.evaluation import report
    from globe.evaluation.plots import consistency_figure, grouped_line_figure, robustness_figure
    from globe.evaluation.published import TABLE1

    out_dir.mkdir(parents=True, exist_ok=True)
    report.write_csv(out_dir / "robustness.csv", res.robustness)
    report.write_csv(out_dir / "consistency.csv", res.consistency)
    report.write_csv(out_dir / "ablation_train_level.csv", res.train_level)
    report.write_csv(out_dir / "ablation_threshold.csv", res.threshold)
    robustness_figure(res.robustness, {"SLaTe-PRO": TABLE1["slate_pro"][1]}).savefig(out_dir / "robustness.png", dpi=130)
    for method in dict.fromkeys(r["method"] for r in res.consistency):
        for definition in dict.fromkeys(r["definition"] for r in res.consistency):
            consistency_figure(res.consistency, method, definition).savefig(
                out_dir / f"consistency_{method}_{definition}.png", dpi=130)
    if res.train_level:
        grouped_line_figure([r | {"series": f"{r['dataset']} ({r['method']})"} for r in res.train_level], "train_level", "series",
                            "object_f1", "Training noise level (tested at 1.0)", "training noise level",
                            "object F1 (weighted)").savefig(out_dir / "ablation_train_level.png", dpi=130)
    if res.threshold:
        grouped_line_figure(res.threshold, "threshold", "dataset", "object_f1", "Gate threshold d",
                            "threshold d", "object F1 (weighted)").savefig(out_dir / "ablation_threshold.png", dpi=130)
    md = "\n".join(["# Robustness (train at noise 0.5, test at 1.0)", "", report.rows_markdown(res.robustness),
                    f"Published SLaTe-PRO on clean HOMER+: object F1 {TABLE1['slate_pro'][1]:.2f} (its per-noise values are "
                    "only shown graphically in the paper).", "",
                    "# Behavioural consistency", "", report.rows_markdown(res.consistency),
                    "# Ablation: training noise level", "", report.rows_markdown(res.train_level),
                    "# Ablation: threshold d", "", report.rows_markdown(res.threshold)])
    (out_dir / "robustness.md").write_text(md, encoding="utf-8")
