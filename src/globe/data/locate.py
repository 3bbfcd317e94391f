"""Where the data lives: ``--data`` option > ``GLOBE_DATA`` > ``../shared/data/homer_plus``.

A household is one folder of the data folder, named exactly; nothing is searched for.
"""

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


def _is_folder_name(name: str) -> bool:
    return bool(name) and name not in (".", "..") and "/" not in name and "\\" not in name and "\x00" not in name \
        and name == name.strip()


def household_names(root: Path) -> list[str]:
    """Every household of the data folder ``root``: its folders holding a ``nodes.csv``, by name,
    HOMER+'s ``Household<name>`` folders by their short name unless a folder ``<name>`` exists
    too (then by their own); a folder that cannot be read is passed over."""
    prefix = HOUSEHOLD_DIR.format(name="")
    root = Path(root)
    try:
        folders = sorted(p.name for p in root.iterdir() if p.is_dir())
    except OSError:
        return []
    names = []
    for folder in folders:
        try:
            if not any(c.name.lower() == "nodes.csv" for c in (root / folder).iterdir()):
                continue
        except OSError:
            continue
        short = folder[len(prefix):]
        names.append(short if folder.startswith(prefix) and short and short not in folders else folder)
    return names


def household_dir(root: Path, name: str) -> Path:
    """The folder of household ``name``: ``root/<name>``, or ``root/Household<name>`` (HOMER+'s
    short names ``A``, ``B``, ``C``) when no folder ``<name>`` exists. Both existing is an error
    rather than a guess; a name with a path separator is refused (the data folder is ``--data``)."""
    root = Path(root)
    if not _is_folder_name(name):
        raise DataError(f"household name {name!r} is not a folder name (set the data folder with --data)",
                        source=str(root))
    exact = root / name
    short = root / HOUSEHOLD_DIR.format(name=name)
    if exact.is_dir() and short.is_dir():
        raise DataError(f"household {name!r} is ambiguous: both {exact.name}/ and {short.name}/ exist; "
                        f"name the folder ({short.name!r})", source=str(root))
    for folder in (exact, short):
        if folder.is_dir():
            return folder
    available = household_names(root)
    raise DataError(
        f"household {name!r} not found (no folder {exact.name}/ or {short.name}/); "
        f"available: {', '.join(available) or 'none'}",
        source=str(root),
    )
