"""``globe train`` and ``globe predict``."""

from __future__ import annotations

import csv
import datetime as dt
from pathlib import Path
from typing import Annotated, get_args

import typer

from globe.cli.common import ConfigOption, DataOption, console, count, household_map, households_from, out, resolve
from globe.config import Deployment, DeployMethod
from globe.data.records import Household, map_fingerprint
from globe.errors import DataError, ModelFileError
from globe.models.io import MODEL_FILE, load_household_model, save_household_model
from globe.session import HouseholdSession, Observation, build_session, deployment_summary
from globe.session.grid import DayGrid

ModelDir = Annotated[Path, typer.Option("--model-dir", help=f"folder holding the trained model ({MODEL_FILE})")]
METHODS = get_args(DeployMethod)


def _method(text: str | None) -> DeployMethod | None:
    if text is not None and text not in METHODS:
        raise typer.BadParameter(f"{text!r}; expected one of {', '.join(METHODS)}", param_hint="'--method'")
    return text  # type: ignore[return-value]


def train(
    household: Annotated[str, typer.Option("--household", help="household name, e.g. A")],
    model_dir: ModelDir,
    method: Annotated[str | None, typer.Option(
        "--method", help="how the models are chosen: routine (default: the routine family by cross-validation on the "
                         "training days, as globe evaluate's routine row), ngram_smoothed, ngram (the paper's) or "
                         "persistence")] = None,
    data: DataOption = None,
    config: ConfigOption = None,
) -> None:
    """Choose and fit the household's models on its training days and save them, with what was chosen, as one file."""
    from globe.evaluation.deploy import choose_deployment

    cfg = resolve(config)
    if "," in household:
        raise typer.BadParameter("one household at a time", param_hint="'--household'")
    if not household.strip():
        raise typer.BadParameter("names no household", param_hint="'--household'")
    chosen_by = _method(method)
    (h,) = households_from(cfg, data, household)
    deployment = choose_deployment(h, cfg, method=chosen_by, progress=console.print)
    session = build_session(h, cfg, deployment, None, learn=False)
    fingerprint = map_fingerprint(h.nodes, h.objects)
    path = save_household_model(model_dir, session.activity_model, session.chooser.model,
                                household=Path(h.source).name or h.name, fingerprint=fingerprint,
                                objects_columns=h.objects, nodes=h.nodes, grid=session.grid.as_dict(),
                                deployment=deployment.model_dump(mode="json"), days=h.train)
    _say(f"trained on {count(len(h.train), 'day')} of household {h.name} -> {path}")
    _say(f"it runs {deployment_summary(deployment)}")
    s = deployment.scores
    if "activity_log_loss" in s and "persistence_log_loss" in s:
        _say(f"cross-validation on its training days: next-activity log loss {s['activity_log_loss']:.3f} "
                  f"(persistence {s['persistence_log_loss']:.3f}), weighted F1 {s['activity_f1']:.3f} (persistence "
                  f"{s['persistence_f1']:.3f})")


def _say(text: str) -> None:
    """A line of output, exactly as written (user labels are never markup), never wrapped."""
    out.print(text, markup=False, highlight=False, soft_wrap=True)


def _split(text: str | None) -> tuple[str, ...]:
    """A comma-separated list; a label holding a comma is quoted as in CSV (``a,"b, c"``)."""
    if not text:
        return ()
    try:
        fields = next(csv.reader([text], skipinitialspace=True))
    except csv.Error as err:
        raise DataError(f"cannot read the list {text[:60]!r}: {err}") from None
    return tuple(x.strip() for x in fields if x.strip())


def _known(values: tuple[str, ...], known: tuple[str, ...] | list[str], what: str, option: str) -> None:
    unknown = [v for v in values if v not in known]
    if unknown:
        shown = ", ".join(sorted(known)[:40]) + (", ..." if len(known) > 40 else "")
        label = unknown[0] if len(unknown[0]) <= 64 else unknown[0][:64] + "..."
        raise DataError(f"--{option}: unknown {what} {label!r}; known: {shown or 'none'}")


def _date(text: str | None) -> dt.date:
    if text is None:
        return dt.date.today()
    try:
        return dt.date.fromisoformat(text)
    except ValueError:
        raise DataError(f"--date: {text!r} is not a date; expected YYYY-MM-DD") from None


def _step(grid: DayGrid, text: str, option: str) -> int:
    """``HH:MM`` as a step of the household's day (a time before its day start is after midnight)."""
    try:
        hours, minutes = (int(x) for x in text.strip().split(":"))
        if not (0 <= hours < 24 and 0 <= minutes < 60):
            raise ValueError
    except ValueError:
        raise DataError(f"{option}: {text!r} is not a time of day; expected HH:MM, e.g. 18:00") from None
    minute = hours * 60 + minutes
    minute += 1440 if minute < grid.day_start_minute else 0
    return (minute - grid.day_start_minute) // grid.step_minutes


