"""The fetch policy scored: test days replayed through the household's session, as the robot runs.

Models are fitted on training days only and learn nothing from the test days. After each step t
(the activity and every object's place at t observed) the session decides its fetches by the one
rule of fetches (:func:`globe.inference.fetch_policy.follow_fetches`): a fetch of o at t is
*useful* when the person next uses o (it moves) at a step u with min_lead <= u - t <= window; a
use counts as *fetched in advance* when o had been fetched at a step t with min_lead <= u - t <=
window, its lead time minutes[u] - minutes[t]; an object fetched and not yet used is not fetched
again until its window has passed, and none is fetched while in use or just put back.

The candidates do not depend on the costs, so each step's are kept from the replay and every
point of the precision-recall curve over the cost ratio follows the same rule over them; at the
configured costs that is exactly what the session decided.

Beside it, the object baseline (:data:`BASELINE`): the same days, steps and rule, its candidates
P(o is used within the lead window | the activity at t, the clock slot) counted on training days
(:class:`~globe.models.baselines.HourActivityAhead`), so the table shows what a robot would get
from the clock and the activity alone; and the oracle (:data:`ORACLE`): the same steps and rule,
its candidates from the policy's own movement model told the true activity of every step of the
lead window (:func:`~globe.inference.forecast.forecast_known`), what perfect activity knowledge
would give. Where cross-validation on the fetch cost chose the clock-aware uses model for the
policy's method (:mod:`globe.evaluation.fetch_source`), the session is built with that model as
its fetch policy's candidates (``Deployment.fetch_objects``, as the service builds such a home's),
so that row too is what the session decided. A home whose activities are recognised from its
sensors (``globe evaluate --activities recognised``) is replayed with its sensors and no label, as
it is served.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass, replace
from typing import Callable, Mapping, Sequence

from globe.data.records import Day, Household
from globe.data.sensors import SensorData
from globe.evaluation.lookahead import ORACLE
from globe.evaluation.online import add_report, day_observations, replay, replay_dates
from globe.evaluation.selection import Selection
from globe.inference.fetch_policy import (
    FetchCandidate,
    FetchContext,
    FetchPolicy,
    FetchReport,
    follow_fetches,
    left_alone,
)
from globe.inference.forecast import Forecast, forecast_known
from globe.models.baselines import HOUR_ACTIVITY, HourActivityAhead, fit_uses_ahead, minutes_since_use, used_matrix
from globe.sequences.movements import moved_objects
from globe.session import HouseholdSession

BASELINE = HOUR_ACTIVITY
"""The fetch table's baseline row: fetches by the clock and the activity alone."""

LAST_DATE = dt.date(2000, 12, 31)  # what the test days are replayed up to (their weekdays kept)


@dataclass(frozen=True, slots=True)
class ReplayedDay:
    """One day as the session saw it, step by step: when each step began, what was used at it,
    the candidate fetches after it and the objects no fetch could touch."""

    minutes: tuple[int, ...]
    uses: tuple[frozenset[str], ...]
    candidates: tuple[tuple[FetchCandidate, ...], ...]
    left_alone: tuple[frozenset[str], ...]
    report: FetchReport  # what the session decided, scored


def replay_day(session: HouseholdSession, household: Household, day: Day, date: dt.date,
               sensors: SensorData | None = None) -> ReplayedDay:
    """Every row of ``day`` on ``date`` through ``session`` (a session that does not learn); with
    ``sensors`` (the home's), each row's activations and no label, as a home nobody labels is served."""
    if sensors is not None and session.sensing is None:
        raise ValueError(f"{household.name}: a session built without sensors cannot be told them (build it with them)")
    hidden = None if sensors is None else (lambda _row: False)
    rows = day_observations(household, day, date, visible=hidden, sensors=sensors)
    records, _ = replay(session, [(day.name, t, obs) for t, obs in rows])
    n = session.step + 1 if session.step is not None else 0
    candidates: list[tuple[FetchCandidate, ...]] = [()] * n
    alone: list[frozenset[str]] = [frozenset()] * n
    for r in records:
        candidates[r.decision.step - 1] = r.decision.candidates
        alone[r.decision.step - 1] = r.decision.left_alone
    minutes = tuple(session.grid.minute(t) for t in range(n))
    return ReplayedDay(minutes, tuple(session.uses()), tuple(candidates), tuple(alone), session.fetch_report())


