"""Where the fetch policy's candidates come from, chosen by what the fetches cost on training days.

The lookahead chooses its objects (the movement model's forecast or the clock-aware uses model)
by relocation F1, the metric it is scored on; the fetch policy is scored on something else — a
useless fetch costs ``policy.cost_useless``, a use the robot did not fetch in advance
``policy.cost_missed`` — so its candidates are chosen by that cost, on held-out *training* days.

Each fold's held-out days are seen as a household session fitted on the fold's other days sees
them, fetching by the movement forecast (:func:`~globe.evaluation.fetch.forecast_day`: the
candidates, uses and fetches the session decides step by step, its forecasts made for all steps
at once); the clock-aware uses model's fetches are followed at the same steps by the same rule
(:func:`~globe.evaluation.fetch.evaluate_uses_baseline`, which a session built with that model
decides step for step). The movement forecast stays unless the clock-aware model costs less per
day fold by fold, beyond noise (:func:`~globe.evaluation.selection.best_beyond_noise`).
"""

from __future__ import annotations

import time
from dataclasses import replace
from typing import Sequence

from globe.config import Deployment, GlobeConfig, ModelConfig, PolicyConfig
from globe.data.records import Day, Household
from globe.evaluation.fetch import LAST_DATE, evaluate_uses_baseline, fit_uses_baseline, forecast_day, pooled
from globe.evaluation.lookahead import CLOCK, MOVEMENTS, Setting
from globe.evaluation.online import replay_dates
from globe.evaluation.selection import DataKey, Memo, SearchKey, Selection, best_beyond_noise
from globe.evaluation.tuning import data_folds, fold_days
from globe.inference.fetch_policy import FetchReport
from globe.session import build_session

SOURCES = (MOVEMENTS, CLOCK)
"""The candidate sources, in the order they win ties (the movement forecast first)."""

CRITERION = "-cost_per_day"


def fetch_cost(report: FetchReport, policy: PolicyConfig) -> float:
    """What the fetches of ``report`` cost: each useless fetch ``policy.cost_useless``, each use
    not fetched in advance ``policy.cost_missed``."""
    useless = report.fetches - report.useful_fetches
    missed = report.used_objects - report.used_fetched_in_advance
    return policy.cost_useless * useless + policy.cost_missed * missed


def policy_deployment(config: GlobeConfig, models: ModelConfig, setting: Setting,
                      fetch_objects: str = MOVEMENTS) -> Deployment:
    """The configured deployment with activity ``models``, the movement ``setting`` and the fetch
    source: what a fetch policy's session is built from, here and in the fetch table."""
    run_end, run_memory, run_next = setting
    return Deployment.configured(config).model_copy(update={
        "models": models, "run_end": run_end, "run_memory": run_memory, "run_next": run_next,
        "fetch_objects": fetch_objects})


def choose_fetch_source(household: Household, config: GlobeConfig, models: ModelConfig, setting: Setting,
                        memo: Memo | None = None) -> Selection:
    """The fetch policy's candidate source for ``household`` with activity ``models`` and the
    movement ``setting`` (run end, run memory, next activity): ``best`` is ``{"objects": ...}``,
    one of :data:`SOURCES`; ``scores`` the mean over folds of minus the cost per held-out day;
    ``metrics`` the pooled precision and recall of each. Kept in ``memo``."""
    key = SearchKey("fetch-source", DataKey.of(household),
                    (config.policy, config.lookahead, config.data.step_minutes, setting), models,
                    config.selection.folds, None)
    memo = Memo() if memo is None else memo
    return memo.get(key, _choose, household, config, models, setting)


def _choose(household: Household, config: GlobeConfig, models: ModelConfig, setting: Setting) -> Selection:
    started = time.perf_counter()
    per_fold: dict[str, list[float]] = {s: [] for s in SOURCES}
    reports: dict[str, list[FetchReport]] = {s: [] for s in SOURCES}
    deployment = policy_deployment(config, models, setting)
    for fold in data_folds(household, config.selection.folds):
        train, held_out = fold_days(household, fold)
        if not held_out or not train:
            continue
        for source, report in _fold_reports(household, config, deployment, train, held_out).items():
            per_fold[source].append(-fetch_cost(report, config.policy) / len(held_out))
            reports[source].append(report)
    best = best_beyond_noise([(s, per_fold[s]) for s in SOURCES])
    scores = [({"objects": s}, sum(per_fold[s]) / max(len(per_fold[s]), 1)) for s in SOURCES]
    metrics = []
    for s in SOURCES:
        total = pooled(reports[s])
        metrics.append({"precision": total.precision, "recall": total.recall, "fetches": float(total.fetches)})
    return Selection({"objects": best}, scores, time.perf_counter() - started, CRITERION, metrics)


def _fold_reports(household: Household, config: GlobeConfig, deployment: Deployment, train: Sequence[Day],
                  held_out: Sequence[Day]) -> dict[str, FetchReport]:
    """One fold's fetch reports at the configured costs, per source."""
    session = build_session(replace(household, train=tuple(train), test=tuple(held_out)), config, deployment, None,
                            learn=False)
    policy = session.policy
    dates = replay_dates(held_out, LAST_DATE)  # the weekdays a replay would give them
    seen = [forecast_day(session, household, day, date) for day, date in zip(held_out, dates)]
    clock = fit_uses_baseline(train, household.objects, policy.min_lead_steps, policy.window_steps, clock=True)
    return {MOVEMENTS: pooled([day.report for day in seen]),
            CLOCK: evaluate_uses_baseline(clock, policy, held_out, seen, household.name, ()).report}
