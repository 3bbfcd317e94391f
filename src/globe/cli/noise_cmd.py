"""``globe noise``: generate HOMER-Noise (the work is :func:`globe.noise.dataset.generate_dataset`)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from globe import assembly
from globe.cli.common import (
    ConfigOption,
    DataOption,
    HouseholdsOption,
    console,
    households_from,
    print_table,
    resolve,
)
from globe.noise.dataset import generate_dataset

NoiseDir = Annotated[Path, typer.Option("--noise-dir", help="where HOMER-Noise is (or will be) written")]


def print_summary(summary: dict) -> None:
    table = Table(title=f"HOMER-Noise (scorer {summary['scorer']}, seed {summary['seed']}, {summary['seconds']} s)")
    for col in ("type", *[f"level {lv:g}" for lv in summary["levels"]], "dropped", "top objects", "top destinations"):
        table.add_column(col)
    for noise_type, e in summary["types"].items():
        table.add_row(noise_type, *[str(e["per_level"][f"{lv:g}"]) for lv in summary["levels"]],
                      str(sum(e["dropped"].values())), ", ".join(list(e["objects"])[:4]),
                      ", ".join(list(e["destinations"])[:4]))
    print_table(table)


def noise(
    noise_dir: NoiseDir = Path("results/homer_noise"),
    data: DataOption = None,
    households: HouseholdsOption = None,
    seed: Annotated[int | None, typer.Option("--seed", help="random seed")] = None,
    types: Annotated[str | None, typer.Option("--types", help="comma-separated: person,pet,toddler")] = None,
    levels: Annotated[str | None, typer.Option(
        "--levels", help="comma-separated noise levels in (0, 1], e.g. 0.25,0.5,1")] = None,
    backend: Annotated[str | None, typer.Option("--backend", help="embedded or none (uniform)")] = None,
    config: ConfigOption = None,
) -> None:
    """Generate HOMER-Noise: every home x noise type x level, with manifests and a summary."""
    cfg = resolve(config, noise__seed=seed, llm__backend=backend,
                  noise__types=tuple(t.strip() for t in types.split(",")) if types else None,
                  noise__levels=tuple(x.strip() for x in levels.split(",")) if levels else None)
    hs = households_from(cfg, data, households)
    with console.status("proposing disturbances") as status:
        summary = generate_dataset(cfg.noise, hs, noise_dir, assembly.noise_scorer(cfg), lambda m: status.update(m))
    print_summary(summary)
    console.print(f"HOMER-Noise in {noise_dir}", markup=False)
