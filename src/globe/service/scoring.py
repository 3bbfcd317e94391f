"""Online scores: how well GLOBE does in one home, scored against what then happened.

- *Activity accuracy one step ahead*: when an observation opens step t+1 of a day, GLOBE's top
  next activity is taken from the state before it (what ``GET /prediction`` said, or would have
  said, for that step) and stored; when the step closes (the next step opens) it is compared with
  the step's observed activity. Steps whose activity stayed unknown, the first step of a day and
  steps after a gap are not scored.
- *Fetch precision and recall*: the fetches GLOBE decided (also in shadow mode) are scored when
  the day closes, by the offline rule of :func:`globe.evaluation.fetch.score_fetches` (a fetch is
  right when the object is then used within the policy's lead window).

The scores are counts per day (so days add up) in the store's ``day_scores`` table, written in
the same transaction as the observation that settles them: a restart keeps them.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass, field

from globe.config import GlobeConfig, PolicyConfig
from globe.evaluation.fetch import FetchReport, score_fetches
from globe.service.assistant import OnlineAssistant, Placement
from globe.service.schema import DayScore
from globe.service.schemas import OnlineScores
from globe.service.store import Store


@dataclass(slots=True)
class Settled:
    """What one observation settles: rows to write with it, and the prediction to remember once applied."""

    statements: list[tuple[str, tuple]] = field(default_factory=list)
    prediction: tuple[int, str, float] | None = None  # (step, activity, probability) for the step it opens


def lead_window(a: OnlineAssistant, policy: PolicyConfig) -> tuple[int, int]:
    return a.lead_window((policy.min_lead_minutes, policy.lead_window_minutes))


def before_observe(name: str, a: OnlineAssistant, place: Placement, policy: PolicyConfig) -> Settled:
    """The scores an observation at ``place`` settles, read before it is applied."""
    out = Settled()
    day = a.day
    if not place.new_step or day is None:
        return out
    if a.steps_today:
        last = a.steps_today - 1
        predicted, observed = a.step_predictions.get(last), a.observed_activity(last)
        if predicted is not None and observed is not None:
            out.statements.append(Store.observed_statement(name, day, last, observed))
            correct = int(predicted[0] == observed)
            out.statements.append(Store.score_statement(name, day, predictions=1, correct=correct))
        if place.step == 0:  # a new day, or a gap long enough to restart it: the day's fetches are settled
            report = fetch_report(a, policy)
            if report.fetches or report.used_objects:
                out.statements.append(Store.score_statement(name, day, fetches=report.fetches,
                                                            useful_fetches=report.useful_fetches,
                                                            uses=report.used_objects,
                                                            uses_fetched=report.used_fetched_in_advance))
            out.statements += Store.segment_closed_statements(name, day)
    if place.day == day and place.step == a.steps_today and place.step > 0:
        top = a.next_activity()
        if top is not None:
            out.prediction = (place.step, top[0], top[1])
            out.statements.append(Store.step_prediction_statement(name, day, place.step, *top))
    return out


def after_observe(a: OnlineAssistant, settled: Settled) -> None:
    """Remember the prediction made for the step just opened (it is scored when that step closes)."""
    if settled.prediction is not None:
        step, activity, probability = settled.prediction
        a.step_predictions[step] = (activity, probability)


def fetch_report(a: OnlineAssistant, policy: PolicyConfig) -> FetchReport:
    """Today's fetches so far scored against today so far (a fetch whose window is still open
    may yet turn out right)."""
    lo, hi = lead_window(a, policy)
    return score_fetches(a.household, a.current_day(), a.fetches_today, lo, hi)


def record_fetch(a: OnlineAssistant, obj: str, policy: PolicyConfig) -> int | None:
    """Note a fetch decided after the current step; returns that step, or None when the same
    object was decided within its window already (the threshold rule repeats itself)."""
    if not a.steps_today:
        return None
    now = a.steps_today - 1
    _, window = lead_window(a, policy)
    if any(obj in objs and now - t < window for t, objs in a.fetches_today.items()):
        return None
    a.fetches_today.setdefault(now, []).append(obj)
    return now


def restore(a: OnlineAssistant, store: Store, name: str) -> None:
    """After a (re)build: today's predictions and fetches from the store."""
    day = a.day
    if day is None:
        return
    a.step_predictions.update({p.step: (p.activity, p.probability) for p in store.step_predictions(name, day)})
    for f in store.fetches(name, day):
        a.fetches_today.setdefault(f.step, []).append(f.object)


def today_score(a: OnlineAssistant, store: Store, name: str, policy: PolicyConfig) -> DayScore | None:
    """Today's scores so far: the settled steps from the store, and today's fetches scored now."""
    day = a.day
    if day is None:
        return None
    stored = next(iter(store.day_scores(name, day)), DayScore(day))
    report = fetch_report(a, policy)
    return DayScore(day, stored.predictions, stored.correct, stored.fetches + report.fetches,
                    stored.useful_fetches + report.useful_fetches, stored.uses + report.used_objects,
                    stored.uses_fetched + report.used_fetched_in_advance)


__all__ = ["Settled", "after_observe", "before_observe", "fetch_report", "record_fetch", "restore", "today_score"]


def online_scores(store: Store, name: str, a: OnlineAssistant, config: GlobeConfig, days: int = 28) -> OnlineScores:
    """The per-day online scores of the last ``days`` days before the household's current day
    (today's so far included), and their totals."""
    today = a.day
    since = (dt.date.fromisoformat(today) - dt.timedelta(days=days - 1)).isoformat() if today else "0000"
    rows = [r for r in store.day_scores(name, since) if r.day != today]
    now = today_score(a, store, name, config.policy)
    if now is not None:
        rows.append(now)
    return OnlineScores.from_days(rows)
