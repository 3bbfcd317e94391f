"""Plots of the anticipation results (lookahead F1, fetch precision-recall, lead times); Agg
backend, callers save the figures."""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from globe.evaluation.published import DataScope  # noqa: E402

# SLaTe-PRO's published object-usage F1 on HOMER+ (its own relocation metric, 10-60 minutes ahead)
SLATE_PRO_OBJECT_F1 = {"without user queries": 0.57, "with user queries": 0.60}


def save_figure(fig: Figure, path: Path, dpi: int = 130) -> None:
    """Save and close (a results run draws many figures; open ones keep their memory)."""
    fig.savefig(path, dpi=dpi)
    plt.close(fig)


def lookahead_figure(rows: Sequence[dict], scope: DataScope) -> Figure:
    """Relocation F1 against the horizon per method (mean of the households, each household
    thin), with SLaTe-PRO's published object-usage F1 marked and labelled as published on HOMER+."""
    fig, ax = plt.subplots(figsize=(7.0, 4.2))
    methods = list(dict.fromkeys(r["method"] for r in rows))
    for i, method in enumerate(methods):
        color = f"C{i}"
        mean = [r for r in rows if r["method"] == method and r["household"] == "mean"]
        ax.plot([r["horizon_min"] for r in mean], [r["f1"] for r in mean], marker="o", color=color, label=f"ours: {method}")
        for hh in dict.fromkeys(r["household"] for r in rows if r["method"] == method and r["household"] != "mean"):
            mine = [r for r in rows if r["method"] == method and r["household"] == hh]
            ax.plot([r["horizon_min"] for r in mine], [r["f1"] for r in mine], color=color, alpha=0.25, linewidth=0.8)
    for (label, value), style in zip(SLATE_PRO_OBJECT_F1.items() if scope.homer_plus else (), ("--", ":")):
        ax.axhline(value, color="black", linestyle=style, linewidth=1, label=f"SLaTe-PRO, published: {label} ({value:.2f})")
    ax.set_xlabel("horizon (minutes ahead)")
    ax.set_ylabel(f"relocation F1 (mean of {', '.join(scope.households)}; thin: each home)")
    ax.set_ylim(0, 1)
    horizons = sorted({r["horizon_min"] for r in rows}) or [0]
    ax.set_title(f"{scope.title} test days: where objects will be, {horizons[0]}-{horizons[-1]} minutes ahead")
    ax.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    return fig


def fetch_curve_figure(rows: Sequence[dict], target: tuple[float, float] = (0.40, 0.80)) -> Figure:
    """Fetch precision against recall over the policy's cost ratio, per household and pooled; the
    configured costs are circled and the target region is shaded."""
    fig, ax = plt.subplots(figsize=(6.0, 4.6))
    for i, hh in enumerate(dict.fromkeys(r["household"] for r in rows)):
        mine = sorted((r for r in rows if r["household"] == hh), key=lambda r: r["threshold"])
        ax.plot([r["recall"] for r in mine], [r["precision"] for r in mine], marker=".", color=f"C{i}",
                linewidth=2 if hh == "all" else 1, label=f"household {hh}" if hh != "all" else "all households")
        for r in mine:
            if r["configured"]:
                ax.scatter([r["recall"]], [r["precision"]], s=90, facecolors="none", edgecolors=f"C{i}", zorder=3)
    ax.axvspan(target[0], 1.0, ymin=target[1], ymax=1.0, color="green", alpha=0.08, label="target: P >= 0.80 at R >= 0.40")
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1)
    ax.set_xlabel("recall (uses fetched in advance)")
    ax.set_ylabel("precision (fetches used in the window)")
    ax.set_title("Fetch policy over the cost ratio (circled: configured costs)")
    ax.legend(fontsize=7, loc="lower left")
    fig.tight_layout()
    return fig


def lead_time_figure(rows: Sequence[dict]) -> Figure:
    """How long before each use the configured policy had fetched the object, per household."""
    fig, ax = plt.subplots(figsize=(6.0, 3.8))
    households = list(dict.fromkeys(r["household"] for r in rows))
    leads = sorted({r["lead_min"] for r in rows})
    width = 0.8 / max(len(households), 1)
    for i, hh in enumerate(households):
        counts = {r["lead_min"]: r["uses"] for r in rows if r["household"] == hh}
        ax.bar([k + (i - (len(households) - 1) / 2) * width for k in range(len(leads))], [counts.get(x, 0) for x in leads],
               width, label=f"household {hh}")
    ax.set_xticks(range(len(leads)), [str(x) for x in leads])
    ax.set_xlabel("lead time (minutes between the fetch and the use)")
    ax.set_ylabel("uses fetched in advance")
    ax.set_title("Lead times of the configured fetch policy")
    ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


def activity_horizon_figure(rows: Sequence[dict], title: str) -> Figure:
    """Accuracy and log loss of the activity 10-60 minutes ahead per method, one column per
    household (``rows``: ``activity_anticipation.csv``)."""
    homes = list(dict.fromkeys(r["household"] for r in rows))
    fig, axes = plt.subplots(2, max(len(homes), 1), figsize=(3.6 * max(len(homes), 1), 5.6), squeeze=False)
    for col, hh in enumerate(homes):
        mine = [r for r in rows if r["household"] == hh]
        for i, method in enumerate(dict.fromkeys(r["method"] for r in mine)):
            line = [r for r in mine if r["method"] == method]
            x = [r["horizon_min"] for r in line]
            axes[0][col].plot(x, [r["accuracy"] for r in line], marker="o", color=f"C{i}", label=method)
            axes[1][col].plot(x, [r["log_loss"] for r in line], marker="o", color=f"C{i}", label=method)
        axes[0][col].set_title(f"home {hh}", fontsize=9)
        axes[0][col].set_ylim(0, 1)
        axes[1][col].set_yscale("log")
        axes[1][col].set_xlabel("minutes ahead")
    axes[0][0].set_ylabel("accuracy")
    axes[1][0].set_ylabel("log loss (nats, log scale)")
    axes[0][0].legend(fontsize=7)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return fig
