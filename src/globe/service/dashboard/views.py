"""What each dashboard page shows, read from the registry under the household's lock (so a page
never sees half an observation) and rendered with the package's Jinja2 templates.

Reading a page changes nothing: the next hour is read from the fetch policy's forecaster, not
from a prediction (a prediction records the fetch it decides)."""

from __future__ import annotations

import datetime as dt
import re
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import jinja2

from globe import __version__, assembly
from globe.errors import GlobeError
from globe.service import timepolicy
from globe.service.dashboard import svg
from globe.service.registry import Registry
from globe.service.schemas import OnlineScores
from globe.service.scoring import online_scores
from globe.session import HouseholdSession, deployment_summary

ACTOGRAM_DAYS = 28
RECENT_STEPS = 12


@lru_cache(maxsize=1)
def environment() -> jinja2.Environment:
    """The templates shipped in the package (autoescaped)."""
    env = jinja2.Environment(loader=jinja2.PackageLoader("globe.service.dashboard", "templates"),
                             autoescape=jinja2.select_autoescape(default=True, default_for_string=True),
                             undefined=jinja2.StrictUndefined, trim_blocks=True, lstrip_blocks=True)
    env.filters["pct"] = lambda v: "–" if v is None else f"{100 * v:.0f}%"
    env.filters["prob"] = lambda v: "–" if v is None else f"{v:.2f}"
    env.filters["words"] = lambda label: str(label).replace("_", " ")  # brushing_teeth -> brushing teeth
    return env


def render(template: str, **context: Any) -> str:
    return environment().get_template(template).render(version=__version__, **context)


def _clock(minute: int) -> str:
    return f"{(minute % 1440) // 60:02d}:{minute % 60:02d}"


@dataclass(frozen=True, slots=True)
class HouseholdLine:
    name: str
    status: str
    days_learned: int | None
    shadow: bool
    last_seen: str
    accuracy: float | None
    problem: str | None = None


def household_lines(registry: Registry, names: list[str]) -> list[HouseholdLine]:
    """One line per household for the admin's list (a household that cannot be built says why)."""
    out = []
    for name in names:
        shadow = registry.store.shadow(name)
        try:
            with registry.locked(name) as a:
                tz = timepolicy.zone(registry.row(name).timezone)
                scores = online_scores(registry.store, name, a, 7)
                out.append(HouseholdLine(name, a.status, a.days_learned, shadow, _last_seen(a, tz), scores.accuracy))
        except GlobeError as err:
            out.append(HouseholdLine(name, "unavailable", None, shadow, "–", None, str(err)))
    return out


def _last_seen(a: HouseholdSession, tz: dt.tzinfo) -> str:
    last = a.last_instant
    return "never" if last is None else last.astimezone(tz).strftime("%Y-%m-%d %H:%M")


def _colours(a: HouseholdSession) -> dict[str, str]:
    labels = set(getattr(a.activity_model, "classes_", ()))
    labels.update(x for _, x, _ in a.today() if x is not None)
    return svg.colours(sorted(labels))


def status(registry: Registry, name: str, a: HouseholdSession) -> dict[str, Any]:
    row = registry.row(name)
    tz = timepolicy.zone(row.timezone)
    return {"name": name, "status": a.status, "days_learned": a.days_learned, "last_seen": _last_seen(a, tz),
            "timezone": row.timezone, "shadow": registry.store.shadow(name), "day": a.day,
            "steps_today": sum(seen for _, _, seen in a.today()), "observations": a.observations}


