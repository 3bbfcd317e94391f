"""``globe evaluate`` and ``globe reproduce``: Table I rows, timing, records, plots."""

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
from globe.errors import ConfigError
from globe.evaluation.methods import METHODS

OutOption = Annotated[Path, typer.Option("--out", help="results folder to write")]


def _backend(cfg: GlobeConfig, methods: list[str]):
    if not any(METHODS[m].needs_llm for m in methods):
        return None
    return assembly.llm_backend(cfg.llm)


def table1_table(rows: list[dict], labels: dict[str, str]) -> Table:
    """Compact terminal view of Table I: weighted F1 averaged over households, and per household."""
    from globe.evaluation.published import TABLE1

    weighted = [r for r in rows if r["average"] == "weighted"]
    households = [h for h in dict.fromkeys(r["household"] for r in weighted) if h != "mean"]
    table = Table(title="Table I - HOMER+ test days, weighted F1 (mean of households)")
    for col in ["method", "activity", "object", "mean", *[f"{h}: act/obj" for h in households]]:
        table.add_column(col, justify="left" if col == "method" else "right")
    for method in dict.fromkeys(r["method"] for r in weighted):
        get = {r["household"]: r for r in weighted if r["method"] == method}
        m = get["mean"]
        table.add_row(labels.get(method, method), f"{m['activity_f1']:.3f}", f"{m['object_f1']:.3f}", f"{m['mean_f1']:.3f}",
                      *[f"{get[h]['activity_f1']:.3f} / {get[h]['object_f1']:.3f}" for h in households])
    for method, (a, o, mean) in TABLE1.items():
        table.add_row(f"[dim]{method} (published)[/dim]", f"{a:.2f}", f"{o:.2f}", f"{mean:.2f}", *["" for _ in households])
    return table


def timing_table(rows: list[dict]) -> Table:
    from globe.evaluation.published import TABLE2

    table = Table(title="Table II - time for the whole test split (s)")
    for col in ("method", "household", "train", "inference", "LLM calls", "LLM s", "CV s"):
        table.add_column(col, justify="left" if col in ("method", "household") else "right")
    for r in rows:
        table.add_row(r["method"], r["household"], f"{r['train_s']:.3f}", f"{r['inference_s']:.3f}", str(r["llm_calls"]),
                      f"{r['llm_s']:.2f}", f"{r['selection_s']:.2f}" if r["selection_s"] else "")
    for method, (tr, inf) in TABLE2.items():
        table.add_row(f"[dim]{method} (published)[/dim]", "", f"{tr:.2f}", f"{inf:.2f}", "", "", "")
    return table


def run_table1(cfg: GlobeConfig, data: Path | None, households: str | None, methods: list[str], out_dir: Path) -> None:
    from globe.evaluation.experiments import run_methods
    from globe.evaluation.results import write_table1_results

    unknown = [m for m in methods if m not in METHODS]
    if unknown:
        raise ConfigError(f"unknown method {unknown[0]!r}; expected one of {', '.join(METHODS)}")
    hs = households_from(cfg, data, households)
    backend = _backend(cfg, methods)
    started = time.perf_counter()
    with progress_bar(sum(len(h.test) for h in hs) * len(methods), "evaluating") as advance:
        runs = run_methods(cfg, hs, methods, backend, progress=lambda m, n: advance(n, f"evaluating {m}"))
    results = write_table1_results(out_dir, runs, cfg)
    out.print(table1_table(results.rows, results.labels))
    out.print(timing_table(results.timing))
    console.print(f"results in {out_dir} ({time.perf_counter() - started:.1f} s)")


def evaluate(
    out_dir: OutOption = Path("results/evaluate"),
    methods: Annotated[str, typer.Option("--methods", help=f"comma-separated, from: {', '.join(METHODS)}")] = "persistence,ngram",
    data: DataOption = None,
    households: HouseholdsOption = None,
    config: ConfigOption = None,
    threshold: Annotated[float | None, typer.Option("--threshold", help="gate threshold d")] = None,
    backend: Annotated[str | None, typer.Option("--backend", help="embedded, remote or none")] = None,
) -> None:
    """Evaluate chosen methods on the test days and write a results folder."""
    cfg = resolve(config, gate__threshold=threshold, llm__backend=backend)
    run_table1(cfg, data, households, [m.strip() for m in methods.split(",") if m.strip()], out_dir)


def reproduce(
    out_dir: OutOption = Path("results/reproduce"),
    data: DataOption = None,
    config: ConfigOption = None,
    backend: Annotated[str | None, typer.Option("--backend", help="embedded, remote or none")] = None,
    robustness: Annotated[bool, typer.Option("--robustness/--no-robustness", help="also generate HOMER-Noise and run the robustness suite")] = True,
) -> None:
    """Run every experiment available on the shipped HOMER+ and write the results folder."""
    cfg = resolve(config, llm__backend=backend)
    run_table1(cfg, data, None, list(cfg.evaluation.methods), out_dir)
    if robustness:
        from globe.cli.noise_cmd import run_robustness

        run_robustness(cfg, households_from(cfg, data, None), out_dir / "homer_noise", out_dir / "robustness")
