"""The README's and the docs' overview figure, drawn from a results folder (the committed
reference results by default): weighted F1 of activity and object prediction on HOMER+, our
methods beside the paper's published rows. Usage: python tools/docs_figure.py [RESULTS] [OUT.png]
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from globe.evaluation.docs_tables import PUBLISHED_LABELS, read_rows  # noqa: E402
from globe.evaluation.methods import METHODS  # noqa: E402
from globe.evaluation.published import TABLE1  # noqa: E402

SHOWN = ("persistence", "ngram", "globe", "globe_personal", "routine")


def main(results: Path, out: Path) -> None:
    rows = {r["method"]: r for r in read_rows(results, "table1.csv")
            if r["average"] == "weighted" and r["household"] == "mean"}
    bars = [(METHODS[m].label, float(rows[m]["activity_f1"]), float(rows[m]["object_f1"]), False)
            for m in SHOWN if m in rows]
    bars += [(f"{PUBLISHED_LABELS.get(m, m)} (published)", f[0], f[1], True)
             for m, f in TABLE1.items() if f[0] is not None and f[1] is not None and m != "llm_only"]
    fig, ax = plt.subplots(figsize=(7.5, 3.4), dpi=110)
    ys = range(len(bars))
    ax.barh([y + 0.2 for y in ys], [b[1] for b in bars], height=0.38, label="activity", color="#4c78a8")
    ax.barh([y - 0.2 for y in ys], [b[2] for b in bars], height=0.38, label="object", color="#f58518")
    ax.set_yticks(list(ys), [b[0] for b in bars], fontsize=8)
    for tick, bar in zip(ax.get_yticklabels(), bars):
        tick.set_fontstyle("italic" if bar[3] else "normal")
    ax.invert_yaxis()
    ax.set_xlim(0.5, 0.9)
    ax.set_xlabel("weighted F1 on HOMER+ test days (mean of households A, B, C)", fontsize=8)
    ax.set_title("Next activity and next object: GLOBE's models beside the paper's published figures", fontsize=9)
    ax.legend(fontsize=8, loc="lower right")
    ax.tick_params(axis="x", labelsize=8)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out)
    plt.close(fig)


if __name__ == "__main__":
    root = Path(__file__).resolve().parents[1]
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else root / "reference" / "homer_plus",
         Path(sys.argv[2]) if len(sys.argv) > 2 else root / "docs" / "img" / "overview.png")
