"""Write the robustness suite's results folder: CSV and Markdown tables and PNG plots."""

from __future__ import annotations

from pathlib import Path

from globe.config import NoiseConfig
from globe.evaluation import report
from globe.evaluation.plots import consistency_figure, grouped_line_figure, robustness_figure
from globe.evaluation.published import TABLE1, DataScope
from globe.evaluation.robustness import RobustnessResults


def write_robustness_results(out_dir: Path, res: RobustnessResults, noise: NoiseConfig, scope: DataScope) -> None:
    """CSV tables, Markdown and PNG plots of the robustness suite (``noise`` names its levels);
    SLaTe-PRO's published clean figure stands beside HOMER+ only."""
    levels = f"trained at noise level {noise.train_level:g}, tested at {noise.test_level:g}"
    out_dir.mkdir(parents=True, exist_ok=True)
    report.write_csv(out_dir / "robustness.csv", res.robustness)
    report.write_csv(out_dir / "consistency.csv", res.consistency)
    report.write_csv(out_dir / "ablation_train_level.csv", res.train_level)
    report.write_csv(out_dir / "ablation_threshold.csv", res.threshold)
    published = {"SLaTe-PRO": TABLE1["slate_pro"][1]} if scope.homer_plus else None
    robustness_figure(res.robustness, f"{scope.title}, test data (noisy: {levels})", published).savefig(
        out_dir / "robustness.png", dpi=130)
    for method in dict.fromkeys(r["method"] for r in res.consistency):
        for definition in dict.fromkeys(r["definition"] for r in res.consistency):
            consistency_figure(res.consistency, method, definition).savefig(
                out_dir / f"consistency_{method}_{definition}.png", dpi=130)
    if res.train_level:
        grouped_line_figure([r | {"series": f"{r['dataset']} ({r['method']})"} for r in res.train_level], "train_level", "series",
                            "object_f1", f"Training noise level (tested at {noise.test_level:g})", "training noise level",
                            "object F1 (weighted)").savefig(out_dir / "ablation_train_level.png", dpi=130)
    if res.threshold:
        grouped_line_figure(res.threshold, "threshold", "dataset", "object_f1", "Gate threshold d",
                            "threshold d", "object F1 (weighted)").savefig(out_dir / "ablation_threshold.png", dpi=130)
    note = (f"Published SLaTe-PRO on clean HOMER+: object F1 {TABLE1['slate_pro'][1]:.2f} (its per-noise values are "
            "only shown graphically in the paper)." if scope.homer_plus else "")
    md = "\n".join([f"# Robustness: {scope.title} ({levels})", "", report.rows_markdown(res.robustness), note, "",
                    "# Behavioural consistency", "", report.rows_markdown(res.consistency),
                    "# Ablation: training noise level", "", report.rows_markdown(res.train_level),
                    "# Ablation: threshold d", "", report.rows_markdown(res.threshold)])
    (out_dir / "robustness.md").write_text(md, encoding="utf-8")
