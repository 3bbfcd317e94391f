"""A real ``globe serve`` process on a free loopback port, with its SQLite file and an admin
token: what every test that talks HTTP to the service starts."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import httpx
import pytest

from globe.service.auth import create_token
from globe.service.client import GlobeClient
from tests.helpers import free_port


class Server:
    def __init__(self, db, log, env=None, preexec_fn=None):
        self.db, self.log, self.port, self.proc = db, log, free_port(), None
        self.preexec_fn = preexec_fn  # run in the server process before it starts (e.g. resource limits)
        self.args: list[str] = []  # more options of globe serve
        # The paper's models unless a test asks for the deployment chosen by cross-validation (it runs
        # in the background and rebuilds the household when it ends); the LLM's answers in this test's
        # own folder, never in the checkout's cache.
        self.env = {"GLOBE_LLM__BACKEND": "none", "GLOBE_SERVICE__PRELOAD": "false", "GLOBE_SELECTION__DEPLOY": "ngram",
                    "GLOBE_LLM__CACHE_DIR": str(Path(log).parent / "llm-cache"), **(env or {})}
        self.admin = create_token(db, admin=True)

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}"

    def client(self, token: str | None = None, **kw) -> GlobeClient:
        return GlobeClient(self.url, token=self.admin if token is None else token, **kw)

    def token(self, household: str) -> str:
        return create_token(self.db, household=household)

    def start(self, expect_failure: bool = False) -> "Server":
        env = dict(os.environ, **self.env)
        with open(self.log, "a") as fh:
            self.proc = subprocess.Popen([sys.executable, "-m", "globe", "serve", "--db", str(self.db),
                                          "--port", str(self.port), *self.args], cwd=Path(self.log).parent,
                                         stdout=fh, stderr=subprocess.STDOUT, env=env, preexec_fn=self.preexec_fn)
        deadline = time.time() + 60
        while time.time() < deadline:
            if self.proc.poll() is not None:
                if expect_failure:
                    return self
                pytest.fail(f"service exited: {open(self.log).read()[-3000:]}")
            try:
                if httpx.get(self.url + "/health", timeout=1).status_code == 200:
                    return self
            except httpx.HTTPError:
                time.sleep(0.1)
        self.kill()
        pytest.fail("service did not start within 60 s")

    def kill(self) -> None:
        if self.proc and self.proc.poll() is None:
            self.proc.send_signal(signal.SIGKILL)
            self.proc.wait(timeout=10)

    def stop(self) -> None:
        if self.proc and self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.kill()