def _session(model_dir: Path, config: Path | None, data: Path | None, household: str | None) -> HouseholdSession:
    """The household's session from its model file, at the start of a day."""
    fingerprint = folder = None
    cfg = resolve(config)
    if household is not None:
        folder, fingerprint = household_map(cfg, data, household)
    model = load_household_model(model_dir, fingerprint=fingerprint, household=folder)
    if model.grid is None or model.deployment is None or not model.nodes:
        raise ModelFileError(f"{model_dir / MODEL_FILE}: it holds no training days (an older globe train wrote it); "
                             "retrain it with: globe train --household NAME --model-dir DIR")
    home = Household(model.household, model.nodes, model.objects_columns, model.days, ())
    deployment = Deployment.model_validate(model.deployment)
    return build_session(home, cfg, deployment, None, grid=DayGrid(**model.grid), learn=False)


def predict(
    model_dir: ModelDir,
    history: Annotated[str, typer.Option("--history", help="the day's activities so far, one per step from --start, "
                                                          "comma-separated (quote a label holding a comma: "
                                                          "'a,\"b, c\"')")] = "",
    start: Annotated[str | None, typer.Option(
        "--start", help="when the history begins, HH:MM (default: the household's day start, e.g. 06:00); the steps "
                        "before it are unknown")] = None,
    at: Annotated[str | None, typer.Option(
        "--at", help="the time now, HH:MM (default: the history's last step); the steps after the history are "
                     "unknown")] = None,
    date: Annotated[str | None, typer.Option(
        "--date", help="the day's date, YYYY-MM-DD (default: today; a model that knows the day of the week uses it)")
    ] = None,
    objects: Annotated[str, typer.Option("--objects", help="objects moved so far in the current activity run")] = "",
    top: Annotated[int, typer.Option("--top", min=1, help="how many candidates to list")] = 3,
    horizon: Annotated[int | None, typer.Option(
        "--horizon", min=1, max=1440, help="also list the objects expected to be used within this many minutes, "
                                           "when and where to")] = None,
    household: Annotated[str | None, typer.Option(
        "--household", help="check that the model was trained for this household's map")] = None,
    data: DataOption = None,
    config: ConfigOption = None,
) -> None:
    """Predict the next activity, the object needed, what the robot would fetch now and, with
    --horizon, the objects expected within it: from the time of day and what was observed."""
    day = _date(date)
    session = _session(model_dir, config, data, household)
    grid = session.grid
    hist = _split(history)
    for label in hist:
        try:
            session.activity_label(label)  # the one label rule: unknown labels refused, variants named
        except DataError as err:
            raise DataError(f"--history: {err.message}") from None
    moved = _split(objects)
    _known(moved, session.household.objects, "object", "objects")
    first = _step(grid, start, "--start") if start is not None else 0
    last = first + len(hist) - 1
    now = _step(grid, at, "--at") if at is not None else max(last, first)
    if now < last:
        raise DataError(f"--at: {at} is before the history's last step ({grid.clock(last)})")
    for t, label in enumerate(hist, start=first):
        session.observe(Observation(grid.wall(day.isoformat(), t), label, {}))
    if now > last or not hist:
        session.observe(Observation(grid.wall(day.isoformat(), now), None, {}))
    decision = session.decide()
    _say(f"household {session.household.name}: {deployment_summary(session.deployment)}")
    _say(f"at {grid.clock(now)} on {day.isoformat()} ({grid.describe()}; step {now})")
    belief = session.belief()
    ranked = session.activity_model.ranked(belief)
    _say(f"next activity ({grid.clock(now + 1)}):")
    for a in ranked[:top]:
        _say(f"  {a:28s} {belief[a]:.3f}")
    if decision.activity is None:
        return
    nxt = decision.activity
    ranked_objects, dist = session.object_ranking(nxt, moved if moved else None)
    _say(f"next object during {nxt}:")
    if not dist:
        _say("  (none: no object was seen moving during this activity in training)")
    for o in ranked_objects[:top]:
        _say(f"  {o:28s} {dist[o]:.3f}")
    lo, hi = session.policy.min_lead_steps * grid.step_minutes, session.policy.window_steps * grid.step_minutes
    if decision.fetches:
        for c in decision.fetches:
            _say(f"fetch now: {c.obj} to {c.to_location or 'where it is used'} (P(used {lo}-{hi} min from now) "
                      f"{c.probability:.2f})")
    else:
        _say(f"fetch now: nothing (no object is likely enough to be used {lo}-{hi} min from now)")
    if horizon is not None:
        steps = max(1, horizon // grid.step_minutes)
        expected = [(obj, probs, to) for obj, probs, to in session.next_hour(steps) if sum(probs) >= 0.05]
        expected.sort(key=lambda e: -sum(e[1]))
        _say(f"expected within {horizon} minutes:")
        if not expected:
            _say("  (nothing above 5 %)")
        for obj, probs, to in expected[:max(top, 8)]:
            peak = max(range(len(probs)), key=probs.__getitem__)
            _say(f"  {obj:20s} {min(sum(probs), 1.0):.2f}  most likely at {grid.clock(now + 1 + peak)}  to "
                      f"{to or '?'}")
