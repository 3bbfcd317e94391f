"""The missing-label plot: F1 against the share of visible activity labels (Agg backend)."""

from __future__ import annotations

from typing import Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

SERIES = (("activity_f1", "activity F1 (one step)"), ("object_f1", "object F1 (one step)"),
          ("lookahead_f1_mean", "lookahead F1 (mean of 10-60 min)"))


def missing_labels_figure(rows: Sequence[dict]) -> Figure:
    """Mean over households (thick) and each household (thin) of every F1 in ``rows``."""
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    households = [h for h in dict.fromkeys(r["household"] for r in rows) if h != "mean"]
    for k, (key, label) in enumerate(SERIES):
        colour = f"C{k}"
        for h in households:
            pts = sorted((r["labels_pct"], r[key]) for r in rows if r["household"] == h and r.get(key) is not None)
            if pts:
                ax.plot(*zip(*pts), color=colour, alpha=0.3, linewidth=1)
        pts = sorted((r["labels_pct"], r[key]) for r in rows if r["household"] == "mean" and r.get(key) is not None)
        if pts:
            ax.plot(*zip(*pts), color=colour, marker="o", linewidth=2, label=label)
            for x, y in pts:
                ax.annotate(f"{y:.2f}", (x, y), textcoords="offset points", xytext=(0, 6), ha="center", fontsize=7)
    ax.set_xlabel("activity labels visible (% of history steps)")
    ax.set_ylabel("F1")
    ax.set_ylim(0, 1)
    ax.set_title("Missing activity labels: the activity filter (thin lines: households)")
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    return fig
