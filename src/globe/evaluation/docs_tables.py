"""The documentation's numbers, written from a results folder, never typed by hand.

A Markdown page marks each generated table with ``<!-- globe:table NAME -->`` and
``<!-- /globe:table -->``; :func:`render` replaces what lies between with the table NAME built
from a results folder of the main job (``reference/homer_plus`` in the repository). The table
``config`` is the configuration reference, built from :class:`~globe.config.GlobeConfig` itself.
``globe docs tables`` writes the pages; its ``--check`` (and the docs test) fails when a page
differs from what this module writes.
"""

from __future__ import annotations

import csv
import json
import re
import statistics
import typing
from pathlib import Path
from typing import Any, Callable, Iterable, Sequence

from pydantic import BaseModel
from pydantic.fields import FieldInfo

from globe.config import GlobeConfig
from globe.errors import DataError
from globe.evaluation.methods import METHODS
from globe.evaluation.published import TABLE1, TABLE1_MEAN_ONLY
from globe.models.baselines import HOUR_ACTIVITY, ORACLE, ORACLE_LABEL

MARKER = re.compile(r"(<!-- globe:table (?P<name>[a-z0-9_]+) -->\n)(?P<body>.*?)(<!-- /globe:table -->)", re.S)

# how a published method is named beside ours
PUBLISHED_LABELS = {"globe": "GLOBE", "ngram": "n-gram Markov", "slate_pro": "SLaTe-PRO",
                    "llm_only": "LLM-only, GPT-4.1", "stot": "STOT"}
DATASET_ORDER = ("clean", "person", "pet", "toddler")


# ---- reading a results folder ------------------------------------------------------------------

def read_rows(results: Path, name: str) -> list[dict[str, str]]:
    """The rows of ``results/name`` (CSV), or a DataError naming the missing file."""
    path = Path(results) / name
    if not path.is_file():
        raise DataError(f"{name} not found in the results folder (run 'globe reproduce --out {results}')",
                        source=str(path))
    with path.open(newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def _f(value: str | float | None, digits: int = 3) -> str:
    """A number to ``digits`` decimals; "–" for an absent one (nothing to score)."""
    if value is None or value == "":
        return "–"
    return f"{float(value):.{digits}f}"


def _mean(values: Iterable[str]) -> float | None:
    numbers = [float(v) for v in values if v not in ("", None)]
    return round(statistics.fmean(numbers), 4) if numbers else None


def markdown(header: Sequence[str], rows: Iterable[Sequence[str]], right: int = 1) -> str:
    """A Markdown table; columns from ``right`` on are numbers, aligned right."""
    aligns = ["---" if i < right else "---:" for i in range(len(header))]
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join(aligns) + "|"]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines) + "\n"


def _label(method: str) -> str:
    """A method as the tables name it (a baseline says so, and so does the oracle)."""
    if method == ORACLE:
        return ORACLE_LABEL
    return METHODS[method].shown if method in METHODS else method


# ---- Table I and its companions ----------------------------------------------------------------

def _homer_plus(results: Path) -> bool:
    """Whether the results are on HOMER+ (``data.json``): the paper's figures stand beside those only."""
    path = results / "data.json"
    return path.is_file() and bool(json.loads(path.read_text(encoding="utf-8")).get("homer_plus"))


def table1(results: Path) -> str:
    """Weighted F1, mean of the households, ours beside every published row of the paper's Table I."""
    rows = [r for r in read_rows(results, "table1.csv") if r["average"] == "weighted" and r["household"] == "mean"]
    details = read_rows(results, "details.csv")
    body = []
    for r in rows:
        change = _mean(d["activity_f1_change_steps"] for d in details if d["method"] == r["method"])
        body.append([_label(r["method"]), _f(r["activity_f1"]), _f(change), _f(r["object_f1"]), _f(r["mean_f1"])])
    published: list[tuple[str, float | None, float | None, float]] = [(k, a, o, m) for k, (a, o, m) in TABLE1.items()]
    published += [(method, None, None, m) for method, m in TABLE1_MEAN_ONLY.items()]
    for method, a, o, m in published if _homer_plus(results) else ():
        body.append([f"*{PUBLISHED_LABELS.get(method, method)} (published)*", _f(a, 2), "", _f(o, 2), _f(m, 2)])
    return markdown(["method", "activity", "activity, change steps", "object", "mean"], body)


