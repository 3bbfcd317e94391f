"""The robot loop offline: replay test days step by step with the fetch policy, no server needed.

Models are fitted on training days only and learn nothing from the test days. After each step t
(the activity and every object's place at t observed) the policy may start fetches. A fetch of
o at t is *useful* when the person first takes o at a step u with min_lead <= u - t <= window
(the object moved: its location at u differs from u-1). A use (every movement event) counts as
*fetched in advance* when o had been fetched at a step t with min_lead <= u - t <= window; its
lead time is minutes[u] - minutes[t]. An object fetched and not yet used is not fetched again
until its window has passed.

The forecasts do not depend on the costs, so they are computed once per step and every point
of the precision-recall curve over the cost ratio replays the same candidates.
"""

from __future__ import annotations

import statistics
from dataclasses import dataclass, field
from typing import Callable, Mapping, Sequence

from globe.data.records import Day, Household
from globe.inference.fetch_policy import FetchCandidate, FetchPolicy


@dataclass(slots=True)
class FetchReport:
    """What a robot team cares about, over some replayed days."""

    steps: int = 0
    fetches: int = 0
    useful_fetches: int = 0
    used_objects: int = 0
    used_fetched_in_advance: int = 0
    lead_minutes: list[int] = field(default_factory=list)

    @property
    def precision(self) -> float:
        return self.useful_fetches / self.fetches if self.fetches else 0.0

    @property
    def recall(self) -> float:
        return self.used_fetched_in_advance / self.used_objects if self.used_objects else 0.0

    @property
    def median_lead_min(self) -> float | None:
        return float(statistics.median(self.lead_minutes)) if self.lead_minutes else None


def day_candidates(policy: FetchPolicy, day: Day) -> list[list[FetchCandidate]]:
    """The policy's candidates after each step t = 0..T-2 of ``day`` (most likely useful first;
    every step's forecast computed in one batch)."""
    queries = [(day.activities[: t + 1], day.locations[: t + 1]) for t in range(len(day) - 1)]
    if not queries:
        return []
    forecasts = policy.forecaster.forecast_many(queries, policy.window_steps - 1, weekdays=[day.weekday] * len(queries))
    return policy.candidates_many(forecasts)


def use_steps(household: Household, day: Day) -> dict[str, list[int]]:
    """Object -> the steps at which it moved (was used) during ``day``."""
    out: dict[str, list[int]] = {}
    for t in range(1, len(day)):
        before, after = day.locations[t - 1], day.locations[t]
        if before != after:
            for j, obj in enumerate(household.objects):
                if before[j] != after[j]:
                    out.setdefault(obj, []).append(t)
    return out


def replay_day(policy: FetchPolicy, household: Household, day: Day, candidates: Sequence[Sequence[FetchCandidate]],
               report: FetchReport | None = None) -> FetchReport:
    """Replay one day with ``policy``'s decision rule over precomputed ``candidates``."""

    def decide(t: int, pending: Mapping[str, int]) -> list[str]:
        return [c.obj for c in policy.choose(candidates[t], exclude=pending)] if t < len(candidates) else []

    return _score(household, day, decide, len(candidates), policy.min_lead_steps, policy.window_steps, report)


def score_fetches(household: Household, day: Day, fetched: Mapping[int, Sequence[str]], min_lead_steps: int,
                  window_steps: int, report: FetchReport | None = None) -> FetchReport:
    """Score fetches already decided (``fetched``: step -> objects; an online service's decisions)
    over ``day`` as it then happened, by the same rule as :func:`replay_day` (a fetch of an object
    still pending, fetched and not yet used within its window, is not counted again)."""

    def decide(t: int, pending: Mapping[str, int]) -> list[str]:
        return [o for o in fetched.get(t, ()) if o not in pending]

    return _score(household, day, decide, len(day), max(1, min_lead_steps), window_steps, report)


