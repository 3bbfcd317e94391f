"""Save and load models as plain, versioned JSON: parameters plus the observed sequences.

Training is counting and takes milliseconds, so the file keeps what was observed (readable,
diffable, independent of internal data structures) and loading re-counts it.

A household's model (activity and object model together) is ONE file, ``model.json``, written
beside and renamed into place: a killed save leaves the previous model or none, never a mixed
pair. It records the household, a fingerprint of the map it was trained on and a checksum of its
content, so a model for another map, an edited or truncated file, or anything malformed is a
one-line :class:`ModelFileError`. The checksum only catches accidents (anyone can recompute it):
every field is checked by type and range whatever it says.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

from globe.data.csv_logs import activity_label, check_map
from globe.data.records import Day, Node, map_fingerprint
from globe.errors import DataError, GlobeError, ModelFileError
from globe.models.activity import ActivityModel
from globe.models.base import check_is_fitted
from globe.models.baselines import HourActivityObjects, PersistenceModel
from globe.models.clock import ClockModel
from globe.models.objects import ObjectModel
from globe.models.routine import RoutineModel

FORMAT = "globe-model"
FORMAT_VERSION = 1
BUNDLE_FORMAT = "globe-household-model"
BUNDLE_VERSION = 2
MODEL_FILE = "model.json"
LEGACY_FILES = ("activity.json", "objects.json")
_TRAIN = "globe train --household NAME --model-dir DIR"
MAX_MODEL_BYTES = 256 << 20
_KINDS = {cls.kind: cls for cls in (ActivityModel, ClockModel, ObjectModel, HourActivityObjects, PersistenceModel,
                                     RoutineModel)}
_OBJECT_KINDS = frozenset({ObjectModel.kind, HourActivityObjects.kind})
_TIMED = HourActivityObjects.kind  # its runs carry each object's clock minute
_ACTIVITY_KINDS = frozenset(_KINDS) - _OBJECT_KINDS


def model_to_dict(model: Any) -> dict[str, Any]:
    check_is_fitted(model)
    data = model.training_data_
    if model.kind == _TIMED:
        data = [[a, list(objs), list(minutes)] for a, objs, minutes in data]
    elif model.kind in _OBJECT_KINDS:
        data = [[a, list(objs)] for a, objs in data]
    else:
        data = [list(d) for d in data]
    out = {"format": FORMAT, "version": FORMAT_VERSION, "kind": model.kind, "params": model.get_params(), "data": data}
    weekdays = getattr(model, "weekdays_", None)
    if weekdays is not None and any(w is not None for w in weekdays):
        out["weekdays"] = list(weekdays)  # each day's day of the week, for a model that knows it
    return out


MAX_LABEL = 1024  # no activity, object or place of a sane model comes near it (the service allows 128)


def _is_labels(value: Any) -> bool:
    """A list of labels, each as the label rule has it (:func:`globe.data.csv_logs.activity_label`:
    no control, bidirectional or invisible character) and at most :data:`MAX_LABEL` long."""
    return isinstance(value, list) and all(isinstance(x, str) and 0 < len(x) <= MAX_LABEL and _fine(x) for x in value)


MAX_MINUTE = 7 * 24 * 60  # a day may run past midnight; no step of a sane day is a week past its start


def _is_minutes(value: Any) -> bool:
    """A list of clock minutes: whole numbers (not bools) in 0..MAX_MINUTE."""
    return isinstance(value, list) and all(type(m) is int and 0 <= m <= MAX_MINUTE for m in value)


def _fine(label: str) -> bool:
    try:
        return activity_label(label) == label
    except DataError:
        return False


def _check_data(kind: str, data: Any, source: str) -> None:
    """The observed sequences, shape and types, before anything is counted."""
    if not isinstance(data, list):
        raise ModelFileError(f"{source}: malformed model file: 'data' is {type(data).__name__}, expected a list")
    for i, item in enumerate(data):
        if kind == _TIMED:
            ok = isinstance(item, list) and len(item) == 3 and _is_labels(item[:1]) and _is_labels(item[1]) \
                and _is_minutes(item[2]) and len(item[2]) == len(item[1])
        elif kind in _OBJECT_KINDS:
            ok = isinstance(item, list) and len(item) == 2 and _is_labels(item[:1]) and _is_labels(item[1])
        else:
            ok = _is_labels(item) and len(item) > 0
        if not ok:
            expected = ("[activity, [objects...], [minutes...]]" if kind == _TIMED else
                        "[activity, [objects...]]" if kind in _OBJECT_KINDS else "a non-empty list of activity labels")
            raise ModelFileError(f"{source}: malformed model file: data[{i}] is not {expected}")


MAX_INT_PARAM = 1_000_000  # no order, window or cap of a sane model comes near it
MAX_FLOAT_PARAM = 1e6


def _is_version(value: Any, expected: int) -> bool:
    """``value`` is the integer ``expected`` (JSON ``true`` equals 1 in Python: not a version)."""
    return type(value) is int and value == expected


def _check_params(cls: Any, params: dict[str, Any], source: str) -> None:
    """Every parameter by type and range, whatever the checksum says (anyone can recompute it):
    an allowed value of the allowed type, a whole number in 1..MAX_INT_PARAM (not a bool), a
    finite number in 0..MAX_FLOAT_PARAM."""
    for name, value in params.items():
        allowed = cls._parameter_constraints.get(name)
        where = f"{source}: malformed model file: params.{name}={value!r}"
        if allowed is None:
            raise ModelFileError(f"{where} is not a parameter of {cls.__name__}")
        if value is None and name in cls._optional_params:
            continue
        if isinstance(allowed, tuple):
            if not any(type(value) is type(a) and value == a for a in allowed):
                raise ModelFileError(f"{where}; expected one of {', '.join(map(repr, allowed))}")
        elif allowed is int:
            if type(value) is not int or not 1 <= value <= MAX_INT_PARAM:
                raise ModelFileError(f"{where}; expected a whole number in 1..{MAX_INT_PARAM}")
        elif allowed is float:
            if type(value) not in (int, float) or not math.isfinite(value) or not 0 <= value <= MAX_FLOAT_PARAM:
                raise ModelFileError(f"{where}; expected a finite number in 0..{MAX_FLOAT_PARAM:g}")


def model_from_dict(payload: Any, source: str = "<dict>") -> Any:
    """A fitted model from :func:`model_to_dict`'s output; anything else is a ModelFileError."""
    if not isinstance(payload, dict):
        raise ModelFileError(f"{source}: not a GLOBE model file (a JSON {type(payload).__name__}, expected an object)")
    if payload.get("format") != FORMAT:
        raise ModelFileError(f"{source}: not a GLOBE model file (format {payload.get('format')!r})")
    if not _is_version(payload.get("version"), FORMAT_VERSION):
        raise ModelFileError(f"{source}: format version {payload.get('version')!r}, this GLOBE reads {FORMAT_VERSION}")
    kind = payload.get("kind")
    cls = _KINDS.get(kind) if isinstance(kind, str) else None
    if cls is None:
        raise ModelFileError(f"{source}: unknown model kind {kind!r}; expected one of {', '.join(_KINDS)}")
    params = payload.get("params", {})
    if not isinstance(params, dict) or not all(isinstance(k, str) for k in params):
        raise ModelFileError(f"{source}: malformed model file: 'params' is not an object")
    _check_params(cls, params, source)
    if "data" not in payload:
        raise ModelFileError(f"{source}: malformed model file: no 'data'")
    _check_data(cls.kind, payload["data"], source)
    weekdays = payload.get("weekdays")
    if weekdays is not None and (cls.kind in _OBJECT_KINDS or not isinstance(weekdays, list)
                                 or len(weekdays) != len(payload["data"])
                                 or not all(w is None or (type(w) is int and 0 <= w <= 6) for w in weekdays)):
        raise ModelFileError(f"{source}: malformed model file: 'weekdays' is not one day of the week (0-6 or null) "
                             "per day of 'data'")
    try:
        model: Any = cls(**params)
        data = payload["data"]
        if cls.kind == _TIMED:
            return model.fit([(a, tuple(o), tuple(m)) for a, o, m in data])
        if cls.kind in _OBJECT_KINDS:
            return model.fit([(a, tuple(o)) for a, o in data])
        return model.fit([tuple(d) for d in data], weekdays)
    except (GlobeError, TypeError, ValueError, KeyError, IndexError, AttributeError, OverflowError,
            RecursionError) as err:
        raise ModelFileError(f"{source}: malformed model file: {' '.join(str(err).split())}") from err


