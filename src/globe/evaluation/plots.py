"""Plots as matplotlib Figures (Agg backend); callers save them. Never ``plt.show()``."""

from __future__ import annotations

from typing import Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from globe.evaluation.published import TABLE1, DataScope  # noqa: E402


def table1_figure(rows: Sequence[dict], labels: dict[str, str], scope: DataScope) -> Figure:
    """Mean-over-households weighted F1 per method, with the paper's published values marked on
    HOMER+ (and only there)."""
    mine = [r for r in rows if r["household"] == "mean" and r["average"] == "weighted"]
    methods = [r["method"] for r in mine]
    fig, ax = plt.subplots(figsize=(max(6.0, 1.6 * len(methods) + 2), 4.2))
    width = 0.26
    metrics = [("activity_f1", "activity F1", 0), ("object_f1", "object F1", 1), ("mean_f1", "mean F1", 2)]
    for key, name, k in metrics:
        xs = [i + (k - 1) * width for i in range(len(methods))]
        values = [float("nan") if r[key] is None else float(r[key]) for r in mine]  # absent: no bar
        ax.bar(xs, values, width, label=f"ours: {name}")
        for x, v in zip(xs, values):
            ax.text(x, (0.0 if v != v else v) + 0.01, "–" if v != v else f"{v:.2f}", ha="center", fontsize=7)
        pub = [(x, TABLE1[m][k]) for x, m in zip(xs, methods) if m in TABLE1 and scope.homer_plus]
        if pub:
            ax.scatter([p[0] for p in pub], [p[1] for p in pub], marker="_", s=300, color="black", zorder=3,
                       label="published (paper)" if k == 0 else None)
    ax.set_xticks(range(len(methods)), [labels.get(m, m) for m in methods], rotation=15, ha="right", fontsize=8)
    ax.set_ylabel(f"weighted F1 (mean of {', '.join(scope.households)})")
    ax.set_ylim(0, 1.05)
    ax.set_title(f"{scope.title} test days: next activity and next object")
    ax.legend(fontsize=7, loc="upper right", ncols=2)
    fig.tight_layout()
    return fig


def reliability_figure(curves: dict[str, tuple[list[float], list[float], list[int]]], title: str) -> Figure:
    """Reliability diagram: mean confidence vs accuracy per bin, one line per method."""
    fig, ax = plt.subplots(figsize=(5, 4.5))
    ax.plot([0, 1], [0, 1], ls="--", color="grey", label="perfectly calibrated")
    for name, (conf, acc, _counts) in curves.items():
        ax.plot(conf, acc, marker="o", label=name)
    ax.set_xlabel("predicted probability (confidence)")
    ax.set_ylabel("observed accuracy")
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1)
    ax.set_title(title)
    ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


def robustness_figure(rows: Sequence[dict], xlabel: str, published_clean: dict[str, float] | None = None) -> Figure:
    """Object F1 per dataset (clean, person, pet, toddler) and method: all events (solid) and
    routine events only (hatched)."""
    datasets = list(dict.fromkeys(r["dataset"] for r in rows))
    methods = list(dict.fromkeys(r["method"] for r in rows))
    fig, ax = plt.subplots(figsize=(8, 4.2))
    width = 0.8 / (2 * len(methods))
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for k, method in enumerate(methods):
        get = {r["dataset"]: r for r in rows if r["method"] == method}
        xs = [i + (2 * k) * width - 0.4 + width / 2 for i in range(len(datasets))]
        ax.bar(xs, [get[d]["object_f1"] for d in datasets], width, color=colors[k % len(colors)], label=f"{method}: all events")
        ax.bar([x + width for x in xs], [get[d]["object_f1_routine"] for d in datasets], width, color=colors[k % len(colors)],
               alpha=0.45, hatch="//", label=f"{method}: routine events only")
    if published_clean:
        for name, value in published_clean.items():
            ax.axhline(value, ls="--", lw=1, color="black")
            ax.text(len(datasets) - 0.5, value + 0.01, f"{name} clean (published) {value:.2f}", ha="right", fontsize=7)
    ax.set_xticks(range(len(datasets)), datasets)
    ax.set_ylabel("object F1 (weighted, mean of A, B, C)")
    ax.set_xlabel(xlabel)
    ax.set_ylim(0, 1)
    ax.set_title("Robustness to person / pet / toddler disturbances")
    ax.legend(fontsize=7, ncols=2, loc="lower left")
    fig.tight_layout()
    return fig


def grouped_line_figure(rows: Sequence[dict], x: str, series: str, y: str, title: str, xlabel: str, ylabel: str) -> Figure:
    """One line per ``series`` value, ``y`` against ``x``."""
    fig, ax = plt.subplots(figsize=(6, 4))
    for name in dict.fromkeys(r[series] for r in rows):
        pts = sorted((r[x], r[y]) for r in rows if r[series] == name and r[y] is not None)
        ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o", label=str(name))
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def consistency_figure(rows: Sequence[dict], method: str, definition: str) -> Figure:
    """Object F1 under more / moderate / less consistent behaviour, per dataset."""
    mine = [r for r in rows if r["method"] == method and r["definition"] == definition]
    datasets = list(dict.fromkeys(r["dataset"] for r in mine))
    groups = ("more", "moderate", "less")
    fig, ax = plt.subplots(figsize=(7, 4))
    width = 0.8 / len(groups)
    for k, g in enumerate(groups):
        vals = [next((r["object_f1"] or 0 for r in mine if r["dataset"] == d and r["consistency"] == g), 0) for d in datasets]
        ax.bar([i + (k - 1) * width for i in range(len(datasets))], vals, width, label=f"{g}{'ly' if g == 'moderate' else ''} consistent")
    ax.set_xticks(range(len(datasets)), datasets)
    ax.set_ylabel("object F1 (weighted)")
    ax.set_ylim(0, 1)
    ax.set_title(f"Behavioural consistency ({method}): activities by {definition.replace('_', ' ')}")
    ax.legend(fontsize=7)
    fig.tight_layout()
    return fig
