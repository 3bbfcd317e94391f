"""``globe noise`` (generate HOMER-Noise) and ``globe robustness`` (the robustness suite)."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from globe.cli.common import (
    ConfigOption,
    DataOption,
    HouseholdsOption,
    console,
    households_from,
    out,
    progress_bar,
    resolve,
)
from globe import assembly
from globe.config import GlobeConfig
from globe.data.records import Household

NoiseDir = Annotated[Path, typer.Option("--noise-dir", help="where HOMER-Noise is (or will be) written")]


def generate(cfg: GlobeConfig, households: list[Household], noise_dir: Path) -> dict:
    """Propose at level 1.0 once per (home, type), then write every level (nested subsets)."""
    from globe.noise import dataset
    from globe.noise.generate import propose

    scorer = assembly.noise_scorer(cfg)
    n = cfg.noise
    proposals = {}
    started = time.perf_counter()
    total = len(households) * len(n.types) * max(len(h.train) + len(h.test) for h in households)
    with progress_bar(total, "proposing disturbances") as advance:
        for noise_type in n.types:
            for h in households:
                advance(0, f"proposing {noise_type} disturbances in {h.name}")
                proposals[(h.name, noise_type)] = propose(h, noise_type, scorer, seed=n.seed, rate=n.rate,
                                                          temperature=n.temperature, progress=advance)
    for noise_type in n.types:
        for level in n.levels:
            dataset.write_level(noise_dir, households, proposals, noise_type, level)
    summary = dataset.summary(proposals, n.levels)
    summary |= {"seed": n.seed, "rate": n.rate, "temperature": n.temperature, "scorer": scorer.name,
                "seconds": round(time.perf_counter() - started, 2)}
    dataset.write_summary(noise_dir, summary)
    return summary


def print_summary(summary: dict) -> None:
    table = Table(title=f"HOMER-Noise (scorer {summary['scorer']}, seed {summary['seed']}, {summary['seconds']} s)")
    for col in ("type", *[f"level {lv:g}" for lv in summary["levels"]], "dropped", "top objects", "top destinations"):
        table.add_column(col)
    for noise_type, e in summary["types"].items():
        table.add_row(noise_type, *[str(e["per_level"][f"{lv:g}"]) for lv in summary["levels"]],
                      str(sum(e["dropped"].values())), ", ".join(list(e["objects"])[:4]), ", ".join(list(e["destinations"])[:4]))
    out.print(table)


def noise(
    noise_dir: NoiseDir = Path("results/homer_noise"),
    data: DataOption = None,
    households: HouseholdsOption = None,
    seed: Annotated[int | None, typer.Option("--seed", help="random seed")] = None,
    types: Annotated[str | None, typer.Option("--types", help="comma-separated: person,pet,toddler")] = None,
    levels: Annotated[str | None, typer.Option("--levels", help="comma-separated noise levels, e.g. 0.25,0.5,1")] = None,
    backend: Annotated[str | None, typer.Option("--backend", help="embedded or none (uniform)")] = None,
    config: ConfigOption = None,
) -> None:
    """Generate HOMER-Noise: every home x noise type x level, with manifests and a summary."""
    cfg = resolve(config, noise__seed=seed, llm__backend=backend,
                  noise__types=tuple(t.strip() for t in types.split(",")) if types else None,
                  noise__levels=tuple(float(x) for x in levels.split(",")) if levels else None)
    summary = generate(cfg, households_from(cfg, data, households), noise_dir)
    print_summary(summary)
    console.print(f"HOMER-Noise in {noise_dir}")


def run_robustness(cfg: GlobeConfig, households: list[Household], noise_dir: Path, out_dir: Path) -> None:
    from globe.evaluation.robustness import run_suite, write_robustness_results

    if not (noise_dir / "summary.json").is_file():
        print_summary(generate(cfg, households, noise_dir))
    backend = assembly.llm_backend(cfg.llm)
    with console.status("robustness suite") as status:
        res = run_suite(cfg, households, noise_dir, backend, progress=lambda s: status.update(f"robustness suite: {s}"))
    write_robustness_results(out_dir, res)
    table = Table(title="Robustness: object F1, all events / routine events only (mean of households)")
    for col in ("dataset", "method", "activity F1", "object F1 all", "object F1 routine", "injected"):
        table.add_column(col)
    for r in res.robustness:
        table.add_row(r["dataset"], r["method"], f"{r['activity_f1']:.3f}", f"{r['object_f1']:.3f}",
                      f"{r['object_f1_routine']:.3f}", str(r["injected_events"]))
    out.print(table)


def robustness(
    out_dir: Annotated[Path, typer.Option("--out", help="results folder")] = Path("results/robustness"),
    noise_dir: NoiseDir = Path("results/homer_noise"),
    data: DataOption = None,
    backend: Annotated[str | None, typer.Option("--backend", help="embedded or none")] = None,
    config: ConfigOption = None,
) -> None:
    """Robustness suite: noise types, behavioural consistency, ablations (generates noise if needed)."""
    cfg = resolve(config, llm__backend=backend)
    run_robustness(cfg, households_from(cfg, data, None), noise_dir, out_dir)