def _write_atomic(path: Path, text: str) -> None:
    """Written beside, flushed to disk, renamed into place: readers see the old file or the new."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
    try:
        fd = os.open(path.parent, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def save_model(model: Any, path: Path) -> None:
    """Write one model atomically: a crash leaves the previous file intact."""
    path = Path(path)
    try:
        _write_atomic(path, json.dumps(model_to_dict(model)))
    except OSError as err:
        raise ModelFileError(f"{path}: cannot write the model: {err.strerror or err}") from err


def _read_json(path: Path) -> Any:
    try:
        if path.is_dir():
            raise ModelFileError(f"{path}: is a folder, not a model file")
        if path.stat().st_size > MAX_MODEL_BYTES:
            raise ModelFileError(f"{path}: larger than {MAX_MODEL_BYTES >> 20} MiB; not a model file")
        raw = path.read_bytes()
    except FileNotFoundError as err:
        raise ModelFileError(f"{path}: model file not found") from err
    except OSError as err:
        raise ModelFileError(f"{path}: cannot read the model: {err.strerror or err}") from err
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as err:
        raise ModelFileError(f"{path}: not a GLOBE model file (not UTF-8 text at byte {err.start})") from err
    try:
        return json.loads(text)
    except json.JSONDecodeError as err:
        raise ModelFileError(f"{path}: not JSON (line {err.lineno}, column {err.colno}: {err.msg}); "
                             "the file is damaged or truncated") from err
    except RecursionError as err:
        raise ModelFileError(f"{path}: not a GLOBE model file (nested too deeply)") from err


def load_model(path: Path) -> Any:
    path = Path(path)
    return model_from_dict(_read_json(path), str(path))


# -- a household's model: both models, one file ------------------------------------------------------


@dataclass(frozen=True)
class HouseholdModel:
    """What ``globe train`` saves and ``globe predict`` loads: both models, and what a household's
    session is built from (its map, its grid, its deployment and its training days' places; the
    days' activities are the activity model's)."""

    household: str
    fingerprint: str
    activity: Any
    objects: Any
    objects_columns: tuple[str, ...]
    nodes: tuple[Node, ...] = ()
    grid: dict[str, int] | None = None
    deployment: dict[str, Any] | None = None
    days: tuple[Day, ...] = ()


def _places(days: Sequence[Day]) -> list[dict[str, Any]]:
    """Each day's name and where every object was: its first row, then each change (step, column,
    place): a few kilobytes a day where the rows would take a hundred."""
    out = []
    for day in days:
        moves = [[t, j, after] for t in range(1, len(day))
                 for j, (before, after) in enumerate(zip(day.locations[t - 1], day.locations[t])) if before != after]
        out.append({"name": day.name, "minutes": list(day.minutes), "first": list(day.locations[0]) if len(day) else [],
                    "moves": moves})
    return out


def _days(places: Any, activities: Sequence[tuple[str, ...]], columns: tuple[str, ...], nodes: tuple[Node, ...],
          src: str) -> tuple[Day, ...]:
    """The training days back from :func:`_places` and the activity model's sequences, every
    place a node of the map and every change inside its day."""
    known = {n.node for n in nodes}
    if not isinstance(places, list) or len(places) != len(activities):
        raise ModelFileError(f"{src}: malformed model file: 'places' is not one entry per training day")
    out = []
    for i, (entry, acts) in enumerate(zip(places, activities)):
        where = f"{src}: malformed model file: places[{i}]"
        if not isinstance(entry, dict) or not isinstance(entry.get("name"), str) or not _is_labels(entry.get("first")):
            raise ModelFileError(f"{where} has no name or first row of places")
        minutes, first, moves = entry.get("minutes"), entry["first"], entry.get("moves")
        if (not isinstance(minutes, list) or len(minutes) != len(acts)
                or not all(type(m) is int and 0 <= m <= 100_000 for m in minutes)):
            raise ModelFileError(f"{where}: 'minutes' is not one minute per step of its day")
        if len(first) != len(columns) or not set(first) <= known or not isinstance(moves, list):
            raise ModelFileError(f"{where}: its places are not one node of the map per object")
        rows, row = [], list(first)
        changes: dict[int, list[tuple[int, str]]] = {}
        for move in moves:
            if not (isinstance(move, list) and len(move) == 3 and type(move[0]) is int and 1 <= move[0] < len(acts)
                    and type(move[1]) is int and 0 <= move[1] < len(columns) and move[2] in known):
                raise ModelFileError(f"{where}: a move is not [step, column, node of the map] inside its day")
            changes.setdefault(move[0], []).append((move[1], move[2]))
        for t in range(len(acts)):
            for j, place in changes.get(t, ()):
                row[j] = place
            rows.append(tuple(row))
        out.append(Day(entry["name"], tuple(minutes), tuple(acts), tuple(rows)))
    return tuple(out)


def _checksum(body: dict[str, Any]) -> str:
    canonical = json.dumps(body, sort_keys=True, ensure_ascii=True, separators=(",", ":"))
    return "sha256:" + hashlib.sha256(canonical.encode("ascii")).hexdigest()


def save_household_model(model_dir: Path, activity: Any, objects: Any, *, household: str, fingerprint: str,
                         objects_columns: tuple[str, ...] = (), nodes: Sequence[Node] = (),
                         grid: dict[str, int] | None = None, deployment: dict[str, Any] | None = None,
                         days: Sequence[Day] = ()) -> Path:
    """Save both models as one file ``model_dir/model.json`` in one atomic step, with what a session
    is built from when given (the map's ``nodes``, the ``grid``, the ``deployment`` and the training
    ``days``, whose activities must be the activity model's); returns its path."""
    body: dict[str, Any] = {
        "format": BUNDLE_FORMAT, "version": BUNDLE_VERSION, "household": household, "map_fingerprint": fingerprint,
        "objects_columns": list(objects_columns),
        "activity": model_to_dict(activity), "objects": model_to_dict(objects),
    }
    if nodes:
        body["nodes"] = [[n.node, n.cls, n.category, n.movable, n.start_location] for n in nodes]
    if grid is not None and deployment is not None:
        body |= {"grid": dict(grid), "deployment": deployment, "places": _places(days)}
    path = Path(model_dir) / MODEL_FILE
    try:
        if Path(model_dir).exists() and not Path(model_dir).is_dir():
            raise ModelFileError(f"{model_dir}: is a file; --model-dir must be a folder")
        _write_atomic(path, json.dumps({**body, "checksum": _checksum(body)}))
    except OSError as err:
        raise ModelFileError(f"{model_dir}: cannot write the model: {err.strerror or err}") from err
    return path


def load_household_model(model_dir: Path, *, fingerprint: str | None = None,
                         household: str | None = None) -> HouseholdModel:
    """Load ``model_dir/model.json``, checking its format, checksum and parts, and, when given, that
    it was trained for this map (``fingerprint``) and household."""
    model_dir = Path(model_dir)
    path = model_dir / MODEL_FILE
    if not model_dir.is_dir():
        raise ModelFileError(f"{model_dir}: no such model folder (create one with: {_TRAIN})")
    if not path.exists():
        legacy = [n for n in LEGACY_FILES if (model_dir / n).exists()]
        hint = (f"{' and '.join(legacy)} are from an older GLOBE that saved the models separately; "
                "retrain with globe train" if legacy else f"train one with: {_TRAIN}")
        raise ModelFileError(f"{path}: model file not found ({hint})")
    payload = _read_json(path)
    src = str(path)
    if not isinstance(payload, dict) or payload.get("format") != BUNDLE_FORMAT:
        got = payload.get("format") if isinstance(payload, dict) else type(payload).__name__
        raise ModelFileError(f"{src}: not a GLOBE household model (format {got!r})")
    if not _is_version(payload.get("version"), BUNDLE_VERSION):
        raise ModelFileError(f"{src}: format version {payload.get('version')!r}, this GLOBE reads {BUNDLE_VERSION}; "
                             f"retrain it ({_TRAIN})")
    body = {k: v for k, v in payload.items() if k != "checksum"}
    if payload.get("checksum") != _checksum(body):
        raise ModelFileError(f"{src}: checksum mismatch (the file was edited, mixed with another or damaged); "
                             "retrain it")
    name, fp, columns = payload.get("household"), payload.get("map_fingerprint"), payload.get("objects_columns", [])
    if not isinstance(name, str) or not isinstance(fp, str) or not _is_labels(columns):
        raise ModelFileError(f"{src}: malformed model file: household, map_fingerprint or objects_columns missing")
    if fingerprint is not None and fp != fingerprint:
        raise ModelFileError(f"{src}: trained for another map (household {name!r}, map {fp[:19]}...; this map is "
                             f"{fingerprint[:19]}...); retrain it for this household")
    if household is not None and name != household:
        raise ModelFileError(f"{src}: trained for household {name!r}, not {household!r}")
    activity = model_from_dict(payload.get("activity"), f"{src} (activity)")
    objects = model_from_dict(payload.get("objects"), f"{src} (objects)")
    if activity.kind not in _ACTIVITY_KINDS or objects.kind not in _OBJECT_KINDS:
        raise ModelFileError(f"{src}: malformed model file: parts are {activity.kind!r} and {objects.kind!r}, "
                             "expected an activity model and an object model")
    foreign = sorted({o for run in objects.training_data_ for o in run[1]} - set(columns)) if columns else []
    if foreign:
        raise ModelFileError(f"{src}: malformed model file: its object model names {foreign[0][:64]!r}, not an object "
                             "of the household (objects_columns)")
    nodes = _nodes(payload.get("nodes", []), tuple(columns), fp, src)
    grid, deployment = payload.get("grid"), payload.get("deployment")
    days: tuple[Day, ...] = ()
    if grid is not None or deployment is not None:
        whole = isinstance(grid, dict) and set(grid) == {"step_minutes", "day_start_minute", "steps"} and all(
            type(v) is int and 0 <= v <= 100_000 for v in grid.values())
        if not whole or not isinstance(deployment, dict):
            raise ModelFileError(f"{src}: malformed model file: 'grid' or 'deployment' is not what globe train writes")
        days = _days(payload.get("places"), activity.training_data_, tuple(columns), nodes, src)
    return HouseholdModel(name, fp, activity, objects, tuple(columns), nodes, grid, deployment, days)


def _nodes(rows: Any, columns: tuple[str, ...], fingerprint: str, src: str) -> tuple[Node, ...]:
    """The stored map, checked by the map's rules and against its fingerprint."""
    if not isinstance(rows, list) or not all(isinstance(r, list) and len(r) == 5 and _is_labels([r[0], r[1], r[4]])
                                             and isinstance(r[2], str) and type(r[3]) is bool for r in rows):
        raise ModelFileError(f"{src}: malformed model file: 'nodes' is not a list of map rows")
    nodes = tuple(Node(*r) for r in rows)
    if nodes and map_fingerprint(nodes, columns) != fingerprint:
        raise ModelFileError(f"{src}: malformed model file: its map does not match its map_fingerprint")
    try:
        check_map(nodes)
    except DataError as err:
        raise ModelFileError(f"{src}: malformed model file: its map: {err.message}") from None
    return nodes
