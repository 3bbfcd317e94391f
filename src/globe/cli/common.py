"""What every command shares: the config it resolves, the console, the progress bar."""

from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path
from typing import Annotated, Any, Iterator

import typer
from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
)

from globe.config import GlobeConfig, load_config
from globe.data.csv_logs import load_household
from globe.data.locate import resolve_data_root
from globe.data.records import Household

console = Console(stderr=True)
out = Console()

DataOption = Annotated[Path | None, typer.Option("--data", help="HOMER+-style data folder (else $GLOBE_DATA, else ../shared/data/homer_plus)")]
ConfigOption = Annotated[Path | None, typer.Option("--config", help="TOML configuration file")]
HouseholdsOption = Annotated[str | None, typer.Option("--households", help="comma-separated households, e.g. A,B,C")]


def resolve(config: Path | None, **overrides: Any) -> GlobeConfig:
    return load_config(config, {k.replace("__", "."): v for k, v in overrides.items()})


def households_from(cfg: GlobeConfig, data: Path | None, households: str | None) -> list[Household]:
    root = resolve_data_root(data if data is not None else cfg.data.root)
    names = [h.strip() for h in households.split(",")] if households else list(cfg.data.households)
    return [load_household(root, n) for n in names]


@contextmanager
def progress_bar(total: int, description: str) -> Iterator[Any]:
    """A rich progress bar on stderr; yields ``advance(n)``."""
    with Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                  console=console, transient=True, disable=not console.is_terminal) as progress:
        task = progress.add_task(description, total=total)

        def advance(n: int = 1, description: str | None = None) -> None:
            progress.update(task, advance=n, **({"description": description} if description else {}))

        yield advance
