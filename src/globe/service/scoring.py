"""Online scores kept in the database: how well GLOBE does in one home, against what then happened.

What an observation settles is the session's rule (:meth:`globe.session.HouseholdSession.settle`,
the same that scores a replay offline): the one-step activity prediction of the step it closes
(with whether persistence and hour + activity were right there, so the rules the model must beat
are scored over the same steps), and, when it starts a new day, the finished day's fetches (a
fetch is right when the object is then used within the policy's lead window). Here those become
rows of the store's ``day_scores`` table (counts per day, so days add up), written in the same
transaction as the observation that settles them: a restart keeps them.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import replace

from globe.service.schema import SCORE_COLUMNS, DayScore
from globe.service.schemas import OnlineScores
from globe.service.store import Store
from globe.session import HouseholdSession
from globe.session.records import Settled

Statement = tuple[str, tuple]


def statements(name: str, settled: Settled) -> list[Statement]:
    """The rows an observation's :class:`Settled` writes with it: the closed step's label beside
    its one-step prediction and whether it (and each baseline) was right, the finished day's fetch counts (its
    fetches marked counted, its step predictions dropped), the opened step's one-step prediction."""
    out: list[Statement] = []
    day = settled.day
    if day is None:
        return out
    if settled.observed is not None and settled.scored is not None:
        step, label = settled.observed
        out.append(("UPDATE step_predictions SET observed = ? WHERE household = ? AND day = ? AND step = ?",
                    (label, name, day, step)))
        right = settled.baselines or (False, False)
        out.append(_scores(name, day, predictions=1, correct=int(settled.scored[1]),
                           baseline_predictions=int(settled.baselines is not None),
                           persistence_correct=int(right[0]), hour_activity_correct=int(right[1])))
    report = settled.fetches
    if report is not None:
        if report.fetches or report.used_objects:
            out.append(_scores(name, day, fetches=report.fetches, useful_fetches=report.useful_fetches,
                               uses=report.used_objects, uses_fetched=report.used_fetched_in_advance))
        out += [("UPDATE fetches SET settled = 1 WHERE household = ? AND day = ?", (name, day)),
                ("DELETE FROM step_predictions WHERE household = ? AND day = ?", (name, day))]
    if settled.opened is not None:
        out.append(("INSERT OR REPLACE INTO step_predictions (household, day, step, activity, probability) "
                    "VALUES (?, ?, ?, ?, ?)", (name, day, *settled.opened)))
    return out


def _scores(household: str, day: str, **counts: int) -> Statement:
    """Add ``counts`` (columns of :data:`~globe.service.schema.SCORE_COLUMNS`) to the day's scores."""
    names = [c for c in SCORE_COLUMNS if counts.get(c)] or ["predictions"]
    return (f"INSERT INTO day_scores (household, day, {', '.join(names)}) VALUES (?, ?{', ?' * len(names)}) "
            f"ON CONFLICT (household, day) DO UPDATE SET {', '.join(f'{c} = {c} + excluded.{c}' for c in names)}",
            (household, day, *(counts[c] for c in names)))


def restore(session: HouseholdSession, store: Store, name: str) -> None:
    """After a (re)build: today's one-step predictions and fetches from the store."""
    day = session.day
    if day is None:
        return
    session.step_predictions.update({p.step: (p.activity, p.probability) for p in store.step_predictions(name, day)})
    session.fetched_today.clear()
    for f in store.fetches(name, day):
        session.fetched_today.setdefault(f.step, []).append(f.object)


def today_score(session: HouseholdSession, store: Store, name: str) -> DayScore | None:
    """Today's scores so far: the settled steps from the store, and today's fetches scored now
    (those still inside their window left out)."""
    day = session.day
    if day is None:
        return None
    stored = next(iter(store.day_scores(name, day)), DayScore(day))
    report = session.fetch_report(settled_only=True)
    return replace(stored, fetches=stored.fetches + report.fetches,
                   useful_fetches=stored.useful_fetches + report.useful_fetches,
                   uses=stored.uses + report.used_objects,
                   uses_fetched=stored.uses_fetched + report.used_fetched_in_advance)


def online_scores(store: Store, name: str, session: HouseholdSession, days: int = 28) -> OnlineScores:
    """The per-day online scores of the last ``days`` days before the household's current day
    (today's so far included), and their totals."""
    today = session.day
    since = (dt.date.fromisoformat(today) - dt.timedelta(days=days - 1)).isoformat() if today else "0000"
    rows = [r for r in store.day_scores(name, since) if r.day != today]
    now = today_score(session, store, name)
    if now is not None:
        rows.append(now)
    return OnlineScores.from_days(rows)