def _score(household: Household, day: Day, decide: Callable[[int, Mapping[str, int]], Sequence[str]],
           decided_steps: int, lo: int, hi: int, report: FetchReport | None) -> FetchReport:
    """The module's rule: fetches decided after each step t < ``decided_steps``, uses as the day moved."""
    report = report or FetchReport()
    uses = use_steps(household, day)
    used_at: dict[int, list[str]] = {}
    for obj, steps in uses.items():
        for u in steps:
            used_at.setdefault(u, []).append(obj)
    pending: dict[str, int] = {}  # object -> step it was fetched
    for t in range(len(day)):
        for obj in sorted(used_at.get(t, ())):
            report.used_objects += 1
            fetched = pending.pop(obj, None)
            if fetched is not None and lo <= t - fetched <= hi:
                report.used_fetched_in_advance += 1
                report.lead_minutes.append(day.minutes[t] - day.minutes[fetched])
        for obj in [o for o, f in pending.items() if t - f >= hi]:
            del pending[obj]
        if t >= decided_steps:
            continue
        report.steps += 1
        for obj in decide(t, pending):
            report.fetches += 1
            pending[obj] = t
            report.useful_fetches += any(lo <= u - t <= hi for u in uses.get(obj, ()))
    return report


@dataclass(frozen=True, slots=True)
class FetchEvaluation:
    """One household: the configured policy's report and the curve over cost ratios."""

    household: str
    report: FetchReport
    curve: tuple[tuple[float, float, FetchReport], ...]  # (cost ratio useless/missed, threshold, report)


def evaluate_fetch(policy: FetchPolicy, household: Household, days: Sequence[Day],
                   ratios: Sequence[float]) -> FetchEvaluation:
    """Replay ``days`` with ``policy`` and with the same policy at each cost ratio in ``ratios``."""
    tables = [day_candidates(policy, d) for d in days]

    def run(p: FetchPolicy) -> FetchReport:
        report = FetchReport()
        for day, table in zip(days, tables):
            replay_day(p, household, day, table, report)
        return report

    curve = []
    for ratio in ratios:
        variant = FetchPolicy(policy.forecaster, cost_useless=ratio, cost_missed=1.0,
                              min_lead_steps=policy.min_lead_steps, window_steps=policy.window_steps,
                              max_fetches_per_step=policy.max_fetches_per_step)
        curve.append((float(ratio), variant.threshold, run(variant)))
    return FetchEvaluation(household.name, run(policy), tuple(curve))


FETCH_COLUMNS = ("household", "cost_ratio", "threshold", "fetches", "precision", "recall", "median_lead_min",
                 "configured")


def fetch_rows(evaluations: Sequence[FetchEvaluation], configured_ratio: float) -> list[dict]:
    """``fetch_policy.csv``: the precision-recall curve over the cost ratio, per household and pooled."""
    rows: list[dict] = []

    def row(name: str, ratio: float, threshold: float, rep: FetchReport) -> dict:
        lead = rep.median_lead_min
        return {"household": name, "cost_ratio": ratio, "threshold": round(threshold, 4), "fetches": rep.fetches,
                "precision": round(rep.precision, 4), "recall": round(rep.recall, 4),
                "median_lead_min": "" if lead is None else lead, "configured": abs(ratio - configured_ratio) < 1e-12}

    for ev in evaluations:
        rows.extend(row(ev.household, r, t, rep) for r, t, rep in ev.curve)
    if evaluations:
        for i, (r, t, _) in enumerate(evaluations[0].curve):
            rows.append(row("all", r, t, pooled([ev.curve[i][2] for ev in evaluations])))
    return rows


def pooled(reports: Sequence[FetchReport]) -> FetchReport:
    """Counts of several households added up (micro-averaged precision and recall)."""
    out = FetchReport()
    for r in reports:
        out.steps += r.steps
        out.fetches += r.fetches
        out.useful_fetches += r.useful_fetches
        out.used_objects += r.used_objects
        out.used_fetched_in_advance += r.used_fetched_in_advance
        out.lead_minutes.extend(r.lead_minutes)
    return out


def lead_time_rows(evaluations: Sequence[FetchEvaluation]) -> list[dict]:
    """``fetch_lead_times.csv``: how long before each use the configured policy had fetched it."""
    rows: list[dict] = []
    for ev in evaluations:
        counts: dict[int, int] = {}
        for lead in ev.report.lead_minutes:
            counts[lead] = counts.get(lead, 0) + 1
        rows.extend({"household": ev.household, "lead_min": lead, "uses": n} for lead, n in sorted(counts.items()))
    return rows
