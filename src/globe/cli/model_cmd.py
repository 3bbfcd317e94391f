"""``globe train`` and ``globe predict``."""

from __future__ import annotations

import csv
import datetime as dt
from pathlib import Path
from typing import Annotated

import typer

from globe.assembly import fit_household
from globe.cli.common import ConfigOption, DataOption, household_map, households_from, out, resolve
from globe.data.records import map_fingerprint
from globe.errors import DataError
from globe.models.io import MODEL_FILE, load_household_model, save_household_model

ModelDir = Annotated[Path, typer.Option("--model-dir", help=f"folder holding the trained model ({MODEL_FILE})")]


def train(
    household: Annotated[str, typer.Option("--household", help="household name, e.g. A")],
    model_dir: ModelDir,
    data: DataOption = None,
    config: ConfigOption = None,
) -> None:
    """Fit the activity and object models on a household's training days and save them as one file."""
    cfg = resolve(config)
    if "," in household:
        raise typer.BadParameter("one household at a time", param_hint="'--household'")
    if not household.strip():
        raise typer.BadParameter("names no household", param_hint="'--household'")
    (h,) = households_from(cfg, data, household)
    fitted = fit_household(h, cfg)
    path = save_household_model(model_dir, fitted.activity, fitted.objects, household=Path(h.source).name or h.name,
                                fingerprint=map_fingerprint(h.nodes, h.objects), objects_columns=h.objects)
    out.print(f"trained on {len(h.train)} days of household {h.name} in {fitted.train_s * 1000:.1f} ms -> {path}",
              markup=False, highlight=False)


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
        raise DataError(f"--{option}: unknown {what} {unknown[0]!r}; known: {shown or 'none'}")


def _weekday(text: str | None) -> int | None:
    if text is None:
        return None
    try:
        return dt.date.fromisoformat(text).weekday()
    except ValueError:
        raise DataError(f"--date: {text!r} is not a date; expected YYYY-MM-DD") from None


def predict(
    model_dir: ModelDir,
    history: Annotated[str, typer.Option("--history", help="the day's activities so far, comma-separated (quote a "
                                                                 "label holding a comma: 'a,\"b, c\"')")] = "",
    objects: Annotated[str, typer.Option("--objects", help="objects moved so far in the current activity run")] = "",
    top: Annotated[int, typer.Option("--top", min=1, help="how many candidates to list")] = 3,
    date: Annotated[str | None, typer.Option(
        "--date", help="the day's date, YYYY-MM-DD (a model that knows the day of the week uses it)")] = None,
    household: Annotated[str | None, typer.Option(
        "--household", help="check that the model was trained for this household's map")] = None,
    data: DataOption = None,
    config: ConfigOption = None,
) -> None:
    """Predict the next activity and, for it, the next object."""
    weekday = _weekday(date)
    fingerprint = folder = None
    if household is not None:
        folder, fingerprint = household_map(resolve(config), data, household)
    model = load_household_model(model_dir, fingerprint=fingerprint, household=folder)
    activity_model, object_model = model.activity, model.objects
    hist = _split(history)
    _known(hist, activity_model.classes_, "activity", "history")
    moved = _split(objects)
    known_objects = model.objects_columns or tuple(sorted({o for _, run in object_model.training_data_ for o in run}))
    _known(moved, known_objects, "object", "objects")
    dist = activity_model.predict_proba(hist, weekday)
    ranked = activity_model.ranked(dist)
    out.print("next activity:", markup=False)
    for a in ranked[:top]:
        out.print(f"  {a:28s} {dist[a]:.3f}", markup=False, highlight=False)
    if not ranked:
        return
    # As in the evaluation protocol: the object is predicted for the predicted activity; the
    # run's objects only count as context if that activity continues the current run.
    nxt = ranked[0]
    context = moved if hist and hist[-1] == nxt else ()
    obj_dist = object_model.predict_proba(nxt, context)
    out.print(f"next object during {nxt}:", markup=False, highlight=False)
    if not obj_dist:
        out.print("  (none: no object was seen moving during this activity in training)", markup=False)
    for o in object_model.ranked(nxt, obj_dist)[:top]:
        out.print(f"  {o:28s} {obj_dist[o]:.3f}", markup=False, highlight=False)
