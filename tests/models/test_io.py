"""One atomic model file per household: versioned, fingerprinted, checksummed; malformed is an error."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import pytest

from globe.assembly import fit_household
from globe.config import GlobeConfig
from globe.data.csv_logs import load_household
from globe.data.records import map_fingerprint
from globe.errors import ModelFileError
from globe.models.io import (
    MODEL_FILE,
    load_household_model,
    load_model,
    model_from_dict,
    model_to_dict,
    save_household_model,
    save_model,
)
from tests.corpus.homes import write_home


@pytest.fixture()
def tiny(tmp_path):
    write_home(tmp_path / "data", "HouseholdT")
    h = load_household(tmp_path / "data", "T")
    return h, fit_household(h, GlobeConfig())


def _save(tiny, model_dir):
    h, fitted = tiny
    return save_household_model(model_dir, fitted.activity, fitted.objects, household="HouseholdT",
                                fingerprint=map_fingerprint(h.nodes, h.objects), objects_columns=h.objects)


def test_round_trip_keeps_predictions_and_identity(tiny, tmp_path):
    h, fitted = tiny
    path = _save(tiny, tmp_path / "m")
    assert path == tmp_path / "m" / MODEL_FILE and sorted(p.name for p in (tmp_path / "m").iterdir()) == [MODEL_FILE]
    loaded = load_household_model(tmp_path / "m", fingerprint=map_fingerprint(h.nodes, h.objects),
                                  household="HouseholdT")
    assert loaded.household == "HouseholdT" and loaded.objects_columns == ("cup", "plate")
    assert loaded.activity.predict_proba(("sleeping",)) == fitted.activity.predict_proba(("sleeping",))
    assert loaded.objects.predict_proba("breakfast") == fitted.objects.predict_proba("breakfast")


def test_real_household_round_trip(households, fitted, tmp_path):
    h, f = households["C"], fitted["C"]
    fingerprint = map_fingerprint(h.nodes, h.objects)
    save_household_model(tmp_path, f.activity, f.objects, household="HouseholdC", fingerprint=fingerprint)
    loaded = load_household_model(tmp_path, fingerprint=fingerprint)
    history = h.test[0].activities[:20]
    assert loaded.activity.predict_proba(history) == f.activity.predict_proba(history)


def test_another_map_is_refused(tiny, tmp_path):
    _save(tiny, tmp_path / "m")
    with pytest.raises(ModelFileError, match=r"trained for another map"):
        load_household_model(tmp_path / "m", fingerprint="sha256:" + "0" * 64)
    with pytest.raises(ModelFileError, match=r"trained for household 'HouseholdT', not 'HouseholdB'"):
        load_household_model(tmp_path / "m", household="HouseholdB")


def test_fingerprint_follows_the_map(tiny):
    h, _ = tiny
    fp = map_fingerprint(h.nodes, h.objects)
    assert fp.startswith("sha256:") and fp == map_fingerprint(list(h.nodes), h.objects)
    assert fp != map_fingerprint(h.nodes[:-1], h.objects) and fp != map_fingerprint(h.nodes, h.objects[::-1])


@pytest.mark.parametrize("edit, message", [
    (lambda p: p.update(version=99), r"format version 99, this GLOBE reads 2"),
    (lambda p: p.update(format="other"), r"not a GLOBE household model \(format 'other'\)"),
    (lambda p: p.update(household="HouseholdX"), r"checksum mismatch"),
    (lambda p: p["activity"]["data"].pop(), r"checksum mismatch"),
])
def test_edited_files_are_refused(tiny, tmp_path, edit, message):
    path = _save(tiny, tmp_path / "m")
    payload = json.loads(path.read_text())
    edit(payload)
    path.write_text(json.dumps(payload))
    with pytest.raises(ModelFileError, match=message):
        load_household_model(tmp_path / "m")


def _resign(path, edit):
    """Edit the content and recompute the checksum: only the content checks remain."""
    from globe.models.io import _checksum

    payload = json.loads(path.read_text())
    edit(payload)
    body = {k: v for k, v in payload.items() if k != "checksum"}
    path.write_text(json.dumps({**body, "checksum": _checksum(body)}))


@pytest.mark.parametrize("edit, message", [
    (lambda p: p["activity"].update(data="x"), r"\(activity\): malformed model file: 'data' is str, expected a list"),
    (lambda p: p["activity"].update(data=[[1, 2]]),
     r"\(activity\): malformed model file: data\[0\] is not a non-empty list"),
    (lambda p: p["objects"].update(data=[["a", "b"]]),
     r"\(objects\): malformed model file: data\[0\] is not \[activity"),
    (lambda p: p["activity"].update(params={"max_order": -3}), r"\(activity\): malformed model file: .*max_order=-3"),
    (lambda p: p["activity"].update(params={"nope": 1}), r"\(activity\): malformed model file: .*nope"),
    (lambda p: p["activity"].update(kind="magic"), r"unknown model kind 'magic'"),
    (lambda p: p.update(objects=p["activity"]), r"parts are 'activity' and 'activity'"),
    (lambda p: p.update(objects=[]), r"\(objects\): not a GLOBE model file \(a JSON list"),
    (lambda p: p.update(household=3), r"household, map_fingerprint or objects_columns missing"),
])
def test_malformed_content_is_one_model_file_error(tiny, tmp_path, edit, message):
    path = _save(tiny, tmp_path / "m")
    _resign(path, edit)
    with pytest.raises(ModelFileError, match=message) as err:
        load_household_model(tmp_path / "m")
    assert "\n" not in str(err.value)


def test_a_failed_save_leaves_the_previous_model(tiny, tmp_path, monkeypatch):
    _save(tiny, tmp_path / "m")
    before = (tmp_path / "m" / MODEL_FILE).read_bytes()

    def crash(src, dst):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", crash)
    with pytest.raises(ModelFileError, match=r"cannot write the model: No space left on device"):
        _save(tiny, tmp_path / "m")
    monkeypatch.undo()
    assert (tmp_path / "m" / MODEL_FILE).read_bytes() == before
    assert sorted(p.name for p in (tmp_path / "m").iterdir()) == [MODEL_FILE]  # no temporary file left


_SAVER = """
import sys
from pathlib import Path
from globe.assembly import fit_household
from globe.config import GlobeConfig
from globe.data.csv_logs import load_household
from globe.data.records import map_fingerprint
from globe.models.io import save_household_model

