"""Small helpers shared by tests."""

import socket


def free_port() -> int:
    """A TCP port on loopback that nothing listens on right now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def require_system(*names: str, install: str) -> None:
    """Skip the test, saying what to install, when a system program it drives is missing, but fail
    under ``CI=true`` (CI installs them: their absence there is a broken set-up, not a skip)."""
    import os
    import shutil

    import pytest

    missing = [n for n in names if shutil.which(n) is None]
    if missing:
        message = f"{', '.join(missing)} not found: install {install}"
        if os.environ.get("CI") == "true":
            pytest.fail(message)
        pytest.skip(message)


def results_folder(*parts: str):
    """Where a test run writes what a person looks at afterwards (screenshots): ``$GLOBE_TEST_RESULTS``,
    else ``results/test-run`` under the repository root (ignored by git)."""
    import os
    from pathlib import Path

    root = Path(os.environ.get("GLOBE_TEST_RESULTS") or Path(__file__).resolve().parents[1] / "results" / "test-run")
    folder = root.joinpath(*parts)
    folder.mkdir(parents=True, exist_ok=True)
    return folder
