"""``globe data``: validate observation logs, import native HOMER+ files."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from globe.cli.common import (
    ConfigOption,
    DataOption,
    HouseholdsOption,
    households_from,
    out,
    plain,
    resolve,
)
from globe.data.csv_logs import household_step
from globe.sequences.runs import activity_runs

app = typer.Typer(help="Validate and import household observation logs.", no_args_is_help=True)


@app.command("validate")
def validate(data: DataOption = None, households: HouseholdsOption = None, config: ConfigOption = None) -> None:
    """Load every day file, check it, and summarise each household."""
    cfg = resolve(config)
    table = Table(title="Households")
    for col in ("household", "train days", "test days", "step (min)", "objects", "activities", "movements"):
        table.add_column(col)
    for h in households_from(cfg, data, households):
        days = h.train + h.test
        moves = sum(len(r.events) for d in days for r in activity_runs(d, h.objects, cfg.sequences.alignment))
        acts = {a for d in days for a in d.activities}
        step = cfg.data.step_minutes or household_step(days)
        table.add_row(plain(h.name), str(len(h.train)), str(len(h.test)), str(step or "-"), str(len(h.objects)), str(len(acts)),
                      str(moves))
    out.print(table)
    out.print("all files valid", style="green", markup=False)


@app.command("import-pt")
def import_pt(
    source: Annotated[Path, typer.Argument(help="a HOMER+ checkout's processed_seqLM_coarse folder (or its parent)")],
    dest: Annotated[Path, typer.Argument(help="output household folder (nodes.csv, train/, test/)")],
) -> None:
    """Convert native HOMER+ ``.pt`` files into CSV observation logs (needs globe[torch])."""
    from globe.data.homer_pt import import_household

    written = import_household(source, dest)
    out.print(f"wrote {len(written)} day files and nodes.csv to {dest}", markup=False, highlight=False)
