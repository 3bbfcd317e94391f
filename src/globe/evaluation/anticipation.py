"""Anticipation, end to end: lookahead on SLaTe-PRO's relocation metric and the robot's fetch
policy, for every household, written to a results folder (``globe reproduce`` calls these).

Every choice is made on training days: the routine model's parameters by its cross-validation
(:func:`globe.evaluation.tuning.tuned_models`), the lookahead's change thresholds and movement
settings by :func:`globe.evaluation.lookahead.choose_settings`, the fetch policy's candidate source
by what its fetches cost (:func:`globe.evaluation.fetch_source.choose_fetch_source`,
``fetch_selection.csv``). The fetch policy's threshold follows from the configured costs.

Both tables have a baseline row beside the models (``hour_activity``): objects by the clock and
the activity alone (:func:`~globe.evaluation.lookahead.evaluate_moves_baseline`,
:func:`~globe.evaluation.fetch.evaluate_uses_baseline`), counted on the same training days; and
an oracle row (``oracle``, not deployable): the movement model told the true activity ahead
(:func:`~globe.evaluation.lookahead.evaluate_oracle`,
:func:`~globe.evaluation.fetch.evaluate_oracle_fetch`), so the gap that is the activity's shows.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable, Mapping, Sequence

from globe import assembly
from globe.config import GlobeConfig, ModelConfig
from globe.data.records import Household
from globe.evaluation import report
from globe.evaluation.deploy import choose_deployment
from globe.evaluation.fetch import (
    FETCH_COLUMNS,
    FetchEvaluation,
    evaluate_fetch,
    evaluate_oracle_fetch,
    evaluate_uses_baseline,
    fetch_rows,
    fit_uses_baseline,
    lead_time_rows,
    replay_test_days,
)
from globe.evaluation.fetch_source import choose_fetch_source, policy_deployment
from globe.evaluation.lookahead import (
    BASELINE,
    CLOCK_OFFERED_TO,
    LOOKAHEAD_COLUMNS,
    MOVEMENTS,
    ORACLE,
    LookaheadResult,
    choose_settings,
    evaluate_lookahead,
    evaluate_moves_baseline,
    lookahead_rows,
    setting_of,
)
from globe.evaluation.parallel import run_forked, worker_count
from globe.evaluation.plots_anticipation import fetch_curve_figure, lead_time_figure, lookahead_figure, save_figure
from globe.evaluation.published import DataScope
from globe.evaluation.recognised import Recognised
from globe.evaluation.selection import Memo, SearchKey
from globe.evaluation.tuning import tuned_models
from globe.session import build_session

TASK_COST = {"routine": 5.0, "ngram": 1.3, "persistence": 1.0, BASELINE: 0.5, ORACLE: 0.5}
"""Rough relative cost of one household's lookahead per method (the routine model's CV costs most):
the parallel run starts the longest first."""


def method_models(method: str, household: Household, config: GlobeConfig, memo: Memo) -> ModelConfig:
    """The activity-model configuration a lookahead method forecasts with."""
    if method == "persistence":
        return config.models.model_copy(update={"activity_estimator": "persistence"})
    if method == "ngram":
        return config.models.model_copy(update={"activity_estimator": "longest"})
    if method == "routine":
        return tuned_models(household, config, "routine", memo)[0]
    raise ValueError(f"unknown lookahead method {method!r}; expected persistence, ngram or routine")


def lookahead_methods(config: GlobeConfig) -> list[str]:
    """The lookahead's rows: ``lookahead.methods``, the object baseline (after persistence, else
    first), so no table of models goes without the rule they must beat, and the oracle last, so
    none goes without what perfect activity knowledge would give."""
    methods = [m for m in config.lookahead.methods if m not in (BASELINE, ORACLE)]
    at = methods.index("persistence") + 1 if "persistence" in methods else 0
    return [*methods[:at], BASELINE, *methods[at:], ORACLE]


@dataclass(frozen=True, slots=True)
class AnticipationResult:
    lookahead: tuple[LookaheadResult, ...]
    fetch: tuple[FetchEvaluation, ...]
    config: GlobeConfig
    step_minutes: int  # of every household (:func:`globe.assembly.common_step`)


def run_anticipation(config: GlobeConfig, households: Mapping[str, Household] | Sequence[Household],
                     progress: Callable[[str], None] | None = None, memo: Memo | None = None,
                     recognised: Sequence[Recognised] = ()) -> AnticipationResult:
    """Lookahead for every configured method and the fetch policy on every household's test
    days. ``memo`` may be the main job's (so the routine CV runs once). A household among
    ``recognised`` (its activities recognised from its sensors) has its fetches decided by a
    session told its sensors and no label, as such a home is served.

    Each (household, method) runs on its own process (``evaluation.workers``; the fetch policy
    with its method's lookahead, whose forecaster it shares). The lookahead's cross-validated
    pairs come back into ``memo``, where the missing-label runs look for them."""
    homes = list(households.values()) if isinstance(households, Mapping) else list(households)
    sensing = {r.household.name: r for r in recognised}
    step = assembly.common_step(homes, config)
    memo = Memo() if memo is None else memo
    policy_method = config.policy.method
    tasks: list[tuple[Household, str | None]] = [(h, m) for h in homes for m in lookahead_methods(config)]
    tasks += [(h, None) for h in homes if policy_method not in config.lookahead.methods]
    if progress:
        progress(f"lookahead and fetch policy: {len(tasks)} households x methods (in parallel)")
    before = memo.keys()

    def run(i: int) -> tuple[LookaheadResult | None, tuple[FetchEvaluation, ...], dict]:
        h, method = tasks[i]
        look = None
        if method == BASELINE:
            look = evaluate_moves_baseline(h, config)
        elif method == ORACLE:
            look = evaluate_lookahead(h, config, config.models, ORACLE, memo)
        elif method is not None:
            look = evaluate_lookahead(h, config, method_models(method, h, config, memo), method, memo)
        fetch = _fetch(h, config, memo, look, sensing.get(h.name)) if method in (None, policy_method) else ()
        shared = memo.entries(lambda k: k not in before and isinstance(k, SearchKey) and k.search == "lookahead-cv")
        return None if look is None else replace(look, forecaster=None), fetch, shared

    look: list[LookaheadResult] = []
    fetch: list[FetchEvaluation] = []
    cost = [TASK_COST.get(method or "", 1.0) for _, method in tasks]
    for result, evaluations, shared in run_forked(run, len(tasks), worker_count(config.evaluation.workers), cost):
        memo.update(shared)
        look += [result] if result is not None else []
        fetch += evaluations
    order = {h.name: i for i, h in enumerate(homes)}
    fetch.sort(key=lambda e: ((BASELINE, ORACLE).index(e.method) + 1 if e.method in (BASELINE, ORACLE) else 0,
                              order[e.household]))
    return AnticipationResult(tuple(look), tuple(fetch), config, step)


def _fetch(h: Household, config: GlobeConfig, memo: Memo, same: LookaheadResult | None,
           recognised: Recognised | None = None) -> tuple[FetchEvaluation, ...]:
    """The fetch policy on ``h``'s test days: replayed through a session of the policy's method,
    whose movement model has the settings the lookahead of that method chose on training days
    (``same``, when it ran) and, for a method the clock-aware uses model is offered to, the
    candidate source whose fetches cost least on held-out training days
    (:func:`~globe.evaluation.fetch_source.choose_fetch_source`; ``Deployment.fetch_objects``);
    then the baseline's and the oracle's fetches at the same steps by the same rule. With
    ``recognised``, the session is the one such a home is served: deployed with the policy's
    method as ``globe train`` deploys it (its filter's movement evidence chosen too), reading the
    home's sensors with the recogniser's settings as chosen, told no label."""
    models = method_models(config.policy.method, h, config, memo)
    if same is None:  # the policy's method was not in the lookahead: choose its settings on training days
        setting = setting_of(choose_settings(h, config, models, memo).best)
    else:
        setting = (same.run_end, same.run_memory, same.run_next)
    source = None
    if config.policy.method in CLOCK_OFFERED_TO:
        source = choose_fetch_source(h, config, models, setting, memo)
    if recognised is None:
        deployment = policy_deployment(config, models, setting, MOVEMENTS if source is None else source.best["objects"])
    else:  # as such a home is served: its deployment's filter reads the sensors
        deployment = choose_deployment(h, config, memo, config.policy.method)
    sensors = None if recognised is None else recognised.sensors
    session = build_session(h, config, deployment, None, learn=False, sensors=sensors, questions_per_day=0,
                            recognition=None if recognised is None else recognised.recognition)
    replayed = replay_test_days(session, h, h.test, sensors)
    policy = session.policy
    ratios = config.policy.curve_ratios
    baseline = fit_uses_baseline(h.train, h.objects, policy.min_lead_steps, policy.window_steps)
    mine = replace(evaluate_fetch(session, h, h.test, ratios, config.policy.method, replayed), source=source)
    return (mine, evaluate_uses_baseline(baseline, policy, h.test, replayed, h.name, ratios),
            evaluate_oracle_fetch(policy, h.test, replayed, h.name, ratios))


SELECTION_COLUMNS = ("method", "household", "objects", "cv_cost_per_day", "cv_precision", "cv_recall", "chosen")


def fetch_selection_rows(evaluations: Sequence[FetchEvaluation]) -> list[dict]:
    """``fetch_selection.csv``: per household whose candidate source was cross-validated, each
    source's cost per held-out training day (and its pooled precision and recall there), and
    which was chosen."""
    rows = []
    for ev in evaluations:
        if ev.source is None:
            continue
        for (params, score), metrics in zip(ev.source.scores, ev.source.metrics):
            rows.append({"method": ev.method, "household": ev.household, "objects": params["objects"],
                         "cv_cost_per_day": round(-score, 4), "cv_precision": round(metrics["precision"], 4),
                         "cv_recall": round(metrics["recall"], 4), "chosen": params == ev.source.best})
    return rows


def _ratio(config: GlobeConfig) -> float:
    p = config.policy
    return p.cost_useless / p.cost_missed if p.cost_missed > 0 else float("inf")


def write_anticipation_results(out_dir: Path, result: AnticipationResult, scope: DataScope) -> list[Path]:
    """``lookahead.csv`` (+ selection, timing, plot), ``fetch_policy.csv`` (+ plot, and the choice
    of its candidate source: ``fetch_selection.csv``) and ``fetch_lead_times.csv`` (+ plot).
    Returns the paths written."""
    out_dir.mkdir(parents=True, exist_ok=True)
    step = result.step_minutes
    rows = lookahead_rows(result.lookahead, step)
    paths = {name: out_dir / name for name in ("lookahead.csv", "lookahead_selection.csv", "lookahead_timing.csv",
                                               "lookahead.png", "fetch_policy.csv", "fetch_selection.csv",
                                               "fetch_policy.png", "fetch_lead_times.csv", "fetch_lead_times.png")}
    report.write_csv(paths["lookahead.csv"], rows, list(LOOKAHEAD_COLUMNS))
    report.write_csv(paths["lookahead_selection.csv"],
                     [{"method": r.method, "household": r.household,
                       "run_end": p["run_end"], "run_memory": p["run_memory"], "run_next": p["run_next"],
                       "horizon_min": step * (p["horizon"] + 1), "threshold": p["threshold"], "cv_f1": round(s, 4),
                       "chosen": (p["run_end"], p["run_memory"], p["run_next"]) == (r.run_end, r.run_memory, r.run_next)
                       and p.get("objects", r.objects) == r.objects and p["threshold"] == r.thresholds[p["horizon"]],
                       "objects": p.get("objects", r.objects)}
                      for r in result.lookahead for p, s in r.selection.scores],
                     ["method", "household", "run_end", "run_memory", "run_next", "horizon_min", "threshold", "cv_f1",
                      "chosen", "objects"])
    timing = [{"method": r.method, "household": r.household, "train_s": round(r.train_s, 4)} for r in result.lookahead]
    report.write_csv(paths["lookahead_timing.csv"], timing, ["method", "household", "train_s"])
    save_figure(lookahead_figure(rows, scope), paths["lookahead.png"])
    report.write_csv(paths["fetch_selection.csv"], fetch_selection_rows(result.fetch), list(SELECTION_COLUMNS))
    frows = fetch_rows(result.fetch, _ratio(result.config))
    report.write_csv(paths["fetch_policy.csv"], frows, list(FETCH_COLUMNS))
    save_figure(fetch_curve_figure(frows), paths["fetch_policy.png"])
    lrows = lead_time_rows([ev for ev in result.fetch if ev.method not in (BASELINE, ORACLE)])
    report.write_csv(paths["fetch_lead_times.csv"], lrows, ["household", "lead_min", "uses"])
    save_figure(lead_time_figure(lrows), paths["fetch_lead_times.png"])
    return list(paths.values())
