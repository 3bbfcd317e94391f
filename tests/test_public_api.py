"""The public API: every name of ``globe.__all__`` imports, the package is typed, and importing
it pulls in no optional extra (the core must work without llama_cpp, openai or fastapi)."""

import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

import globe

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("name", sorted(globe.__all__))
def test_every_public_name_imports(name):
    value = getattr(globe, name)
    assert value is not None
    if name != "__version__":
        assert getattr(value, "__module__", "globe").startswith("globe"), f"{name} comes from {value.__module__}"


def test_what_the_issue_promises_is_public():
    wanted = {"load_household", "ActivityModel", "RoutineModel", "PersistenceModel", "ObjectModel", "Forecaster",
              "ActivityFilter", "UncertaintyGate", "EmbeddedBackend", "RemoteBackend", "FetchPolicy", "GlobeClient",
              "GlobeConfig", "__version__"}
    assert wanted <= set(globe.__all__)
    assert len(globe.__all__) == len(set(globe.__all__))


def test_an_unknown_name_is_an_attribute_error():
    with pytest.raises(AttributeError, match="no attribute 'Nope'"):
        globe.Nope  # noqa: B018


def test_the_version_is_the_package_version():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    assert globe.__version__ == project["version"]


def test_the_package_is_typed():
    assert (ROOT / "src" / "globe" / "py.typed").is_file()
    package_data = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["setuptools"]["package-data"]
    assert "py.typed" in package_data["globe"]


def test_importing_globe_pulls_in_no_optional_extra():
    code = ("import sys, globe; heavy = ('fastapi', 'llama_cpp', 'openai', 'httpx', 'uvicorn', 'torch'); "
            "print(sorted({m.split('.')[0] for m in sys.modules} & set(heavy)))")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True)
    assert res.stdout.strip() == "[]"


def test_a_lazy_name_is_kept_after_first_use():
    first = globe.RoutineModel
    assert "RoutineModel" in vars(globe) and globe.RoutineModel is first


def test_every_lazy_name_is_listed_and_nothing_else_is_missing():
    assert set(globe._LAZY) <= set(globe.__all__)
    eager = set(globe.__all__) - set(globe._LAZY)
    assert all(name in vars(globe) for name in eager)