def table1_households(results: Path) -> str:
    """Weighted F1 per household: activity / object."""
    rows = [r for r in read_rows(results, "table1.csv") if r["average"] == "weighted" and r["household"] != "mean"]
    return _activity_object(rows, "household")


def table1_averages(results: Path) -> str:
    """Mean F1 of the households by each average (weighted, micro, macro)."""
    return _activity_object([r for r in read_rows(results, "table1.csv") if r["household"] == "mean"], "average")


def _activity_object(rows: list[dict[str, str]], column: str) -> str:
    """A row per method, a column per value of ``column``: activity / object F1."""
    values = list(dict.fromkeys(r[column] for r in rows))
    body = []
    for method in dict.fromkeys(r["method"] for r in rows):
        get = {r[column]: r for r in rows if r["method"] == method}
        body.append([_label(method), *[f"{_f(get[v]['activity_f1'])} / {_f(get[v]['object_f1'])}" for v in values]])
    return markdown(["method", *[f"{v}: activity / object" for v in values]], body)


def details(results: Path) -> str:
    """Mean over households of the finer measures of ``details.csv``."""
    rows = read_rows(results, "details.csv")
    cols = ("activity_log_loss", "object_f1_oracle_activity", "gate_rate", "llm_fallbacks", "llm_changed_choice")
    body = []
    for method in dict.fromkeys(r["method"] for r in rows):
        mine = [r for r in rows if r["method"] == method]
        body.append([_label(method), *[_f(_mean(r[c] for r in mine)) for c in cols[:3]],
                     *[str(sum(int(r[c]) for r in mine)) for c in cols[3:]]])
    return markdown(["method", "activity log loss", "object F1, true activity", "gate rate", "LLM fallbacks",
                     "LLM changed the choice"], body)


def calibration(results: Path) -> str:
    rows = read_rows(results, "calibration.csv")
    return markdown(["method", "activity ECE", "object ECE"],
                    [[_label(r["method"]), _f(r["activity_ece"]), _f(r["object_ece"])] for r in rows])


def timing(results: Path) -> str:
    """Seconds per household (mean of the households) on the machine that ran the main job."""
    rows = read_rows(results, "timing.csv")
    body = []
    for method in dict.fromkeys(r["method"] for r in rows):
        mine = [r for r in rows if r["method"] == method]
        body.append([_label(method), _f(_mean(r["train_s"] for r in mine)), _f(_mean(r["inference_s"] for r in mine)),
                     str(round(statistics.fmean(int(r["llm_calls"]) for r in mine))),
                     _f(_mean(r["selection_s"] for r in mine), 2)])
    return markdown(["method", "train s", "inference s", "LLM calls", "cross-validation s"], body)


def selection(results: Path) -> str:
    """What cross-validation on the training days chose, per method, household and part."""
    rows = [r for r in read_rows(results, "selection.csv") if r["chosen"] == "True"]
    body = [[_label(r["method"]), r["household"], r["part"], "`" + r["params"].replace(";", ", ") + "`",
             r["criterion"]] for r in rows]
    return markdown(["method", "household", "part", "chosen", "chosen by"], body, right=99)


# ---- activity anticipation ---------------------------------------------------------------------

def activity_anticipation(results: Path) -> str:
    """Accuracy and log loss of the activity +10..+60 minutes ahead, mean of the households."""
    rows = read_rows(results, "activity_anticipation.csv")
    horizons = list(dict.fromkeys(r["horizon_min"] for r in rows))
    body = []
    for method in dict.fromkeys(r["method"] for r in rows):
        for metric in ("weighted_f1", "accuracy", "log_loss"):
            cells = [_f(_mean(r[metric] for r in rows if r["method"] == method and r["horizon_min"] == h))
                     for h in horizons]
            body.append([method, metric.replace("_", " "), *cells])
    return markdown(["model", "measure", *[f"+{h} min" for h in horizons]], body, right=2)


