"""Save and load models as plain, versioned JSON: parameters plus the observed sequences.

Training is counting and takes milliseconds, so the file keeps what was observed (readable,
diffable, independent of internal data structures) and loading re-counts it.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from globe.errors import ModelFileError
from globe.models.activity import ActivityModel
from globe.models.baselines import PersistenceModel
from globe.models.objects import ObjectModel
from globe.models.routine import RoutineModel

FORMAT = "globe-model"
FORMAT_VERSION = 1
_KINDS = {cls.kind: cls for cls in (ActivityModel, ObjectModel, PersistenceModel, RoutineModel)}


def model_to_dict(model: Any) -> dict[str, Any]:
    model._check_fitted()
    data = model.training_data_
    if model.kind == "object":
        data = [[a, list(objs)] for a, objs in data]
    else:
        data = [list(d) for d in data]
    return {"format": FORMAT, "version": FORMAT_VERSION, "kind": model.kind, "params": model.get_params(), "data": data}


def model_from_dict(payload: dict[str, Any], source: str = "<dict>") -> Any:
    if payload.get("format") != FORMAT:
        raise ModelFileError(f"{source}: not a GLOBE model file (format {payload.get('format')!r})")
    if payload.get("version") != FORMAT_VERSION:
        raise ModelFileError(f"{source}: format version {payload.get('version')!r}, this GLOBE reads {FORMAT_VERSION}")
    cls = _KINDS.get(payload.get("kind", ""))
    if cls is None:
        raise ModelFileError(f"{source}: unknown model kind {payload.get('kind')!r}; expected one of {', '.join(_KINDS)}")
    try:
        model = cls(**payload.get("params", {}))
        data = payload["data"]
        return model.fit([(a, tuple(o)) for a, o in data] if cls.kind == "object" else [tuple(d) for d in data])
    except (KeyError, TypeError, ValueError) as err:
        raise ModelFileError(f"{source}: malformed model file: {err}") from err


def save_model(model: Any, path: Path) -> None:
    """Write atomically: a crash leaves the previous file intact."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(model_to_dict(model)), encoding="utf-8")
    os.replace(tmp, path)


def load_model(path: Path) -> Any:
    path = Path(path)
    try:
        payload = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError as err:
        raise ModelFileError(f"{path}: model file not found") from err
    except json.JSONDecodeError as err:
        raise ModelFileError(f"{path}: not JSON: {err}") from err
    return model_from_dict(payload, str(path))
