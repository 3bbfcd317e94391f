"""Plots of the anticipation results (lookahead F1, fetch precision-recall, lead times); Agg
backend, callers save the figures."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.axes import Axes  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.ticker import FixedLocator, FuncFormatter, NullFormatter  # noqa: E402

from globe.evaluation.published import DataScope  # noqa: E402
from globe.models.baselines import HOUR_ACTIVITY, ORACLE, ORACLE_LABEL  # noqa: E402

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
        baseline = method in ("persistence", HOUR_ACTIVITY)
        label = ORACLE_LABEL if method == ORACLE else f"baseline: {method}" if baseline else f"ours: {method}"
        ax.plot([r["horizon_min"] for r in mean], [r["f1"] for r in mean], marker="o", color=color,
                linestyle=":" if method == ORACLE else "--" if baseline else "-", label=label)
        for hh in dict.fromkeys(r["household"] for r in rows if r["method"] == method and r["household"] != "mean"):
            mine = [r for r in rows if r["method"] == method and r["household"] == hh]
            ax.plot([r["horizon_min"] for r in mine], [r["f1"] for r in mine], color=color, alpha=0.25, linewidth=0.8)
    for (label, value), style in zip(SLATE_PRO_OBJECT_F1.items() if scope.homer_plus else (), ("--", ":")):
        ax.axhline(value, color="black", linestyle=style, linewidth=1,
                   label=f"SLaTe-PRO, published: {label} ({value:.2f})")
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
    configured costs are circled and the target region is shaded. A baseline's rows (``method``
    :data:`~globe.models.baselines.HOUR_ACTIVITY`) are drawn pooled only, dashed and named as the
    baseline; the oracle's (:data:`~globe.models.baselines.ORACLE`) pooled only, dotted, named as such."""
    fig, ax = plt.subplots(figsize=(6.0, 4.6))
    policy = [r for r in rows if r.get("method") not in (HOUR_ACTIVITY, ORACLE)]
    for i, hh in enumerate(dict.fromkeys(r["household"] for r in policy)):
        mine = sorted((r for r in policy if r["household"] == hh), key=lambda r: r["threshold"])
        ax.plot([r["recall"] for r in mine], [r["precision"] for r in mine], marker=".", color=f"C{i}",
                linewidth=2 if hh == "all" else 1, label=f"household {hh}" if hh != "all" else "all households")
        for r in mine:
            if r["configured"]:
                ax.scatter([r["recall"]], [r["precision"]], s=90, facecolors="none", edgecolors=f"C{i}", zorder=3)
    for method, color, style, name in ((HOUR_ACTIVITY, "grey", "--", "baseline: hour + activity"),
                                       (ORACLE, "black", ":", ORACLE_LABEL)):
        pooled = sorted((r for r in rows if r.get("method") == method and r["household"] == "all"),
                        key=lambda r: r["threshold"])
        if pooled:
            ax.plot([r["recall"] for r in pooled], [r["precision"] for r in pooled], marker=".", color=color,
                    linestyle=style, linewidth=1.5, label=f"{name} (all households)")
        for r in pooled:
            if r["configured"]:
                ax.scatter([r["recall"]], [r["precision"]], s=90, facecolors="none", edgecolors=color, zorder=3)
    ax.axvspan(target[0], 1.0, ymin=target[1], ymax=1.0, color="green", alpha=0.08,
               label="target: P >= 0.80 at R >= 0.40")
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
        offset = (i - (len(households) - 1) / 2) * width
        ax.bar([k + offset for k in range(len(leads))], [counts.get(x, 0) for x in leads],
               width, label=f"household {hh}")
    ax.set_xticks(range(len(leads)), [str(x) for x in leads])
    ax.set_xlabel("lead time (minutes between the fetch and the use)")
    ax.set_ylabel("uses fetched in advance")
    ax.set_title("Lead times of the configured fetch policy")
    ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


LINE_STYLES = (("o", "-"), ("s", "--"), ("^", ":"), ("D", "-."), ("v", (0, (5, 1, 1, 1))), ("P", (0, (1, 1))))
"""(marker, line style) of the methods of :func:`activity_horizon_figure`, in their order."""


def _same_series(rows: Sequence[dict], method: str, other: str) -> bool:
    """Whether ``method`` scored exactly as ``other`` at every horizon (accuracy and log loss)."""
    def series(name: str) -> list[tuple[float, float, float]]:
        return sorted((float(r["horizon_min"]), float(r["accuracy"]), float(r["log_loss"]))
                      for r in rows if r["method"] == name)
    mine, theirs = series(method), series(other)
    return bool(mine) and len(mine) == len(theirs) and all(
        a[0] == b[0] and abs(a[1] - b[1]) < 1e-9 and abs(a[2] - b[2]) < 1e-9 for a, b in zip(mine, theirs))


