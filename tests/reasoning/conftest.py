"""Real LLM fixtures: the embedded Gemma model, and llama-cpp-python's OpenAI-compatible server."""

from __future__ import annotations

import socket
import subprocess
import sys
import time

import pytest


@pytest.fixture(scope="session")
def gguf_path():
    from globe.reasoning.backends.embedded import packaged_model_path

    return packaged_model_path()


@pytest.fixture(scope="session")
def embedded_llm(gguf_path):
    from globe.reasoning.backends.embedded import EmbeddedBackend

    return EmbeddedBackend(model_path=gguf_path, n_threads=2)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="session")
def llm_server(gguf_path, tmp_path_factory):
    """``python -m llama_cpp.server`` on a free loopback port; yields its base URL."""
    port = free_port()
    log = tmp_path_factory.mktemp("llm-server") / "server.log"
    with log.open("w") as fh:
        proc = subprocess.Popen(
            [sys.executable, "-m", "llama_cpp.server", "--model", str(gguf_path), "--host", "127.0.0.1",
             "--port", str(port), "--n_threads", "2", "--n_ctx", "512"],
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
