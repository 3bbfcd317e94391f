"""Plots as matplotlib Figures (Agg backend); callers save them. Never ``plt.show()``."""

from __future__ import annotations

from typing import Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.axes import Axes  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.text import Annotation  # noqa: E402

from globe.evaluation.published import HOMER_PLUS_DAYS, TABLE1, TABLE1_MEAN_ONLY, DataScope  # noqa: E402

PUBLISHED_GID = "published"
"""``gid`` of the published marks in :func:`table1_figure` (the tests find them by it)."""
VALUE_GID = "value"
"""``gid`` of the value labels above the bars of :func:`table1_figure`."""


def published_comparable(scope: DataScope) -> bool:
    """Whether the paper's figures (means over HOMER+'s three households) may be marked beside a
    mean of ours: on HOMER+ and over all three households, never beside one home."""
    return scope.homer_plus and len(set(scope.households)) == len(HOMER_PLUS_DAYS)


def table1_figure(rows: Sequence[dict], labels: dict[str, str], scope: DataScope) -> Figure:
    """Weighted F1 per method (mean over the households, or the one household), with the paper's
    published values marked beside a mean over HOMER+'s three households (and only there). The
    legend sits below the axes, clear of every bar, and a value label that a published mark
    would cross is lifted above the mark."""
    mine = [r for r in rows if r["household"] == "mean" and r["average"] == "weighted"]
    methods = [r["method"] for r in mine]
    fig, ax = plt.subplots(figsize=(max(6.0, 1.6 * len(methods) + 2), 4.6), layout="constrained")
    width = 0.26
    metrics = [("activity_f1", "activity F1", 0), ("object_f1", "object F1", 1), ("mean_f1", "mean F1", 2)]
    show_published = published_comparable(scope)
    marks: list[tuple[Annotation, float, float]] = []  # (value label, bar centre, published value)
    for key, name, k in metrics:
        xs = [i + (k - 1) * width for i in range(len(methods))]
        values = [float("nan") if r[key] is None else float(r[key]) for r in mine]  # absent: no bar
        ax.bar(xs, values, width, label=f"ours: {name}")
        for x, v, method in zip(xs, values, methods):
            text = ax.annotate("–" if v != v else f"{v:.2f}", (x, 0.0 if v != v else v), xytext=(0, 2),
                               textcoords="offset points", ha="center", va="bottom", fontsize=7, gid=VALUE_GID)
            text.set_in_layout(False)
            published = _published_value(method, k) if show_published else None
            if published is not None:
                marks.append((text, x, published))
    if marks:
        ax.hlines([p for _, _, p in marks], [x - width / 2 for _, x, _ in marks], [x + width / 2 for _, x, _ in marks],
                  colors="black", linewidth=1.5, zorder=3, gid=PUBLISHED_GID,
                  label="published (paper, mean of HOMER+'s three households)")
    ax.set_xticks(range(len(methods)), [labels.get(m, m) for m in methods], rotation=15, ha="right", fontsize=8)
    one = len(scope.households) == 1
    ax.set_ylabel(f"weighted F1 ({'household ' if one else 'mean of '}{', '.join(scope.households)})")
    ax.set_ylim(0, 1.12)
    ax.set_title(f"{scope.title} test days: next activity and next object")
    fig.legend(fontsize=7, loc="outside lower center", ncols=4)
    if marks:
        _lift_crossed_labels(fig, ax, marks)
    return fig


def _published_value(method: str, k: int) -> float | None:
    """The paper's figure for ``method`` and metric ``k`` (activity, object, mean), if it has one."""
    if method in TABLE1:
        return TABLE1[method][k]
    return TABLE1_MEAN_ONLY.get(method) if k == 2 else None


def _lift_crossed_labels(fig: Figure, ax: Axes, marks: list[tuple[Annotation, float, float]]) -> None:
    """Move each value label that its bar's published mark would strike through to just above
    the mark (the layout is drawn first, so the label's real extent is known)."""
    fig.canvas.draw()
    clearance = 2.0 * fig.dpi / 72  # points of the mark's half width and a gap, in pixels
    for text, x, published in marks:
        box = text.get_window_extent()
        y = ax.transData.transform((x, published))[1]
        if box.y0 - clearance <= y <= box.y1 + clearance:
            text.xy = (x, published)
            text.set_position((0, 3))


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
        color = colors[k % len(colors)]
        ax.bar(xs, [get[d]["object_f1"] for d in datasets], width, color=color, label=f"{method}: all events")
        ax.bar([x + width for x in xs], [get[d]["object_f1_routine"] for d in datasets], width, color=color,
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


def grouped_line_figure(rows: Sequence[dict], x: str, series: str, y: str, title: str, xlabel: str,
                        ylabel: str) -> Figure:
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
        vals = [next((r["object_f1"] or 0 for r in mine if r["dataset"] == d and r["consistency"] == g), 0)
                for d in datasets]
        ax.bar([i + (k - 1) * width for i in range(len(datasets))], vals, width,
               label=f"{g}{'ly' if g == 'moderate' else ''} consistent")
    ax.set_xticks(range(len(datasets)), datasets)
    ax.set_ylabel("object F1 (weighted)")
    ax.set_ylim(0, 1)
    ax.set_title(f"Behavioural consistency ({method}): activities by {definition.replace('_', ' ')}")
    ax.legend(fontsize=7)
    fig.tight_layout()
    return fig