def today(registry: Registry, name: str) -> dict[str, Any]:
    """The "today" page: status, timeline (with the activity recognised from the sensors, in a
    household with sensors), next hour, fetches with feedback, scores."""
    with registry.locked(name) as a:
        colour = _colours(a)
        steps, recent = [], []
        recognised = a.recognised_today()
        for i, (minute, observed, seen) in enumerate(a.today()):
            predicted = a.step_predictions.get(i)
            found = recognised[i] if i < len(recognised) else None
            step = svg.TimelineStep(minute, observed if seen else None, predicted[0] if predicted else None,
                                    predicted[1] if predicted else None, found[0] if found else None,
                                    found[1] if found else None)
            if seen or found is not None:
                steps.append(step)
            recent.append({"time": _clock(minute), "seen": seen, "observed": step.observed,
                           "recognised": step.recognised, "recognised_probability": step.recognised_probability,
                           "predicted": step.predicted, "probability": step.probability,
                           "hit": None if step.predicted is None or step.observed is None
                           else step.predicted == step.observed})
        top = a.next_activity()
        scores = online_scores(registry.store, name, a)
        grid = a.grid
        chart = {"day_start": grid.day_start_minute, "step_minutes": grid.step_minutes,
                 "span": svg.day_span(grid.steps, grid.step_minutes), "colour": colour,
                 "now": grid.minute(a.step) if a.step is not None else None}
        return {
            **status(registry, name, a),
            "timeline": {n: svg.timeline(steps, layout=layout, **chart)  # type: ignore[arg-type]
                         for n, layout in (("wide", svg.WIDE), ("narrow", svg.NARROW))},
            "recent": recent[-RECENT_STEPS:][::-1],
            "legend": _legend(colour, [x for s in steps for x in (s.observed, s.predicted, s.recognised)]),
            "recognition": _recognition(a),
            "asking": _asking(a),
            "next_activity": top,
            "next_hour": next_hour(registry, a),
            "fetches": fetches_today(registry, name, a),
            "scores": scores,
            "today_score": scores.days[-1] if scores.days and scores.days[-1].day == a.day else None,
        }


def _recognition(a: HouseholdSession) -> dict[str, int] | None:
    """Today's counts for a household with sensors (None without): steps labelled (answers
    included), steps recognised from the sensors alone, questions asked and answered."""
    if a.sensing is None:
        return None
    labelled, recognised = a.step_counts()
    asked, answered = a.questions_today()
    return {"labelled": labelled, "recognised": recognised, "asked": asked, "answered": answered}


def _asking(a: HouseholdSession) -> dict[str, Any] | None:
    """The "what are you doing?" card of a household with sensors and a step under way: the step
    it labels, the question's likely activities when one is asked (else the recognised one), and
    every activity the household knows, for an answer the question did not offer."""
    if a.sensing is None or a.step is None or a.day is None:
        return None
    question = a.question()
    if question is not None:
        options = list(question.options)
    else:
        found = a.recognised()
        options = [found] if found is not None else []
    return {"day": a.day, "step": a.step, "time": _clock(a.grid.minute(a.step)), "question": question is not None,
            "options": options, "activities": sorted(a.known_activities())}


def _legend(colour: dict[str, str], used: list[str | None]) -> list[tuple[str, str]]:
    seen = sorted({u for u in used if u is not None})
    return [(label, colour[label]) for label in seen if label in colour]


