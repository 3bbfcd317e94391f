"""Property tests: a damaged or edited model file loads as a whole model or is one ModelFileError."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from globe.assembly import fit_household
from globe.config import GlobeConfig
from globe.data.csv_logs import load_household
from globe.data.records import map_fingerprint
from globe.errors import ModelFileError
from globe.models.io import MODEL_FILE, _checksum, load_household_model, save_household_model
from tests.corpus.homes import write_home
from tests.fuzz.mutations import byte_damage

EXPLORE = int(os.environ.get("GLOBE_FUZZ_EXAMPLES", "0"))
FUZZ = settings(max_examples=EXPLORE or 100, deadline=None, derandomize=not EXPLORE, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
JSON = st.recursive(st.none() | st.booleans() | st.integers(-3, 200) | st.floats(allow_nan=True) | st.text(max_size=6),
                    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=6), inner, max_size=3),
                    max_leaves=8)


@pytest.fixture(scope="module")
def saved(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("model-fuzz")
    write_home(root / "data", "HouseholdT")
    h = load_household(root / "data", "T")
    f = fit_household(h, GlobeConfig())
    save_household_model(root / "m", f.activity, f.objects, household="HouseholdT",
                         fingerprint=map_fingerprint(h.nodes, h.objects), objects_columns=h.objects)
    return root / "m"


def _outcome(model_dir: Path, data: bytes):
    path = model_dir / MODEL_FILE
    before = path.read_bytes()
    path.write_bytes(data)
    try:
        return load_household_model(model_dir)
    except ModelFileError as err:
        assert "\n" not in str(err) and str(err).startswith(str(path)), str(err)
        return err
    finally:
        path.write_bytes(before)


@FUZZ
@given(st.data())
def test_damaged_bytes_never_load_a_different_model(saved, data):
    original = (saved / MODEL_FILE).read_bytes()
    mutated = data.draw(byte_damage(original))
    result = _outcome(saved, mutated)
    if not isinstance(result, ModelFileError):  # only a change JSON ignores (whitespace) may load
        assert json.loads(mutated) == json.loads(original)


def _paths(node, prefix=()):
    yield prefix
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _paths(v, prefix + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node[:4]):
            yield from _paths(v, prefix + (i,))


@FUZZ
@given(st.data())
def test_edited_and_resigned_content_is_checked(saved, data):
    """Even with a valid checksum (a hand edit that recomputed it), content is checked by shape."""
    payload = json.loads((saved / MODEL_FILE).read_text())
    body = {k: v for k, v in payload.items() if k != "checksum"}
    paths = [p for p in _paths(body) if p]
    target = data.draw(st.sampled_from(paths))
    node = body
    for key in target[:-1]:
        node = node[key]
    node[target[-1]] = data.draw(JSON)
    text = json.dumps({**body, "checksum": _checksum(body)})
    result = _outcome(saved, text.encode("utf-8"))
    if not isinstance(result, ModelFileError):
        assert result.activity.kind in ("activity", "persistence", "routine") and result.objects.kind == "object"
        result.activity.predict_proba(())
