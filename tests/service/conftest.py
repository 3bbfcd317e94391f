"""A real service process on a free loopback port, with its SQLite file under tmp."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import httpx
import pytest

from tests.helpers import free_port


class Server:
    def __init__(self, db, log):
        self.db, self.log, self.port, self.proc = db, log, free_port(), None

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}"

    def start(self) -> "Server":
        env = dict(os.environ, GLOBE_LLM__BACKEND="none")
        with open(self.log, "a") as fh:
            self.proc = subprocess.Popen([sys.executable, "-m", "globe", "serve", "--db", str(self.db), "--port", str(self.port)],
                                         stdout=fh, stderr=subprocess.STDOUT, env=env)
        deadline = time.time() + 60
        while time.time() < deadline:
            if self.proc.poll() is not None:
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


@pytest.fixture()
def server(tmp_path):
    srv = Server(tmp_path / "globe.sqlite3", tmp_path / "server.log").start()
    yield srv
    srv.stop()
