"""Anticipation, end to end: lookahead on SLaTe-PRO's relocation metric and the robot's fetch
policy, for every household, written to a results folder (``globe reproduce`` calls these).

Every choice is made on training days: the routine model's parameters by its cross-validation
(:func:`globe.evaluation.tuning.tuned_models`), the lookahead's change thresholds and movement
settings by :func:`globe.evaluation.lookahead.choose_settings`. The fetch policy has no fitted parameter:
its threshold follows from the configured costs.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Mapping, Sequence

from globe import assembly
from globe.config import GlobeConfig, ModelConfig
from globe.data.records import Household
from globe.evaluation import report
from globe.evaluation.fetch import FETCH_COLUMNS, FetchEvaluation, evaluate_fetch, fetch_rows, lead_time_rows
from globe.evaluation.lookahead import LOOKAHEAD_COLUMNS, LookaheadResult, choose_settings, evaluate_lookahead, lookahead_rows
from globe.evaluation.plots_anticipation import fetch_curve_figure, lead_time_figure, lookahead_figure, save_figure
from globe.evaluation.tuning import tuned_models


def method_models(method: str, household: Household, config: GlobeConfig, cache: dict) -> ModelConfig:
    """The activity-model configuration a lookahead method forecasts with."""
    if method == "persistence":
        return config.models.model_copy(update={"activity_estimator": "persistence"})
    if method == "ngram":
        return config.models.model_copy(update={"activity_estimator": "longest"})
    if method == "routine":
        return tuned_models(household, config, "routine", cache)[0]
    raise ValueError(f"unknown lookahead method {method!r}; expected persistence, ngram or routine")


@dataclass(frozen=True, slots=True)
class AnticipationResult:
    lookahead: tuple[LookaheadResult, ...]
    fetch: tuple[FetchEvaluation, ...]
    config: GlobeConfig


def run_anticipation(config: GlobeConfig, households: Mapping[str, Household] | Sequence[Household],
                     progress: Callable[[str], None] | None = None, cache: dict | None = None) -> AnticipationResult:
    """Lookahead for every configured method and the fetch policy on every household's test
    days. ``cache`` may be the main job's model-selection cache (so the routine CV runs once)."""
    homes = list(households.values()) if isinstance(households, Mapping) else list(households)
    cache = {} if cache is None else cache
    say = progress or (lambda _msg: None)
    look, fetch = [], []
    for h in homes:
        for method in config.lookahead.methods:
            say(f"lookahead: {method}, household {h.name}")
            look.append(evaluate_lookahead(h, config, method_models(method, h, config, cache), method, cache))
        say(f"fetch policy: household {h.name}")
        models = method_models(config.policy.method, h, config, cache)
        same = next((r for r in look if r.household == h.name and r.method == config.policy.method), None)
        if same is not None and same.forecaster is not None:  # the lookahead's forecaster (its paths are shared)
            forecaster = same.forecaster
        else:
            if same is None:  # the policy's method was not in the lookahead: choose its settings on training days
                best = choose_settings(h, config, models, cache=cache).best
                run_end, run_memory = bool(best["run_end"]), bool(best["run_memory"])
            else:
                run_end, run_memory = same.run_end, same.run_memory
            forecaster = assembly.forecaster(h, config, models=models, run_end=run_end, run_memory=run_memory).forecaster
        policy = assembly.fetch_policy(forecaster, config.policy, config.service.step_minutes)
        fetch.append(evaluate_fetch(policy, h, h.test, config.policy.curve_ratios))
    return AnticipationResult(tuple(look), tuple(fetch), config)


def _ratio(config: GlobeConfig) -> float:
    p = config.policy
    return p.cost_useless / p.cost_missed if p.cost_missed > 0 else float("inf")


def write_anticipation_results(out_dir: Path, result: AnticipationResult) -> list[Path]:
    """``lookahead.csv`` (+ selection, timing, plot), ``fetch_policy.csv`` (+ plot) and
    ``fetch_lead_times.csv`` (+ plot). Returns the paths written."""
    out_dir.mkdir(parents=True, exist_ok=True)
    step = result.config.service.step_minutes
    rows = lookahead_rows(result.lookahead, step)
    paths = {name: out_dir / name for name in ("lookahead.csv", "lookahead_selection.csv", "lookahead_timing.csv",
                                               "lookahead.png", "fetch_policy.csv", "fetch_policy.png",
                                               "fetch_lead_times.csv", "fetch_lead_times.png")}
    report.write_csv(paths["lookahead.csv"], rows, list(LOOKAHEAD_COLUMNS))
    report.write_csv(paths["lookahead_selection.csv"],
                     [{"method": r.method, "household": r.household, "run_end": p["run_end"], "run_memory": p["run_memory"],
                       "horizon_min": step * (p["horizon"] + 1), "threshold": p["threshold"], "cv_f1": round(s, 4),
                       "chosen": (p["run_end"], p["run_memory"]) == (r.run_end, r.run_memory)
                       and p["threshold"] == r.thresholds[p["horizon"]]}
                      for r in result.lookahead for p, s in r.selection.scores],
                     ["method", "household", "run_end", "run_memory", "horizon_min", "threshold", "cv_f1", "chosen"])
    report.write_csv(paths["lookahead_timing.csv"],
                     [{"method": r.method, "household": r.household, "train_s": round(r.train_s, 4)} for r in result.lookahead],
                     ["method", "household", "train_s"])
    save_figure(lookahead_figure(rows), paths["lookahead.png"])
    frows = fetch_rows(result.fetch, _ratio(result.config))
    report.write_csv(paths["fetch_policy.csv"], frows, list(FETCH_COLUMNS))
    save_figure(fetch_curve_figure(frows), paths["fetch_policy.png"])
    lrows = lead_time_rows(result.fetch)
    report.write_csv(paths["fetch_lead_times.csv"], lrows, ["household", "lead_min", "uses"])
    save_figure(lead_time_figure(lrows), paths["fetch_lead_times.png"])
    return list(paths.values())