def next_hour(registry: Registry, a: HouseholdSession) -> list[dict[str, Any]]:
    """The objects GLOBE expects to be used within the next hour: when (the most likely step),
    how likely, and where the robot would take them; whether the policy would fetch now."""
    step = a.grid.step_minutes
    steps = max(1, 60 // step)
    policy = a.policy
    lo, hi = policy.min_lead_steps, policy.window_steps
    now = a.grid.minute(a.step) if a.step is not None else None
    decided = a.last_decision
    fetching = {c.obj for c in decided.fetches} if decided is not None else set()
    out = []
    for obj, probs, target in a.next_hour(steps):
        total = sum(probs)
        if total < 0.02:
            continue
        peak = max(range(len(probs)), key=probs.__getitem__)
        useful = sum(probs[max(lo - 1, 0):hi])
        out.append({"object": obj, "probability": min(total, 1.0), "when": _clock(now + (peak + 1) * step)
                    if now is not None else "–", "to": _place(a, target), "to_node": target,
                    "bars": svg.step_bars(probs),
                    "fetch": obj in fetching if decided is not None else useful > policy.threshold})
    out.sort(key=lambda r: -r["probability"])  # type: ignore[operator]
    return out[:8]


def _place(a: HouseholdSession, label: str | None) -> str | None:
    return None if label is None else a.household.place_name(label)


def fetches_today(registry: Registry, name: str, a: HouseholdSession) -> list[dict[str, Any]]:
    """Today's fetch decisions, each with the person's first feedback on that object after it."""
    day = a.day
    if day is None:
        return []
    rows = registry.store.fetches(name, day)
    tz = timepolicy.zone(registry.row(name).timezone)
    start = a.grid.wall(day, 0)
    since = start.replace(tzinfo=tz).astimezone(dt.timezone.utc).isoformat()
    feedback = registry.store.feedback_since(name, since)
    used: set[int] = set()
    out = []
    for f in rows:
        said = None
        for i, (obj, accepted, at) in enumerate(feedback):
            if i not in used and obj == f.object and at >= f.made_at:
                used.add(i)
                said = "accepted" if accepted else "refused"
                break
        # f.step is the clock step of today it was decided after
        when = _clock(a.grid.minute(f.step)) if a.step is not None and 0 <= f.step <= a.step else "–"
        out.append({"time": when, "object": f.object, "to": _place(a, f.to_location), "to_node": f.to_location,
                    "probability": f.probability, "shadow": f.shadow, "feedback": said})
    return out


def routine(registry: Registry, name: str) -> dict[str, Any]:
    """The "routine" page: the actogram of the last days and the online scores per day."""
    with registry.locked(name) as a:
        colour = _colours(a)
        sequences = list(getattr(a.activity_model, "training_data_", ()))
        names = [_day_label(n) for n in a.learned_days[-len(sequences):]] if sequences else []
        names = [""] * (len(sequences) - len(names)) + names
        rows: list[tuple[str, list[str | None]]] = []
        if a.today():
            rows.append(("today", [x for _, x, _ in a.today()]))
        rows += [(label, list(seq)) for label, seq in zip(reversed(names), reversed(sequences))]
        rows = rows[:ACTOGRAM_DAYS]
        scores: OnlineScores = online_scores(registry.store, name, a)
        grid = a.grid
        span = svg.day_span(grid.steps, grid.step_minutes)
        per_day = [(d.day, d.accuracy, d.precision, d.recall) for d in scores.days]
        return {
            **status(registry, name, a),
            "actogram": {n: svg.actogram(rows, day_start=grid.day_start_minute, step_minutes=grid.step_minutes,
                                         span=span, colour=colour, layout=layout)
                         for n, layout in (("wide", svg.WIDE), ("narrow", svg.NARROW))},
            "legend": _legend(colour, [x for _, seq in rows for x in seq]),
            "actogram_days": len(rows),
            "score_chart": {n: svg.score_chart(per_day, layout) for n, layout in (("wide", svg.WIDE),
                                                                                 ("narrow", svg.NARROW))},
            "scores": scores,
        }


_DATE = re.compile(r"\d{4}-\d{2}-\d{2}")


def _day_label(name: str) -> str:
    """A learned day's row label: its date where its name holds one (an imported day of another
    year is not "yesterday"), else its file name."""
    found = _DATE.search(name)
    if found:
        return found.group()
    return name.replace("\\", "/").rsplit("/", 1)[-1].removesuffix(".csv")[:12]


def settings(registry: Registry, name: str) -> dict[str, Any]:
    """The "settings" page: what the household runs (its models and how they were chosen, its
    clock) and the fetch rule, in words with units."""
    with registry.locked(name) as a:
        built = assembly.describe(a.activity_model, a.chooser, a.deployment.models.stay_margin)
        p, policy = registry.config.policy, a.policy
        step = a.grid.step_minutes
        decision: dict[str, Any] = {
            "models": deployment_summary(a.deployment),
            "clock": a.grid.describe(),
            "fetch when": f"P(used within the lead window) > {policy.threshold:.2f} (a useless fetch costs "
                          f"{p.cost_useless:g}, a missed need {p.cost_missed:g})",
            "lead window": f"{policy.min_lead_steps * step} to {policy.window_steps * step} minutes ahead",
            "most fetches per step": policy.max_fetches_per_step,
            "the object, when the models are unsure": _chooser_words(built["chooser"]),
            "new activities": "learned" if a.new_activities == "learn" else "refused (the known ones are listed)"}
        if registry.selecting(name):
            decision["models"] += "; cross-validation under way"
        return {**status(registry, name, a), "models": built, "decision": decision}


def _chooser_words(chooser: dict[str, Any]) -> str:
    """How the object is chosen, in words."""
    if chooser.get("kind") != "globe" or not chooser.get("threshold"):
        return "the object model's own choice (no LLM is asked)"
    how = "picks" if chooser.get("mode") == "replace" else "scores, beside the object model's,"
    return (f"the LLM ({chooser.get('backend')}) {how} among the {chooser.get('top_k')} likeliest objects when the "
            f"object model is less than {chooser['threshold']:.0%} sure")


__all__ = ["household_lines", "render", "routine", "settings", "today"]