def forecast_day(session: HouseholdSession, household: Household, day: Day, date: dt.date,
                 chunk: int = 256) -> ReplayedDay:
    """:func:`replay_day` of a day with every step labelled, its forecasts made for all steps at
    once: the same uses (:func:`~globe.sequences.movements.moved_objects`), the same candidates
    after each step the session decides at (``session.policy``'s movement forecast of the day so
    far, as seen, on ``date``'s day of the week), the same objects no fetch could touch and the
    same fetches, several times faster (a test checks they are equal). A day off the session's
    grid (other minutes, or longer) is replayed. For choices on training days; the scores replay."""
    grid, policy, n = session.grid, session.policy, len(day)
    if n > grid.last_step + 1 or day.minutes != tuple(grid.minute(t) for t in range(n)):
        return replay_day(session, household, day, date)
    decided = min(n, grid.last_step)  # none after the grid's last step, as the session
    queries = [(day.seen[: t + 1], day.locations[: t + 1]) for t in range(decided)]
    candidates: list[tuple[FetchCandidate, ...]] = []
    for lo in range(0, len(queries), chunk):
        part = queries[lo: lo + chunk]
        fcs = policy.forecaster.forecast_many(part, policy.window_steps - 1, weekdays=[date.weekday()] * len(part))
        candidates += [tuple(policy.candidates_from(fcs[q])) for q in range(len(part))]
    rows, places = day.locations, household.use_places
    alone = [left_alone(household.objects, rows[t - 1] if t else rows[t], rows[t], places) if t < decided
             else frozenset() for t in range(n)]
    replayed = ReplayedDay(day.minutes, tuple(moved_objects(day, household.objects)),
                           (*candidates, *[()] * (n - decided)), tuple(alone), FetchReport())
    return replace(replayed, report=follow_policy(policy, replayed))


def follow_policy(policy: FetchPolicy, day: ReplayedDay, report: FetchReport | None = None) -> FetchReport:
    """``policy``'s decisions over a replayed day's candidates, scored by the one rule of fetches."""
    def decide(t: int, waiting: Mapping[str, int]) -> list[str]:
        return [c.obj for c in policy.choose(day.candidates[t], exclude=set(waiting) | day.left_alone[t])]

    return follow_fetches(day.uses, day.minutes, decide, len(day.minutes), policy.min_lead_steps, policy.window_steps,
                          report)[0]


@dataclass(frozen=True, slots=True)
class FetchEvaluation:
    """One household: the configured policy's report and the curve over cost ratios."""

    household: str
    report: FetchReport
    curve: tuple[tuple[float, float, FetchReport], ...]  # (cost ratio useless/missed, threshold, report)
    method: str = ""  # whose candidates: the policy's method, or BASELINE
    source: Selection | None = None  # where cross-validated: the candidate source's choice (fetch_source)


def replay_test_days(session: HouseholdSession, household: Household, days: Sequence[Day],
                     sensors: SensorData | None = None) -> list[ReplayedDay]:
    """``days`` replayed through ``session``, which must not learn (with ``sensors``: told no label)."""
    if session.learning:
        raise ValueError("the fetch policy is scored with models that learn nothing from the test days")
    dates = replay_dates(days, LAST_DATE)
    return [replay_day(session, household, day, date, sensors) for day, date in zip(days, dates)]


def evaluate_fetch(session: HouseholdSession, household: Household, days: Sequence[Day],
                   ratios: Sequence[float], method: str = "", replayed: Sequence[ReplayedDay] | None = None
                   ) -> FetchEvaluation:
    """Replay ``days`` through ``session`` (which must not learn; ``replayed``: already done), then
    follow the same policy at each cost ratio in ``ratios`` over the candidates it saw."""
    replayed = replay_test_days(session, household, days) if replayed is None else replayed
    return FetchEvaluation(household.name, pooled([day.report for day in replayed]),
                           _curve(session.policy, replayed, ratios), method)


def _curve(policy: FetchPolicy, replayed: Sequence[ReplayedDay],
           ratios: Sequence[float]) -> tuple[tuple[float, float, FetchReport], ...]:
    """``policy`` at each cost ratio over the candidates of ``replayed``."""
    curve = []
    for ratio in ratios:
        variant = policy.with_costs(ratio, 1.0)
        report = FetchReport()
        for day in replayed:
            follow_policy(variant, day, report)
        curve.append((float(ratio), variant.threshold, report))
    return tuple(curve)


def fit_uses_baseline(days: Sequence[Day], objects: Sequence[str], min_lead: int, window: int,
                      clock: bool = False) -> HourActivityAhead:
    """The baseline's P(a use within the lead window) on ``days``: :func:`~globe.models.baselines.fit_uses_ahead`
    (with ``clock``, the clock-aware model a session fetches by where cross-validation chose it)."""
    return fit_uses_ahead(days, objects, min_lead, window, clock=clock)


