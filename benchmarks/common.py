"""What every benchmark starts with: the command line (--data) and the HOMER+ households; and
``globe serve`` as its own process, for the benchmarks that go through HTTP."""

from __future__ import annotations

import argparse
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import httpx

from globe.config import GlobeConfig
from globe.data.csv_logs import load_household
from globe.data.locate import household_names, resolve_data_root
from globe.data.records import Household
from globe.errors import DataError


def setup(doc: str | None,
          extra: dict[str, dict] | None = None) -> tuple[GlobeConfig, list[Household], argparse.Namespace]:
    """Parse ``--data`` (and ``extra`` options), load every configured household."""
    parser = argparse.ArgumentParser(description=doc)
    parser.add_argument("--data", default=None, help="HOMER+ folder (else $GLOBE_DATA, else ../shared/data/homer_plus)")
    for flag, kwargs in (extra or {}).items():
        parser.add_argument(flag, **kwargs)
    args = parser.parse_args()
    cfg = GlobeConfig()
    try:
        root = resolve_data_root(args.data)
        return cfg, [load_household(root, n) for n in cfg.data.households or household_names(root)], args
    except DataError as e:  # a missing or broken data folder: its message, not a traceback
        raise SystemExit(str(e)) from None


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def serve(db: Path, env: dict[str, str], *options: str, log: Path | None = None) -> tuple[subprocess.Popen, str]:
    """``globe serve --db db`` (and ``options``) on a free loopback port with environment ``env``,
    its output into ``log``; returns the process and its base URL once /health answers."""
    port = free_port()
    cmd = [sys.executable, "-m", "globe", "serve", "--db", str(db), "--port", str(port), *options]
    with open(log or os.devnull, "w") as out:
        proc = subprocess.Popen(cmd, stdout=out, stderr=subprocess.STDOUT, env=env)
    url = f"http://127.0.0.1:{port}"
    deadline = time.time() + 120
    while time.time() < deadline:
        if proc.poll() is not None:
            raise SystemExit("globe serve exited" + (f":\n{log.read_text()[-3000:]}" if log else ""))
        try:
            if httpx.get(url + "/health", timeout=1).status_code == 200:
                return proc, url
        except httpx.HTTPError:
            time.sleep(0.02)
    proc.kill()
    raise SystemExit("globe serve did not answer /health within 120 s")


def stop(proc: subprocess.Popen) -> None:
    """Terminate ``globe serve`` (SIGTERM), killing it if it has not exited within 30 s."""
    proc.terminate()
    try:
        proc.wait(timeout=30)
    except subprocess.TimeoutExpired:
        proc.kill()