def next_activity(results: Path) -> str:
    rows = read_rows(results, "next_activity.csv")
    households = list(dict.fromkeys(r["household"] for r in rows))
    body = []
    for method in dict.fromkeys(r["method"] for r in rows):
        get = {r["household"]: r for r in rows if r["method"] == method}
        body.append([method, *[_f(get[h]["accuracy"]) for h in households],
                     _f(_mean(get[h]["accuracy"] for h in households))])
    events = {r["household"]: r["events"] for r in rows}
    return markdown(["model", *[f"{h} ({events[h]} changes)" for h in households], "mean"], body)


# ---- anticipation of objects -------------------------------------------------------------------

def lookahead(results: Path) -> str:
    """Relocation F1 at each horizon (mean of the households), and the activity accuracy at r+s."""
    rows = [r for r in read_rows(results, "lookahead.csv") if r["household"] == "mean"]
    horizons = list(dict.fromkeys(r["horizon_min"] for r in rows))
    body = []
    for method in dict.fromkeys(r["method"] for r in rows):
        get = {r["horizon_min"]: r for r in rows if r["method"] == method}
        body.append([f"{_label(method)}: relocation F1", *[_f(get[h]["f1"]) for h in horizons]])
    for method in dict.fromkeys(r["method"] for r in rows):
        get = {r["horizon_min"]: r for r in rows if r["method"] == method}
        body.append([f"{_label(method)}: activity accuracy", *[_f(get[h]["activity_accuracy"]) for h in horizons]])
    return markdown(["model", *[f"{h} min" for h in horizons]], body)


def lookahead_selection(results: Path) -> str:
    """The movement model's variant (and the clock-aware object model where it won) and the change
    threshold per horizon that cross-validation chose."""
    rows = [r for r in read_rows(results, "lookahead_selection.csv") if r["chosen"] == "True"]
    body = []
    for key in dict.fromkeys((r["method"], r["household"]) for r in rows):
        mine = [r for r in rows if (r["method"], r["household"]) == key]
        first = mine[0]
        variant = ", ".join(name for name in ("run_end", "run_memory", "run_next") if first[name] == "True") or "plain"
        if first.get("objects") == "clock":
            variant += "; objects: clock-aware model"
        thresholds = " ".join(r["threshold"] for r in mine)
        body.append([_label(key[0]), key[1], variant, thresholds])
    return markdown(["model", "household", "movement model", "thresholds (10..60 min)"], body, right=99)


def fetch_policy(results: Path) -> str:
    """The fetch policy at the configured costs per household, and over all households along the cost
    ratio; then the baseline's and the oracle's fetches at the configured costs."""
    rows = read_rows(results, "fetch_policy.csv")

    def cells(r: dict[str, str]) -> list[str]:
        return [_label(r.get("method") or ""), r["household"], r["cost_ratio"], _f(r["threshold"]), r["fetches"],
                _f(r["precision"]), _f(r["recall"]), _f(r["median_lead_min"], 0)]

    body = [cells(r) for r in rows if r.get("method") not in (HOUR_ACTIVITY, ORACLE)
            and (r["configured"] == "True" or r["household"] == "all")]
    body += [cells(r) for other in (HOUR_ACTIVITY, ORACLE) for r in rows
             if r.get("method") == other and r["configured"] == "True"]
    return markdown(["model", "household", "costs useless : missed", "fetch when P >", "fetches", "precision",
                     "recall", "median lead (min)"], body, right=2)


def fetch_lead_times(results: Path) -> str:
    rows = read_rows(results, "fetch_lead_times.csv")
    leads = list(dict.fromkeys(r["lead_min"] for r in rows))
    households = list(dict.fromkeys(r["household"] for r in rows))
    body = [[h, *[next(r["uses"] for r in rows if r["household"] == h and r["lead_min"] == lead) for lead in leads]]
            for h in households]
    return markdown(["household", *[f"{lead} min" for lead in leads]], body)


def missing_labels(results: Path) -> str:
    rows = [r for r in read_rows(results, "missing_labels.csv") if r["household"] == "mean"]
    body = [[f"{r['labels_pct']} %", _f(r["activity_f1"]), _f(r["activity_log_loss"]), _f(r["object_f1"]),
             _f(r.get("lookahead_f1_mean"))] for r in rows]
    head = ["labels visible", "activity F1", "activity log loss", "object F1", "lookahead F1 (mean 10–60 min)"]
    return markdown(head, body)