def _legend_label(rows: Sequence[dict], homes: Sequence[str], methods: Sequence[str], method: str) -> str:
    """The method's name, with "(same as ...)" where it scored exactly as an earlier method (in
    every home, or in the homes named)."""
    for other in methods[: methods.index(method)]:
        equal = [hh for hh in homes if any(r["household"] == hh and r["method"] == method for r in rows)
                 and _same_series([r for r in rows if r["household"] == hh], method, other)]
        if equal:
            present = [hh for hh in homes if any(r["household"] == hh and r["method"] == method for r in rows)]
            where = "" if equal == present else f" in home {', '.join(equal)}"
            return f"{method} (same as {other}{where})"
    return method


def _plain_log_ticks(ax: Axes) -> None:
    """Ticks of a log-scaled y axis at plain numbers (0.5, 1, 2, 3, 5, 10, ...), labelled as
    such (never ``4×10⁰``); at least two, widening the limits to the nearest if need be."""
    lo, hi = ax.get_ylim()
    lo, hi = max(lo, 1e-6), max(hi, 2e-6)  # a log axis is positive; guard one drawn from no data
    exponents = range(math.floor(math.log10(lo)) - 1, math.ceil(math.log10(hi)) + 2)
    nice = sorted(round(m * 10.0 ** e, 12) for e in exponents for m in (1, 2, 3, 5))
    ticks = [v for v in nice if lo <= v <= hi]
    if len(ticks) < 2:
        lo, hi = max(v for v in nice if v <= lo), min(v for v in nice if v >= hi)
        ax.set_ylim(lo, hi)
        ticks = [v for v in nice if lo <= v <= hi]
    ax.yaxis.set_major_locator(FixedLocator(ticks))
    ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _pos: f"{v:g}"))
    ax.yaxis.set_minor_formatter(NullFormatter())


def activity_horizon_figure(rows: Sequence[dict], title: str) -> Figure:
    """Accuracy and log loss of the activity 10-60 minutes ahead per method, one column per
    household (``rows``: ``activity_anticipation.csv``). Each method has its own marker and line
    style; the first (the chosen model) is drawn on top, and a method that scored exactly as an
    earlier one says so in the legend ("same as ..."), its line drawn wider beneath it."""
    homes = list(dict.fromkeys(r["household"] for r in rows))
    methods = list(dict.fromkeys(r["method"] for r in rows))
    labels = {m: _legend_label(rows, homes, methods, m) for m in methods}
    fig, axes = plt.subplots(2, max(len(homes), 1), figsize=(max(3.6 * len(homes), 4.8), 6.4), squeeze=False,
                             layout="constrained")
    named: set[str] = set()  # methods in the legend already (each once, from the first home it is in)
    for col, hh in enumerate(homes):
        mine = [r for r in rows if r["household"] == hh]
        for i, method in enumerate(methods):
            line = sorted((r for r in mine if r["method"] == method), key=lambda r: float(r["horizon_min"]))
            if not line:
                continue
            marker, style = LINE_STYLES[i % len(LINE_STYLES)]
            under = labels[method] != method  # scored as an earlier method: wider, hollow, beneath it
            look = {"marker": marker, "linestyle": style, "color": f"C{i}", "zorder": 3 + len(methods) - i,
                    "linewidth": 3.0 if under else 1.5, "markersize": 9 if under else 5,
                    "markerfacecolor": "none" if under else f"C{i}"}
            x = [float(r["horizon_min"]) for r in line]
            label = None if method in named else labels[method]
            axes[0][col].plot(x, [float(r["accuracy"]) for r in line], label=label, **look)
            axes[1][col].plot(x, [float(r["log_loss"]) for r in line], **look)
            named.add(method)
        axes[0][col].set_title(f"home {hh}", fontsize=9)
        axes[0][col].set_ylim(0, 1)
        axes[1][col].set_yscale("log")
        _plain_log_ticks(axes[1][col])
        axes[1][col].set_xlabel("minutes ahead")
        for ax in axes[:, col]:
            minutes = sorted({float(r["horizon_min"]) for r in mine})
            if 0 < len(minutes) <= 8:
                ax.set_xticks(minutes, [f"{m:g}" for m in minutes])
    axes[0][0].set_ylabel("accuracy")
    axes[1][0].set_ylabel("log loss (nats, log scale)")
    fig.legend(fontsize=7, loc="outside lower center", ncols=1 if len(homes) < 2 else 2)
    fig.suptitle(title, fontsize=10)
    return fig