Candidates = Callable[[Day, Sequence[int]], Sequence[tuple[FetchCandidate, ...]]]
"""``candidates(day, rows)``: the candidate fetches after each of ``rows`` (steps of ``day``)."""


def evaluate_candidates(candidates_at: Candidates, policy: FetchPolicy, days: Sequence[Day],
                        replayed: Sequence[ReplayedDay], household: str, ratios: Sequence[float], method: str
                        ) -> FetchEvaluation:
    """A row of other candidates than the session's: at each step the session decided (of
    ``replayed``, ``days`` replayed), ``candidates_at``'s instead, followed by ``policy``'s rule
    (its costs: the configured report; each of ``ratios``: the curve)."""
    mine = []
    for day, seen in zip(days, replayed):
        row = {m: t for t, m in enumerate(day.minutes)}
        asked = [(i, row[minute]) for i, (minute, theirs) in enumerate(zip(seen.minutes, seen.candidates))
                 if theirs and minute in row]  # else the session decided nothing here (the day's last step)
        candidates: list[tuple[FetchCandidate, ...]] = [()] * len(seen.candidates)
        for (i, _), found in zip(asked, candidates_at(day, [r for _, r in asked]) if asked else ()):
            candidates[i] = tuple(found)
        mine.append(replace(seen, candidates=tuple(candidates)))
    reports = [follow_policy(policy, day) for day in mine]
    return FetchEvaluation(household, pooled(reports), _curve(policy, mine, ratios), method)


def evaluate_uses_baseline(baseline: HourActivityAhead, policy: FetchPolicy, days: Sequence[Day],
                           replayed: Sequence[ReplayedDay], household: str, ratios: Sequence[float],
                           method: str = BASELINE) -> FetchEvaluation:
    """The baseline row: :func:`evaluate_candidates` of P(a use within the lead window) by
    ``baseline``, read as a session's policy reads its uses model
    (:meth:`~globe.inference.fetch_policy.FetchPolicy.candidates_from_uses`)."""
    def candidates_at(day: Day, rows: Sequence[int]) -> list[tuple[FetchCandidate, ...]]:
        since = minutes_since_use(used_matrix(day, baseline.objects), day.minutes)
        return [tuple(policy.candidates_from_uses(baseline, FetchContext(day.seen[r], day.minutes[r], day.weekday,
                                                                         since[r], _no_forecast)))
                for r in rows]

    return evaluate_candidates(candidates_at, policy, days, replayed, household, ratios, method)


def _no_forecast(horizon: int) -> Forecast:
    raise AssertionError("the uses baseline reads no forecast")


def evaluate_oracle_fetch(policy: FetchPolicy, days: Sequence[Day], replayed: Sequence[ReplayedDay], household: str,
                          ratios: Sequence[float]) -> FetchEvaluation:
    """The oracle row: :func:`evaluate_candidates` of ``policy``'s own movement model told the true
    activities of steps t..t+window (:func:`~globe.inference.forecast.forecast_known`)."""
    movements, window = policy.forecaster.movements, policy.window_steps

    def candidates_at(day: Day, rows: Sequence[int]) -> list[tuple[FetchCandidate, ...]]:
        fcs = forecast_known(movements, [(day.activities[: r + 1], day.locations[: r + 1]) for r in rows],
                             [day.activities[r: r + window + 1] for r in rows], window - 1)
        return [tuple(policy.candidates_from(fcs[q])) for q in range(len(rows))]

    return evaluate_candidates(candidates_at, policy, days, replayed, household, ratios, ORACLE)


FETCH_COLUMNS = ("method", "household", "cost_ratio", "threshold", "fetches", "precision", "recall", "median_lead_min",
                 "configured")


def fetch_rows(evaluations: Sequence[FetchEvaluation], configured_ratio: float) -> list[dict]:
    """``fetch_policy.csv``: the precision-recall curve over the cost ratio, per method (the
    policy's, then the baseline), per household and pooled."""
    rows: list[dict] = []
    for method in dict.fromkeys(ev.method for ev in evaluations):
        rows += _method_rows(method, [ev for ev in evaluations if ev.method == method], configured_ratio)
    return rows


def _method_rows(method: str, evaluations: Sequence[FetchEvaluation], configured_ratio: float) -> list[dict]:
    rows: list[dict] = []

    def row(name: str, ratio: float, threshold: float, rep: FetchReport) -> dict:
        lead = rep.median_lead_min
        return {"method": method, "household": name, "cost_ratio": ratio, "threshold": round(threshold, 4),
                "fetches": rep.fetches, "precision": round(rep.precision, 4), "recall": round(rep.recall, 4),
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
        add_report(out, r)
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
