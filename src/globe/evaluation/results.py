"""Write a Table I results folder from method runs (CSV, Markdown, records, plots, config)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

from globe.config import GlobeConfig
from globe.evaluation import experiments, report
from globe.evaluation.experiments import MethodRun
from globe.evaluation.methods import METHODS
from globe.evaluation.plots import reliability_figure, table1_figure
from globe.evaluation.plots_anticipation import save_figure
from globe.evaluation.published import DataScope


@dataclass(frozen=True, slots=True)
class Table1Results:
    rows: list[dict]
    timing: list[dict]
    labels: dict[str, str]
    scope: DataScope


def write_table1_results(out_dir: Path, runs: Sequence[MethodRun], config: GlobeConfig,
                         scope: DataScope, activities: str = "annotated") -> Table1Results:
    """Everything a reader needs to trace each number back to the predictions behind it
    (``data.json`` also says which ``activities`` the models were shown on the test days:
    annotated, or recognised from sensors)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    report.write_json(out_dir / "config.json", config.model_dump(mode="json"))
    report.write_json(out_dir / "data.json", {**scope.as_dict(), "activities": activities})
    built: dict[str, dict] = {}
    for run in runs:
        built.setdefault(run.method, {})[run.household] = run.built
    report.write_json(out_dir / "built.json", built)
    labels = {name: m.shown for name, m in METHODS.items()}  # a baseline says so
    rows = experiments.table1_rows(runs)
    report.write_csv(out_dir / "table1.csv", rows)
    details = experiments.detail_rows(runs)
    report.write_csv(out_dir / "details.csv", details)
    timing = experiments.timing_rows(runs)
    report.write_csv(out_dir / "timing.csv", timing)
    report.write_csv(out_dir / "selection.csv", experiments.selection_rows(runs),
                     ["method", "household", "part", "params", "criterion", "cv_log_loss", "cv_weighted_f1", "chosen",
                      "at_edge"])
    calib, curves = experiments.calibration_rows(runs, config.evaluation.calibration_bins)
    report.write_csv(out_dir / "calibration.csv", calib)
    for part, per_method in curves.items():
        save_figure(reliability_figure(per_method, f"Reliability of {part} probabilities"),
                    out_dir / f"reliability_{part}.png", dpi=120)
    for run in runs:
        stem = f"{run.method}_{run.household}"
        report.write_records(out_dir / "records", f"{stem}_activity", run.evaluation.activity)
        report.write_records(out_dir / "records", f"{stem}_objects", run.evaluation.objects)
        report.write_records(out_dir / "records", f"{stem}_objects_oracle", run.oracle.objects)
    # the paper's names for HOMER+ (its tables stand beside the paper's); plain ones for a home of one's own
    scores, times = (f"# Table I ({scope.title})", "# Table II (timing)") if scope.homer_plus else (
        f"# Scores on the test days ({scope.title})", "# Time for the whole test split")
    md = "\n".join([
        scores, "", report.table1_markdown(rows, labels, "weighted", scope),
        report.table1_markdown(rows, labels, "micro", scope), report.table1_markdown(rows, labels, "macro", scope),
        times, "", report.timing_markdown(timing, scope),
        "# Details", "", report.details_markdown(details),
        "# Calibration (expected calibration error)", "", report.rows_markdown(calib),
    ])
    (out_dir / "table1.md").write_text(md, encoding="utf-8")
    save_figure(table1_figure(rows, labels, scope), out_dir / "table1.png")
    return Table1Results(rows, timing, labels, scope)
