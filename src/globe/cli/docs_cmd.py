"""``globe docs``: write the documentation's tables from a results folder (and check them)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from globe.cli.common import console, out
from globe.data.locate import repository_root

app = typer.Typer(help="The documentation's generated parts.", no_args_is_help=True)


@app.command("tables")
def tables(
    results: Annotated[Path | None, typer.Option(
        "--results", help="results folder of the main job (default: reference/homer_plus of the checkout)")] = None,
    root: Annotated[Path | None, typer.Option(
        "--root", help="the checkout whose README.md and docs/*.md are written (default: this one)")] = None,
    check: Annotated[bool, typer.Option("--check", help="write nothing; exit 1 when a page differs")] = False,
) -> None:
    """Rewrite every table between <!-- globe:table NAME --> markers in README.md and docs/, and the
    configuration reference, from a results folder and GlobeConfig."""
    from globe.evaluation import docs_tables

    base = root if root is not None else repository_root()
    folder = results if results is not None else base / "reference" / "homer_plus"
    if check:
        stale = [page for page, _ in docs_tables.stale_pages(base, folder)]
        for page in stale:
            console.print(f"{page}: its tables differ from {folder} (run 'globe docs tables')", soft_wrap=True)
        if stale:
            raise typer.Exit(1)
        out.print(f"every table matches {folder}", markup=False, highlight=False, soft_wrap=True)
        return
    written = docs_tables.write_pages(base, folder)
    for page in written:
        out.print(f"wrote {page}", markup=False, highlight=False, soft_wrap=True)
    if not written:
        out.print(f"every table already matches {folder}", markup=False, highlight=False, soft_wrap=True)
