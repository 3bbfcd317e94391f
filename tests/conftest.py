"""Session fixtures: the real HOMER+ data (resolved exactly as the CLI does), fitted models, the
embedded Gemma model and llama-cpp-python's OpenAI-compatible server."""

from __future__ import annotations

import os
import random
import socket
import subprocess
import sys
import time

import pytest

from globe.assembly import fit_household
from globe.config import GlobeConfig
from globe.data.csv_logs import load_household
from globe.data.locate import resolve_data_root
from tests.helpers import free_port


def pytest_configure(config):
    """One seed per run, drawn once: here in the run's own process (pytest-xdist's controller),
    handed to every xdist worker through its ``workerinput``, so that all workers (and the header a
    failure is rerun from) use the same seed."""
    workerinput = getattr(config, "workerinput", None)
    if workerinput is not None:
        os.environ["GLOBE_TEST_SEED"] = workerinput["globe_test_seed"]
        # llama.cpp's threads spin at each barrier: two workers' LLMs with two threads each on two
        # cores run several times slower than one thread each (the commands the tests start inherit it)
        os.environ.setdefault("GLOBE_LLM__N_THREADS", str(llm_threads()))
    elif not os.environ.get("GLOBE_TEST_SEED"):
        os.environ["GLOBE_TEST_SEED"] = str(random.randrange(1_000_000))


def _cores() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def llm_threads() -> int:
    """llama.cpp threads per test process: the cores shared among pytest-xdist's workers."""
    workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
    return max(1, min(2, _cores() // max(1, workers)))


@pytest.hookimpl(optionalhook=True)
def pytest_configure_node(node):
    """pytest-xdist: a worker starts with the controller's seed."""
    node.workerinput["globe_test_seed"] = os.environ["GLOBE_TEST_SEED"]


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_auto_num_workers(config):
    """``-n auto`` (pyproject.toml's default): one pytest-xdist worker per core, at most 4 (each
    holds HOMER+ and its fitted models, about 1 GB, and starts its own services), and none for a run
    of a single test file (it would run on one worker anyway, after the workers' start)."""
    if os.environ.get("PYTEST_XDIST_AUTO_NUM_WORKERS"):
        return None  # xdist's own reading of it
    files = {arg.split("::")[0] for arg in config.args}
    if len(files) == 1 and os.path.isfile(next(iter(files))):
        return 0
    return max(1, min(_cores(), 4))


def pytest_collection_modifyitems(config, items):
    """Under pytest-xdist, the modules with a test marked ``slow`` first (the order is otherwise
    kept): the workers take whole modules (``--dist loadfile``) in this order, and the longest one
    taken last would leave one worker running alone at the end."""
    if getattr(config, "workerinput", None) is None:
        return
    slow = {item.nodeid.split("::")[0] for item in items if item.get_closest_marker("slow")}
    items.sort(key=lambda item: item.nodeid.split("::")[0] not in slow)


def pytest_report_header(config):
    return f"GLOBE_TEST_SEED={os.environ['GLOBE_TEST_SEED']}"


_WRITTEN_BY_DEFAULT = ("globe.sqlite3", ".globe-cache")


@pytest.fixture(autouse=True)
def _nothing_written_where_the_tests_run(request):
    """The tests use their own folders: a default file (the service's database, the LLM answer
    cache) appearing in the folder they run from means this test did not."""
    from pathlib import Path

    before = {n for n in _WRITTEN_BY_DEFAULT if Path(n).exists()}
    yield
    appeared = [n for n in _WRITTEN_BY_DEFAULT if Path(n).exists() and n not in before]
    # pytest-xdist's workers share this folder: a file another worker's test wrote while this one ran
    # fails both (the culprit is the one that fails again under ``-n 0``).
    assert not appeared, f"{request.node.nodeid} wrote {appeared} into {Path.cwd()} instead of its own folder"


@pytest.fixture(scope="session")
def seed() -> int:
    return int(os.environ.get("GLOBE_TEST_SEED", "0"))


@pytest.fixture(scope="session")
def homer_root():
    """Fails loudly (never skips) when the shipped data is missing."""
    return resolve_data_root(None)


@pytest.fixture(scope="session")
def households(homer_root):
    return {name: load_household(homer_root, name) for name in ("A", "B", "C")}


@pytest.fixture(scope="session")
def config() -> GlobeConfig:
    return GlobeConfig()


@pytest.fixture(scope="session")
def fitted(households, config):
    """Paper-configuration models per household (never mutated by tests)."""
    return {n: fit_household(h, config) for n, h in households.items()}


@pytest.fixture(scope="session")
def gguf_path():
    from globe.reasoning.backends.embedded import packaged_model_path

    return packaged_model_path()


@pytest.fixture(scope="session")
def embedded_llm(gguf_path):
    from globe.reasoning.backends.embedded import EmbeddedBackend

    return EmbeddedBackend(model_path=gguf_path, n_threads=llm_threads())


@pytest.fixture(scope="session")
def llm_server(gguf_path, tmp_path_factory):
    """``python -m llama_cpp.server`` on a free loopback port; yields its base URL."""
    port = free_port()
    log = tmp_path_factory.mktemp("llm-server") / "server.log"
    with log.open("w") as fh:
        proc = subprocess.Popen(
            [sys.executable, "-m", "llama_cpp.server", "--model", str(gguf_path), "--host", "127.0.0.1",
             "--port", str(port), "--n_threads", str(llm_threads()), "--n_ctx", "512"],
            stdout=fh, stderr=subprocess.STDOUT,
        )
    deadline = time.time() + 60
    while time.time() < deadline:
        if proc.poll() is not None:
            pytest.fail(f"llama_cpp.server exited: {log.read_text()[-2000:]}")
        try:
            with socket.create_connection(("127.0.0.1", port), timeout=0.5):
                break
        except OSError:
            time.sleep(0.2)
    else:
        proc.kill()
        pytest.fail("llama_cpp.server did not start within 60 s")
    yield f"http://127.0.0.1:{port}/v1"
    proc.terminate()
    try:
        proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
        proc.kill()
