"""The learning-curve figure (Agg backend; the caller saves it)."""

from __future__ import annotations

from typing import Any, Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

PANELS = (("activity_f1", "activity F1 (weighted)"), ("object_f1", "object F1 (weighted)"),
          ("fetch_precision", "fetch precision"), ("fetch_recall", "fetch recall"))


def learning_curve_figure(rows: Sequence[dict[str, Any]], title: str = "Learning through the service: test days") -> Figure:
    """One panel per metric against the number of learned days (log axis: the early days are
    where learning shows); a thin line per household, a thick one for the ``mean`` rows."""
    fig, axes = plt.subplots(2, 2, figsize=(9.0, 6.4), sharex=True)
    households = list(dict.fromkeys(str(r["household"]) for r in rows))
    for ax, (key, label) in zip(axes.flat, PANELS):
        for name in households:
            pts = sorted((int(r["days_learned"]), float(r[key])) for r in rows
                         if str(r["household"]) == name and r[key] not in (None, ""))
            mean = name == "mean"
            ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o", markersize=4 if mean else 3,
                    linewidth=2.4 if mean else 1.0, color="black" if mean else None, alpha=1.0 if mean else 0.75,
                    label=name if mean else f"household {name}")
        ax.set_xscale("log")
        days = sorted({int(r["days_learned"]) for r in rows})
        ax.set_xticks(days, [str(d) for d in days])
        ax.minorticks_off()
        ax.set_ylim(0, 1)
        ax.set_title(label, fontsize=10)
        ax.grid(alpha=0.3)
    for ax in axes[1]:
        ax.set_xlabel("training days learned (streamed as observations)")
    axes[0][0].legend(fontsize=8, loc="lower right")
    fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    return fig
