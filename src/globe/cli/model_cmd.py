"""``globe train`` and ``globe predict``."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from globe.assembly import fit_household
from globe.cli.common import ConfigOption, DataOption, households_from, out, resolve
from globe.errors import DataError
from globe.models.io import load_model, save_model

ModelDir = Annotated[Path, typer.Option("--model-dir", help="folder with activity.json and objects.json")]


def train(
    household: Annotated[str, typer.Option("--household", help="household name, e.g. A")],
    model_dir: ModelDir,
    data: DataOption = None,
    config: ConfigOption = None,
) -> None:
    """Fit the activity and object models on a household's training days and save them."""
    cfg = resolve(config)
    (h,) = households_from(cfg, data, household)
    fitted = fit_household(h, cfg)
    save_model(fitted.activity, model_dir / "activity.json")
    save_model(fitted.objects, model_dir / "objects.json")
    out.print(f"trained on {len(h.train)} days of household {h.name} in {fitted.train_s * 1000:.1f} ms -> {model_dir}")


def _split(text: str | None) -> tuple[str, ...]:
    return tuple(x.strip() for x in text.split(",") if x.strip()) if text else ()


def predict(
    model_dir: ModelDir,
    history: Annotated[str, typer.Option("--history", help="the day's activities so far, comma-separated")] = "",
    objects: Annotated[str, typer.Option("--objects", help="objects moved so far in the current activity run")] = "",
    top: Annotated[int, typer.Option("--top", min=1, help="how many candidates to list")] = 3,
) -> None:
    """Predict the next activity and, for it, the next object."""
    activity_model = load_model(model_dir / "activity.json")
    object_model = load_model(model_dir / "objects.json")
    hist = _split(history)
    unknown = [a for a in hist if a not in activity_model.classes_]
    if unknown:
        raise DataError(f"unknown activity {unknown[0]!r}; known: {', '.join(activity_model.classes_)}", field="history")
    dist = activity_model.predict_proba(hist)
    ranked = activity_model.ranked(dist)
    out.print("next activity:")
    for a in ranked[:top]:
        out.print(f"  {a:28s} {dist[a]:.3f}")
    if not ranked:
        return
    # As in the evaluation protocol: the object is predicted for the predicted activity; the
    # run's objects only count as context if that activity continues the current run.
    nxt = ranked[0]
    context = _split(objects) if hist and hist[-1] == nxt else ()
    obj_dist = object_model.predict_proba(nxt, context)
    out.print(f"next object during {nxt}:")
    for o in object_model.ranked(nxt, obj_dist)[:top]:
        out.print(f"  {o:28s} {obj_dist[o]:.3f}")