def missing_labels_selection(results: Path) -> str:
    rows = [r for r in read_rows(results, "missing_labels_selection.csv") if r["chosen"] == "True"]
    return markdown(["household", "movement evidence chosen", "CV object F1, no labels"],
                    [[r["household"], "`" + r["params"] + "`", _f(r["cv_object_f1_no_labels"])] for r in rows], right=2)


# ---- HOMER-Noise and robustness ----------------------------------------------------------------

def _dataset_rows(rows: list[dict[str, str]]) -> list[dict[str, str]]:
    return sorted(rows, key=lambda r: DATASET_ORDER.index(r["dataset"]) if r["dataset"] in DATASET_ORDER else 99)


def robustness(results: Path) -> str:
    """Object F1 on all movement events / on the routine's events only, per test data and method."""
    rows = _dataset_rows(read_rows(results, "robustness/robustness.csv"))
    methods = list(dict.fromkeys(r["method"] for r in rows))
    body = []
    for dataset in dict.fromkeys(r["dataset"] for r in rows):
        get = {r["method"]: r for r in rows if r["dataset"] == dataset}
        injected = next(iter(get.values()))["injected_events"]
        body.append([dataset, injected, *[f"{_f(get[m]['object_f1'])} / {_f(get[m]['object_f1_routine'])}"
                                          if m in get else "–" for m in methods]])
    return markdown(["test data", "injected", *[_label(m) for m in methods]], body)


def _ablation(results: Path, name: str, column: str) -> str:
    rows = _dataset_rows(read_rows(results, f"robustness/{name}"))
    values = list(dict.fromkeys(r[column] for r in rows))
    body = []
    for key in dict.fromkeys((r["dataset"], r["method"]) for r in rows):
        get = {r[column]: r for r in rows if (r["dataset"], r["method"]) == key}
        body.append([key[0], _label(key[1]), *[_f(get[v]["object_f1"]) if v in get else "–" for v in values]])
    return markdown(["test data", "method", *[f"{column.replace('_', ' ')} {v}" for v in values]], body, right=2)


def ablation_train_level(results: Path) -> str:
    return _ablation(results, "ablation_train_level.csv", "train_level")


def ablation_threshold(results: Path) -> str:
    return _ablation(results, "ablation_threshold.csv", "threshold")


def consistency(results: Path) -> str:
    rows = _dataset_rows(read_rows(results, "robustness/consistency.csv"))
    groups = list(dict.fromkeys(r["consistency"] for r in rows))
    body = []
    for key in dict.fromkeys((r["dataset"], r["definition"], r["method"]) for r in rows):
        get = {r["consistency"]: r for r in rows if (r["dataset"], r["definition"], r["method"]) == key}
        body.append([key[0], key[1].replace("_", " "), _label(key[2]),
                     *[_f(get[g]["object_f1"]) if g in get else "–" for g in groups]])
    return markdown(["test data", "definition", "method", *[f"{g} consistent" for g in groups]], body, right=3)


def homer_noise(results: Path) -> str:
    """Disturbances generated per noise type and level, and why proposals were dropped."""
    path = Path(results) / "homer_noise" / "summary.json"
    if not path.is_file():
        raise DataError("homer_noise/summary.json not found in the results folder", source=str(path))
    summary = json.loads(path.read_text(encoding="utf-8"))
    levels = [str(level) for level in summary["types"][next(iter(summary["types"]))]["per_level"]]
    body = []
    for kind, info in summary["types"].items():
        dropped = "; ".join(f"{why}: {n}" for why, n in info["dropped"].items())
        body.append([kind, dropped, *[str(info["per_level"][level]) for level in levels]])
    return markdown(["noise type", "proposals dropped", *[f"level {level}" for level in levels]], body, right=2)


# ---- the configuration reference ---------------------------------------------------------------

def _type_name(annotation: Any) -> str:
    if typing.get_origin(annotation) is typing.Literal:
        return "str"
    text = str(annotation) if not isinstance(annotation, type) else annotation.__name__
    text = re.sub(r"typing\.|pathlib\.|datetime\.|globe\.(\w+\.)+", "", text)
    text = re.sub(r"Annotated\[(\w+), [^\]]*\]", r"\1", text)
    return text.replace("NoneType", "None")


