"""A model file re-sealed with a recomputed checksum is still checked field by field: values of
the wrong type or out of range are a ModelFileError naming the field, never a loaded model."""

import json
import math

import pytest

from globe.errors import ModelFileError
from globe.models.io import MODEL_FILE, _checksum, load_household_model, save_household_model


def tamper(path, edit) -> None:
    """Edit the saved file and seal it again, as anyone can (the checksum is plain SHA-256)."""
    payload = json.loads(path.read_text())
    payload.pop("checksum")
    edit(payload)
    payload["checksum"] = _checksum(payload)
    path.write_text(json.dumps(payload))


EDITS = {
    "bundle version true": (lambda p: p.__setitem__("version", True), "format version True"),
    "activity version true": (lambda p: p["activity"].__setitem__("version", True), "format version True"),
    "time_weight NaN": (lambda p: p["activity"]["params"].__setitem__("time_weight", math.nan), "params.time_weight"),
    "time_weight infinite": (lambda p: p["activity"]["params"].__setitem__("time_weight", math.inf),
                             "params.time_weight"),
    "time_weight negative": (lambda p: p["activity"]["params"].__setitem__("time_weight", -1.0), "params.time_weight"),
    "max_order true": (lambda p: p["activity"]["params"].__setitem__("max_order", True), "params.max_order"),
    "max_order 2.5": (lambda p: p["objects"]["params"].__setitem__("max_order", 2.5), "params.max_order"),
    "max_order huge": (lambda p: p["objects"]["params"].__setitem__("max_order", 10**40), "params.max_order"),
    "run_start_token 1": (lambda p: p["objects"]["params"].__setitem__("run_start_token", 1), "params.run_start_token"),
    "estimator 3": (lambda p: p["activity"]["params"].__setitem__("estimator", 3), "params.estimator"),
    "unknown parameter": (lambda p: p["objects"]["params"].__setitem__("speed", 1), "params.speed"),
    "weekday 7": (lambda p: p["activity"].__setitem__("weekdays", [7] * len(p["activity"]["data"])), "'weekdays'"),
    "weekday true": (lambda p: p["activity"].__setitem__("weekdays", [True] * len(p["activity"]["data"])),
                     "'weekdays'"),
    "weekdays short": (lambda p: p["activity"].__setitem__("weekdays", [0]), "'weekdays'"),
    "weekdays on objects": (lambda p: p["objects"].__setitem__("weekdays", [0] * len(p["objects"]["data"])),
                            "'weekdays'"),
    # accepted until now:
    "an object the household lacks": (lambda p: p["objects"]["data"][0][1].append("unicorn"),
                                      "'unicorn', not an object"),
    "an ESC in an activity": (lambda p: p["activity"]["data"][0].__setitem__(0, "sleep\x1b[2J"), r"data\[0\] is not"),
    "an ESC in an object": (lambda p: p["objects"]["data"][0][1].append("cup\x1b"), r"data\[0\] is not"),
    "a 5 MB label": (lambda p: p["activity"]["data"][0].__setitem__(0, "x" * (5 << 20)), r"data\[0\] is not"),
}


@pytest.mark.parametrize("edit", EDITS, ids=list(EDITS))
def test_a_resealed_model_file_is_checked_by_type_and_range(tmp_path, fitted, edit):
    f = fitted["A"]
    objects = tuple(sorted({o for _, run in f.objects.training_data_ for o in run}))
    save_household_model(tmp_path, f.activity, f.objects, household="A", fingerprint="f" * 64, objects_columns=objects)
    assert load_household_model(tmp_path).activity.get_params() == f.activity.get_params()  # untouched: loads
    change, named = EDITS[edit]
    tamper(tmp_path / MODEL_FILE, change)
    with pytest.raises(ModelFileError, match=named.replace(".", r"\.")):
        load_household_model(tmp_path)
