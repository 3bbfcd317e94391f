"""Where the data lives: ``--data`` option > ``GLOBE_DATA`` > ``../shared/data/homer_plus``."""

from __future__ import annotations

import os
from pathlib import Path

from globe.errors import DataError

ENV_VAR = "GLOBE_DATA"
HOUSEHOLD_DIR = "Household{name}"


def repository_root() -> Path:
    """The checkout this package is installed from (editable install), else the working dir."""
    here = Path(__file__).resolve()
    for parent in here.parents:
        if (parent / "pyproject.toml").is_file() and (parent / "src" / "globe").is_dir():
            return parent
    return Path.cwd()


def default_data_root() -> Path:
    return repository_root().parent / "shared" / "data" / "homer_plus"


def resolve_data_root(option: str | Path | None = None) -> Path:
    """Resolve the data folder by precedence and check that it exists."""
    if option is not None:
        root, how = Path(option), "--data"
    elif os.environ.get(ENV_VAR):
        root, how = Path(os.environ[ENV_VAR]), f"${ENV_VAR}"
    else:
        root, how = default_data_root(), "the default location"
    if not root.is_dir():
        raise DataError(
            f"data folder not found (from {how}); pass --data DIR or set {ENV_VAR}",
            source=str(root),
        )
    return root


def household_dir(root: Path, name: str) -> Path:
    """``A`` -> ``root/HouseholdA``; a path-like name is taken as the folder itself."""
    candidate = root / HOUSEHOLD_DIR.format(name=name)
    if candidate.is_dir():
        return candidate
    if (root / name).is_dir():
        return root / name
    available = sorted(p.name for p in root.iterdir() if (p / "nodes.csv").is_file())
    raise DataError(
        f"household {name!r} not found; available: {', '.join(available) or 'none'}",
        source=str(root),
    )
