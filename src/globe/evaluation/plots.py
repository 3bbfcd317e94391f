"""Plots as matplotlib Figures (Agg backend); callers save them. Never ``plt.show()``."""

from __future__ import annotations

from typing import Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from globe.evaluation.published import TABLE1  # noqa: E402


def table1_figure(rows: Sequence[dict], labels: dict[str, str]) -> Figure:
    """Mean-over-households weighted F1 per method, with the paper's published values marked."""
    mine = [r for r in rows if r["household"] == "mean" and r["average"] == "weighted"]
    methods = [r["method"] for r in mine]
    fig, ax = plt.subplots(figsize=(max(6.0, 1.6 * len(methods) + 2), 4.2))
    width = 0.26
    metrics = [("activity_f1", "activity F1", 0), ("object_f1", "object F1", 1), ("mean_f1", "mean F1", 2)]
    for key, name, k in metrics:
        xs = [i + (k - 1) * width for i in range(len(methods))]
        bars = ax.bar(xs, [float(r[key]) for r in mine], width, label=f"ours: {name}")
        for x, r in zip(xs, mine):
            ax.text(x, float(r[key]) + 0.01, f"{float(r[key]):.2f}", ha="center", fontsize=7)
        pub = [(x, TABLE1[m][k]) for x, m in zip(xs, methods) if m in TABLE1]
        if pub:
            ax.scatter([p[0] for p in pub], [p[1] for p in pub], marker="_", s=300, color="black", zorder=3,
                       label="published (paper)" if k == 0 else None)
        del bars
    ax.set_xticks(range(len(methods)), [labels.get(m, m) for m in methods], rotation=15, ha="right", fontsize=8)
    ax.set_ylabel("weighted F1 (mean of households A, B, C)")
    ax.set_ylim(0, 1.05)
    ax.set_title("HOMER+ test days: next activity and next object")
    ax.legend(fontsize=7, loc="upper right", ncols=2)
    fig.tight_layout()
    return fig


def reliability_figure(curves: dict[str, tuple[list[float], list[float], list[int]]], title: str) -> Figure:
    """Reliability diagram: mean confidence vs accuracy per bin, one line per method."""
    fig, ax = plt.subplots(figsize=(5, 4.5))
    ax.plot([0, 1], [0, 1], ls="--", color="grey", label="perfectly calibrated")
    for name, (conf, acc, counts) in curves.items():
        ax.plot(conf, acc, marker="o", label=name)
    ax.set_xlabel("predicted probability (confidence)")
    ax.set_ylabel("observed accuracy")
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1)
    ax.set_title(title)
    ax.legend(fontsize=7)
    fig.tight_layout()
    return fig
