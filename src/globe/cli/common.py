"""What every command shares: the config it resolves, the console, the progress bar."""

from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path
from typing import Annotated, Any, Iterator

import typer
from rich.console import Console
from rich.measure import Measurement
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
)
from rich.table import Table
from rich.text import Text

from globe.config import GlobeConfig, load_config
from globe.data.csv_logs import load_household, read_household_map
from globe.data.locate import household_names, resolve_data_root
from globe.data.records import Household, map_fingerprint
from globe.errors import DataError

# Messages carry user text (labels, paths): never read as rich markup or emoji codes (root:x:0).
console = Console(stderr=True, markup=False, emoji=False, highlight=False)
out = Console(emoji=False)

DataOption = Annotated[Path | None, typer.Option(
    "--data", help="HOMER+-style data folder (else $GLOBE_DATA, else ../shared/data/homer_plus)")]
ConfigOption = Annotated[Path | None, typer.Option("--config", help="TOML configuration file")]
HouseholdsOption = Annotated[str | None, typer.Option("--households", help="comma-separated households, e.g. A,B,C")]


def resolve(config: Path | None, **overrides: Any) -> GlobeConfig:
    return load_config(config, {k.replace("__", "."): v for k, v in overrides.items()})


def households_from(cfg: GlobeConfig, data: Path | None, households: str | None) -> list[Household]:
    """Load the named households (else ``data.households``, else every household of the data
    folder) by the ``data`` section's rules."""
    root = resolve_data_root(data if data is not None else cfg.data.root)
    if households is not None:
        names = [h.strip() for h in households.split(",")]
        if not names or any(not n for n in names):
            raise typer.BadParameter(f"{households!r} names no household", param_hint="'--households'")
    elif cfg.data.households is not None:
        names = list(cfg.data.households)
    else:
        names = household_names(root)
        if not names:
            raise DataError("no household folder (one with a nodes.csv) in the data folder; import a home with "
                            "'globe data import' or pass --data", source=str(root))
    return [load_household(root, n, step_minutes=cfg.data.step_minutes, resample=cfg.data.resample) for n in names]


def household_map(cfg: GlobeConfig, data: Path | None, name: str) -> tuple[str, str]:
    """``(folder name, map fingerprint)`` of a household, from its ``nodes.csv`` alone."""
    folder, nodes = read_household_map(resolve_data_root(data if data is not None else cfg.data.root), name)
    return folder.name, map_fingerprint(nodes, tuple(n.cls for n in nodes if n.movable))


def count(n: int, noun: str) -> str:
    """``1 day``, ``2 days``: a number with its noun (plural by ``s``)."""
    return f"{n} {noun}" if n == 1 else f"{n} {noun}s"


def print_table(table: Table) -> None:
    """Print a table on stdout. A terminal fits it to its width; a file or a pipe (a log, CI,
    ``| less``) gets it at its natural width, since rich would otherwise squeeze it into 80
    columns and cut the method names ("Persisten…")."""
    if out.is_terminal:
        out.print(table)
        return
    natural = Measurement.get(out, out.options.update(max_width=100_000), table).maximum
    Console(file=out.file, width=max(natural, 20), emoji=False, color_system=None).print(table)


def plain(text: object) -> Text:
    """User text for a rich table cell or print, shown exactly as written."""
    return Text(str(text))


@contextmanager
def progress_bar(total: int, description: str) -> Iterator[Any]:
    """A rich progress bar on stderr; yields ``advance(n)``."""
    with Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                  console=console, transient=True, disable=not console.is_terminal) as progress:
        task = progress.add_task(description, total=total)

        def advance(n: int = 1, description: str | None = None) -> None:
            if description:
                progress.update(task, advance=n, description=description)
            else:
                progress.update(task, advance=n)

        yield advance


def require_test_days(households: list[Household]) -> None:
    """``globe evaluate`` scores test days: a household without any is a one-line error (it can
    still be trained, validated and served)."""
    empty = [h for h in households if not h.test]
    if empty:
        h = empty[0]
        raise DataError(f"household {h.name} has no test days (test/*.csv): nothing to score; evaluate households "
                        "with test days (it can still be trained and served)", source=h.source)