root, out = Path(sys.argv[1]), Path(sys.argv[2])
hs = [load_household(root, n) for n in ("T", "U")]
fits = [fit_household(h, GlobeConfig()) for h in hs]
print("ready", flush=True)
i = 0
while True:
    h, f = hs[i % 2], fits[i % 2]
    save_household_model(out, f.activity, f.objects, household=h.name, fingerprint=map_fingerprint(h.nodes, h.objects))
    i += 1
"""


def test_a_killed_save_never_leaves_a_model_that_loads_wrong(tmp_path):
    """A real process saving two households' models in turn is killed at random moments: what is
    on disk always loads as one whole model of one household, never a mix or a partial file."""
    write_home(tmp_path / "data", "HouseholdT", train=3)
    write_home(tmp_path / "data", "HouseholdU", train=2)
    expected = {}
    for name in ("T", "U"):
        h = load_household(tmp_path / "data", name)
        expected[name] = len(fit_household(h, GlobeConfig()).activity.training_data_)
    for delay in (0.05, 0.13, 0.21):
        out = tmp_path / f"m{delay}"
        argv = [sys.executable, "-c", _SAVER, str(tmp_path / "data"), str(out)]
        proc = subprocess.Popen(argv, stdout=subprocess.PIPE, text=True)
        assert proc.stdout.readline().strip() == "ready"
        time.sleep(delay)
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=30)
        if not (out / MODEL_FILE).exists():
            continue
        loaded = load_household_model(out)
        assert loaded.household in expected
        assert len(loaded.activity.training_data_) == expected[loaded.household]


@pytest.mark.parametrize("content, message", [
    (b"\xff\xfe\x00{", r"not a GLOBE model file \(not UTF-8 text at byte 0\)"),
    (b"[1, 2]", r"not a GLOBE model file \(a JSON list, expected an object\)"),
    (b'{"format": "globe-model", "version": 1, "kind": "object", "params": {}, "data": [["a"]]}',
     r"data\[0\] is not"),
    (b'{"format": "globe-model", "version": 1, "kind": "activity", "params": [], "data": []}',
     r"'params' is not an object"),
    (b"[" * 100_000, r"not JSON|nested too deeply"),
])
def test_single_model_files_are_checked(tmp_path, content, message):
    path = tmp_path / "m.json"
    path.write_bytes(content)
    with pytest.raises(ModelFileError, match=message):
        load_model(path)


def test_the_object_baseline_round_trips_with_its_minutes(tiny, tmp_path):
    """The object model cross-validation may deploy instead of the n-gram (``models.object_model``)
    is saved with each use's clock minute and answers the same after loading; a minute that is no
    clock minute, or one missing, is refused."""
    h, _ = tiny
    fitted = fit_household(h, GlobeConfig().with_overrides({"models.object_model": "hour_activity"}))
    assert fitted.objects.kind == "hour_activity_objects" and fitted.objects.training_data_
    _save((h, fitted), tmp_path / "m")
    loaded = load_household_model(tmp_path / "m")
    assert loaded.objects.training_data_ == fitted.objects.training_data_
    for minute in (None, 420, 1150):
        assert loaded.objects.predict_proba("breakfast", (), minute) == fitted.objects.predict_proba("breakfast", (),
                                                                                                     minute)
    payload = model_to_dict(fitted.objects)
    for bad in ([["breakfast", ["cup"], [-5]]], [["breakfast", ["cup"], []]], [["breakfast", ["cup"], [True]]]):
        with pytest.raises(ModelFileError, match=r"data\[0\] is not \[activity, \[objects\.\.\.\], \[minutes"):
            model_from_dict({**payload, "data": bad})


def test_single_model_round_trip_and_unwritable_target(tiny, tmp_path):
    _, fitted = tiny
    save_model(fitted.activity, tmp_path / "a.json")
    again = model_from_dict(model_to_dict(load_model(tmp_path / "a.json")))
    assert again.training_data_ == fitted.activity.training_data_
    (tmp_path / "file").write_text("x")
    with pytest.raises(ModelFileError, match=r"cannot write the model"):
        save_model(fitted.activity, tmp_path / "file" / "a.json")
    with pytest.raises(ModelFileError, match=r"is a folder, not a model file"):
        load_model(tmp_path)
