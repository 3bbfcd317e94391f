"""Results folders: CSV tables, Markdown tables, per-prediction records, the config used."""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Iterable, Protocol, Sequence

from globe.evaluation.published import TABLE1, TABLE1_MEAN_ONLY, TABLE2, DataScope


def write_csv(path: Path, rows: Sequence[dict], fieldnames: Sequence[str] | None = None) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    names = list(fieldnames or (rows[0].keys() if rows else []))
    tmp = path.with_name(path.name + ".tmp")
    with tmp.open("w", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, fieldnames=names, lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)
    tmp.replace(path)


class Record(Protocol):
    def as_row(self) -> dict[str, object]: ...


def write_records(folder: Path, name: str, records: Iterable[Record]) -> None:
    """One CSV row per prediction (``as_row``: lists joined with ``|``)."""
    rows = [rec.as_row() for rec in records]
    if rows:
        write_csv(folder / f"{name}.csv", rows)


def write_json(path: Path, payload: object) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(payload, indent=2, default=str) + "\n", encoding="utf-8")


def _fmt(x: float | str | None) -> str:
    return f"{float(x):.3f}" if x not in (None, "") else "–"


def table1_markdown(rows: Sequence[dict], labels: dict[str, str], average: str, scope: DataScope) -> str:
    """The paper's Table I layout: methods x (activity, object, mean) per household and mean; on
    HOMER+ the paper's published rows follow, each labelled as published. A single home that is
    not HOMER+ gets its own columns only (its mean would repeat them)."""
    mine = [r for r in rows if r["average"] == average]
    households = list(dict.fromkeys(r["household"] for r in mine))
    if not scope.homer_plus and len([h for h in households if h != "mean"]) == 1:
        households = [h for h in households if h != "mean"]
    head = "| Method | " + " | ".join(f"{h} act | {h} obj | {h} mean" for h in households) + " |"
    sep = "|---|" + "---|" * (3 * len(households))
    lines = [f"F1 ({average}) on {scope.title} test days", "", head, sep]
    for method in dict.fromkeys(r["method"] for r in mine):
        cells = []
        for h in households:
            r = next((x for x in mine if x["method"] == method and x["household"] == h), None)
            cells += [_fmt(r["activity_f1"]), _fmt(r["object_f1"]), _fmt(r["mean_f1"])] if r else ["–"] * 3
        lines.append(f"| {labels.get(method, method)} | " + " | ".join(cells) + " |")
    if average == "weighted" and scope.homer_plus:
        published = [(method, (f"{a:.2f}", f"{o:.2f}", f"{m:.2f}")) for method, (a, o, m) in TABLE1.items()]
        published += [(method, ("–", "–", f"{m:.2f}")) for method, m in TABLE1_MEAN_ONLY.items()]
        for method, figures in published:
            cells = ["–"] * (3 * (len(households) - 1)) + list(figures)
            lines.append(f"| *{method} (published)* | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def timing_markdown(rows: Sequence[dict], scope: DataScope) -> str:
    lines = ["Training and inference time for the whole test split (seconds, this machine); CV s = hyperparameter",
             "search on training days (not part of training)", "",
             "| Method | Household | Train s | Inference s | LLM calls | LLM s | CV s |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['method']} | {r['household']} | {float(r['train_s']):.3f} | {float(r['inference_s']):.3f} "
                     f"| {r['llm_calls']} | {float(r['llm_s']):.2f} | {float(r['selection_s']):.2f} |")
    for method, (tr, inf) in TABLE2.items() if scope.homer_plus else ():
        lines.append(f"| *{method} (published)* | – | {tr:.2f} | {inf:.2f} | – | – | – |")
    return "\n".join(lines) + "\n"


def details_markdown(rows: Sequence[dict]) -> str:
    cols = ["method", "household", "activity_f1", "activity_f1_change_steps", "activity_log_loss", "object_f1",
            "object_f1_oracle_activity", "gate_rate", "llm_fallbacks", "llm_changed_choice"]
    lines = ["Details (weighted F1): change steps, true-activity oracle, LLM gate", "",
             "| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for r in rows:
        lines.append("| " + " | ".join(str(r[c]) for c in cols) + " |")
    return "\n".join(lines) + "\n"


def rows_markdown(rows: Sequence[dict]) -> str:
    if not rows:
        return ""
    cols = list(rows[0])
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    lines += ["| " + " | ".join(str(r[c]) for c in cols) + " |" for r in rows]
    return "\n".join(lines) + "\n"