def _default(value: Any) -> str:
    if isinstance(value, tuple):
        return "[" + ", ".join(_default(v) for v in value) + "]"
    if isinstance(value, bool):
        return "true" if value else "false"
    if value is None:
        return "none (unset)"
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, Path):
        return f'"{value}"'
    if hasattr(value, "total_seconds"):
        return f"{value.total_seconds():g} s"
    return repr(value)


def _bounds(info: FieldInfo) -> str:
    parts = []
    for meta in info.metadata:
        for attr, sign in (("ge", "≥"), ("gt", ">"), ("le", "≤"), ("lt", "<")):
            bound = getattr(meta, attr, None)
            if bound is not None:
                parts.append(f"{sign} {bound:g}" if isinstance(bound, (int, float)) else f"{sign} {bound}")
    return ", ".join(parts)


def _choices(annotation: Any) -> str:
    args = [a for a in typing.get_args(annotation) if a is not type(None)]
    if typing.get_origin(annotation) is typing.Literal:
        return " / ".join(f'"{a}"' for a in typing.get_args(annotation))
    for arg in args:
        found = _choices(arg)
        if found:
            return found
    return ""


def config(results: Path | None = None) -> str:
    """Every section and field of :class:`GlobeConfig`: TOML key, environment variable, default,
    allowed values and the description written beside the field."""
    blocks = []
    for section, section_field in GlobeConfig.model_fields.items():
        model = section_field.annotation
        if not (isinstance(model, type) and issubclass(model, BaseModel)):
            continue
        body = []
        for name, info in model.model_fields.items():
            allowed = _choices(info.annotation) or _bounds(info)
            kind = "`" + _type_name(info.annotation).replace(" | ", " or ") + "`"
            body.append([f"`{name}`", kind, _default(info.default).replace("|", "\\|"),
                         allowed.replace("|", "\\|"), (info.description or "").replace("|", "\\|")])
        title = f"### `[{section}]`\n\nEnvironment: `GLOBE_{section.upper()}__<FIELD>`\n\n"
        blocks.append(title + markdown(["field", "type", "default", "allowed", "what it does"], body, right=99))
    return "\n".join(blocks)


TABLES: dict[str, Callable[[Path], str]] = {
    "table1": table1,
    "table1_households": table1_households,
    "table1_averages": table1_averages,
    "details": details,
    "calibration": calibration,
    "timing": timing,
    "selection": selection,
    "activity_anticipation": activity_anticipation,
    "next_activity": next_activity,
    "lookahead": lookahead,
    "lookahead_selection": lookahead_selection,
    "fetch_policy": fetch_policy,
    "fetch_lead_times": fetch_lead_times,
    "missing_labels": missing_labels,
    "missing_labels_selection": missing_labels_selection,
    "robustness": robustness,
    "ablation_train_level": ablation_train_level,
    "ablation_threshold": ablation_threshold,
    "consistency": consistency,
    "homer_noise": homer_noise,
    "config": config,
}


# ---- pages -------------------------------------------------------------------------------------

def render(text: str, results: Path, source: str = "page") -> str:
    """``text`` with every marked table rewritten from ``results``; an unknown table name is an error."""
    def replace(match: re.Match[str]) -> str:
        name = match["name"]
        if name not in TABLES:
            line = text.count("\n", 0, match.start()) + 1
            raise DataError(f"{source}:{line}: unknown table {name!r}; known: {', '.join(TABLES)}", source=source)
        return match.group(1) + "\n" + TABLES[name](results) + "\n" + match.group(4)

    return MARKER.sub(replace, text)


def pages(root: Path) -> list[Path]:
    """The pages whose tables are generated: the README and every Markdown page under docs/."""
    root = Path(root)
    return [root / "README.md", *sorted((root / "docs").rglob("*.md"))]


def stale_pages(root: Path, results: Path) -> list[tuple[Path, str]]:
    """``(page, text it should have)`` for every page whose tables differ from ``results``."""
    found = []
    for page in pages(root):
        if not page.is_file():
            continue
        text = page.read_text(encoding="utf-8")
        wanted = render(text, results, str(page.relative_to(root)))
        if wanted != text:
            found.append((page, wanted))
    return found


def write_pages(root: Path, results: Path) -> list[Path]:
    """Rewrite the pages whose tables are stale; returns the pages written."""
    written = []
    for page, text in stale_pages(root, results):
        page.write_text(text, encoding="utf-8")
        written.append(page)
    return written
