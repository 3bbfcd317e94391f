"""``globe evaluate``, ``globe reproduce`` and ``globe robustness``: parse, call
:mod:`globe.evaluation.main_job`, print the tables it returns."""

from __future__ import annotations

import json
import logging
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Callable, Iterator

import typer
from rich.table import Table

from globe.cli.common import (
    ConfigOption,
    DataOption,
    HouseholdsOption,
    console,
    households_from,
    out,
    print_table,
    require_test_days,
    resolve,
)
from globe.evaluation.methods import METHODS
from globe.evaluation.published import DataScope

if TYPE_CHECKING:
    from globe.evaluation.results import Table1Results
    from globe.evaluation.robustness import RobustnessResults

OutOption = Annotated[Path, typer.Option("--out", help="results folder to write")]


def _num(x: float | None) -> str:
    """Three decimals, or "–" for an absent value (nothing to score)."""
    return "–" if x is None else f"{x:.3f}"


def _over(households: list[str] | tuple[str, ...]) -> str:
    """What the tables' numbers are: the mean of several households, or one household's own."""
    return f"household {households[0]}" if len(households) == 1 else "mean of households"


def table1_table(rows: list[dict], labels: dict[str, str], scope: DataScope) -> Table:
    """Compact terminal view of Table I: weighted F1 averaged over households, and per household
    (one household: its own figures once); the paper's published rows beside HOMER+ only, which
    alone keeps the paper's name for the table."""
    from globe.evaluation.published import TABLE1, TABLE1_MEAN_ONLY

    weighted = [r for r in rows if r["average"] == "weighted"]
    households = [h for h in dict.fromkeys(r["household"] for r in weighted) if h != "mean"]
    if scope.homer_plus:
        title = f"Table I - {scope.title} test days, weighted F1 ({_over(households)})"
    else:
        title = f"Scores on the test days of {scope.title}, weighted F1" + (
            f" ({_over(households)})" if len(households) > 1 else "")
    table = Table(title=title)
    each = households if len(households) > 1 else []  # one household: its columns would repeat the first ones
    for col in ["method", "activity", "object", "mean", *[f"{h}: act/obj" for h in each]]:
        table.add_column(col, justify="left" if col == "method" else "right")
    for method in dict.fromkeys(r["method"] for r in weighted):
        get = {r["household"]: r for r in weighted if r["method"] == method}
        m = get["mean"]
        table.add_row(labels.get(method, method), _num(m["activity_f1"]), _num(m["object_f1"]), _num(m["mean_f1"]),
                      *[f"{_num(get[h]['activity_f1'])} / {_num(get[h]['object_f1'])}" for h in each])
    published = [(m, f"{a:.2f}", f"{o:.2f}", f"{mean:.2f}") for m, (a, o, mean) in TABLE1.items()]
    published += [(m, "–", "–", f"{mean:.2f}") for m, mean in TABLE1_MEAN_ONLY.items()]
    for method, *figures in published if scope.homer_plus else ():
        table.add_row(f"[dim]{method} (published)[/dim]", *figures, *["" for _ in each])
    return table


def timing_table(rows: list[dict], scope: DataScope) -> Table:
    from globe.evaluation.published import TABLE2

    table = Table(title=f"{'Table II - time' if scope.homer_plus else 'Time'} for the whole test split (s)")
    for col in ("method", "household", "train", "inference", "LLM calls", "LLM s", "CV s"):
        table.add_column(col, justify="left" if col in ("method", "household") else "right")
    for r in rows:
        table.add_row(r["method"], r["household"], f"{r['train_s']:.3f}", f"{r['inference_s']:.3f}",
                      str(r["llm_calls"]), f"{r['llm_s']:.2f}", f"{r['selection_s']:.2f}" if r["selection_s"] else "")
    for method, (tr, inf) in TABLE2.items() if scope.homer_plus else ():
        table.add_row(f"[dim]{method} (published)[/dim]", "", f"{tr:.2f}", f"{inf:.2f}", "", "", "")
    return table


@contextmanager
def stage_display() -> Iterator[Callable[[str], None]]:
    """Stage lines (``globe.stages``) always go to stderr, so redirected runs show progress; a
    terminal also gets a spinner with the current step."""
    logging.getLogger("globe.stages").setLevel(logging.INFO)
    with console.status("starting") as status:
        yield lambda message: status.update(message)


def print_table1(results: Table1Results) -> None:
    print_table(table1_table(results.rows, results.labels, results.scope))
    print_table(timing_table(results.timing, results.scope))


def print_stages(stages: list[dict]) -> None:
    table = Table(title="Where the time went (s)")
    table.add_column("stage")
    table.add_column("seconds", justify="right")
    for row in stages:
        table.add_row(row["stage"], f"{row['seconds']:.1f}")
    table.add_row("total", f"{sum(r['seconds'] for r in stages):.1f}")
    print_table(table)


def evaluate(
    out_dir: OutOption = Path("results/evaluate"),
    methods: Annotated[str, typer.Option(
        "--methods", help=f"comma-separated, from: {', '.join(METHODS)}")] = "persistence,ngram",
    data: DataOption = None,
    households: HouseholdsOption = None,
    config: ConfigOption = None,
    threshold: Annotated[float | None, typer.Option("--threshold", help="gate threshold d")] = None,
    backend: Annotated[str | None, typer.Option("--backend", help="embedded, remote or none")] = None,
    activity_ahead: Annotated[bool, typer.Option(
        "--activity-ahead/--no-activity-ahead", help="also the activity-ahead tables (the activity at +minutes and the "
        "next different activity, beside the baselines)")] = True,
    objects_ahead: Annotated[bool, typer.Option(
        "--objects-ahead/--no-objects-ahead", help="also the lookahead and fetch-policy tables, for the homes with "
        "objects (forecast with the listed methods among persistence, ngram and routine)")] = True,
    activities: Annotated[str, typer.Option(
        "--activities", help="what the models are shown of the test days: the 'annotated' activities, or those "
        "'recognised' online from the home's sensors as its service recognises them (scored against the annotation "
        "either way)")] = "annotated",
) -> None:
    """Evaluate chosen methods on the test days and write a results folder: Table I, the activity
    ahead, and for homes with objects the objects ahead and the fetch policy."""
    from globe.evaluation import main_job
    from globe.evaluation.recognised import ACTIVITIES

    if activities not in ACTIVITIES:
        raise typer.BadParameter(f"{activities!r} is not one of {', '.join(ACTIVITIES)}", param_hint="'--activities'")
    cfg = resolve(config, gate__threshold=threshold, llm__backend=backend)
    names = main_job.check_methods([m.strip() for m in methods.split(",") if m.strip()])
    hs = households_from(cfg, data, households)
    require_test_days(hs)
    stages = main_job.Stages(out_dir)
    with stage_display() as show:
        stages.progress = show
        results = main_job.evaluate(cfg, hs, names, out_dir, main_job.backend_for(cfg, names), stages,
                                    objects_ahead=objects_ahead, activities=activities,
                                    activity_ahead=activity_ahead)
    print_recognition(out_dir)
    print_table1(results)
    print_activity_anticipation(out_dir)
    if (out_dir / "lookahead.csv").is_file() and any(s["stage"].startswith("anticipation") for s in stages.times):
        print_anticipation(out_dir)
    console.print(f"results in {out_dir} ({sum(s['seconds'] for s in stages.times):.1f} s)", markup=False)


def reproduce(
    out_dir: OutOption = Path("results/reproduce"),
    data: DataOption = None,
    config: ConfigOption = None,
    backend: Annotated[str | None, typer.Option("--backend", help="embedded, remote or none")] = None,
    robustness: Annotated[bool, typer.Option(
        "--robustness/--no-robustness", help="also generate HOMER-Noise and run the robustness suite")] = True,
    anticipation: Annotated[bool, typer.Option(
        "--anticipation/--no-anticipation", help="also run lookahead, the fetch policy and missing labels")] = True,
) -> None:
    """Run every experiment available on the shipped HOMER+ and write the results folder."""
    from globe.evaluation import main_job

    cfg = resolve(config, llm__backend=backend)
    hs = households_from(cfg, data, None)
    with stage_display() as show:
        results = main_job.reproduce(cfg, hs, out_dir, with_robustness=robustness, with_anticipation=anticipation,
                                     progress=show)
    print_table1(results.table1)
    print_activity_anticipation(out_dir)
    if results.robustness is not None:
        print_robustness(results.robustness)
    if results.anticipation is not None and results.missing_labels is not None:
        print_anticipation(out_dir)
    print_stages(results.stages)
    console.print(f"results in {out_dir}", markup=False)


def print_robustness(res: RobustnessResults) -> None:
    table = Table(title="Robustness: object F1, all events / routine events only (mean of households)")
    for col in ("dataset", "method", "activity F1", "object F1 all", "object F1 routine", "injected"):
        table.add_column(col)
    for r in res.robustness:
        table.add_row(r["dataset"], r["method"], _num(r["activity_f1"]), _num(r["object_f1"]),
                      _num(r["object_f1_routine"]), str(r["injected_events"]))
    print_table(table)


def robustness(
    out_dir: Annotated[Path, typer.Option("--out", help="results folder")] = Path("results/robustness"),
    noise_dir: Annotated[Path, typer.Option(
        "--noise-dir", help="HOMER-Noise folder (generated there if missing)")] = Path("results/homer_noise"),
    data: DataOption = None,
    backend: Annotated[str | None, typer.Option("--backend", help="embedded or none")] = None,
    config: ConfigOption = None,
) -> None:
    """Robustness suite: noise types, behavioural consistency, ablations (generates noise if needed)."""
    from globe.evaluation import main_job

    cfg = resolve(config, llm__backend=backend)
    hs = households_from(cfg, data, None)
    stages = main_job.Stages(out_dir)
    with stage_display() as show:
        stages.progress = show
        _, res = main_job.robustness(cfg, hs, noise_dir, out_dir, main_job.backend_for(cfg), stages)
    print_robustness(res)
    console.print(f"results in {out_dir}", markup=False)


def print_recognition(out_dir: Path) -> None:
    """How well the test days' activities were recognised (``recognition.csv``), when they were."""
    import csv

    path = out_dir / "recognition.csv"
    if not path.is_file():
        return
    with path.open(newline="", encoding="utf-8") as fh:
        for r in csv.DictReader(fh):
            out.print(f"{r['household']}: test-day activities recognised from the sensors online, as served, "
                      f"time-slice accuracy {float(r['time_slice_accuracy']):.3f}, class accuracy "
                      f"{float(r['class_accuracy']):.3f} "
                      f"(settings chosen on training days: {r['settings']})", markup=False)


def print_activity_anticipation(out_dir: Path) -> None:
    """Accuracy of the activity ahead per home and method, and of the next different activity,
    read back from the results folder."""
    import csv

    def rows(name: str) -> list[dict]:
        path = out_dir / name
        if not path.is_file():
            return []
        with path.open(newline="", encoding="utf-8") as fh:
            return list(csv.DictReader(fh))

    ahead, nxt = rows("activity_anticipation.csv"), rows("next_activity.csv")
    if not ahead and not nxt:  # not asked for (--no-activity-ahead)
        return
    every = list(dict.fromkeys(r["horizon_min"] for r in ahead))
    horizons = list(dict.fromkeys([every[0], every[(len(every) - 1) // 2], every[-1]])) if every else []
    table = Table(title="The activity ahead: accuracy at +minutes and of the next different activity")
    table.add_column("home")
    table.add_column("method", no_wrap=True)
    for col in (*[f"+{h}" for h in horizons], "next"):
        table.add_column(col, justify="right", no_wrap=True)
    for r0 in dict.fromkeys((r["household"], r["method"]) for r in ahead):
        get = {r["horizon_min"]: f"{float(r['accuracy']):.3f}" for r in ahead if (r["household"], r["method"]) == r0}
        after = next((f"{float(r['accuracy']):.3f}" for r in nxt if (r["household"], r["method"]) == r0), "–")
        table.add_row(*r0, *[get.get(h, "–") for h in horizons], after)
    print_table(table)


def _scope(out_dir: Path) -> DataScope | None:
    """What a results folder is about (``data.json``, written with Table I), if it says."""
    path = out_dir / "data.json"
    return DataScope.from_dict(json.loads(path.read_text(encoding="utf-8"))) if path.is_file() else None


def print_anticipation(out_dir: Path) -> None:
    """The mean rows of the anticipation tables, read back from the results folder."""
    import csv

    def rows(name: str, over: str = "mean") -> list[dict]:
        with (out_dir / name).open(newline="", encoding="utf-8") as fh:
            return [r for r in csv.DictReader(fh) if r.get("household") == over]

    def shown(method: str) -> str:
        return METHODS[method].shown if method in METHODS else method

    look = rows("lookahead.csv")
    horizons = list(dict.fromkeys(r["horizon_min"] for r in look))
    scope = _scope(out_dir)
    published = "; SLaTe-PRO published 0.57, 0.60 with queries" if scope and scope.homer_plus else ""
    where = f" on {scope.title}" if scope else ""
    one = scope is not None and len(scope.households) == 1 and not scope.homer_plus  # the title names it
    over = "" if one else _over(scope.households if scope else ())
    notes = f" ({over}{published})" if over or published else ""
    counted = f"; uses counted: {scope.uses}" if scope else ""
    table = Table(title=f"Lookahead{where}: relocation F1{notes}{counted}")
    table.add_column("method")
    for h in horizons:
        table.add_column(f"{h} min", justify="right")
    for method in dict.fromkeys(r["method"] for r in look):
        get = {r["horizon_min"]: r for r in look if r["method"] == method}
        table.add_row(shown(method), *[f"{float(get[h]['f1']):.3f}" for h in horizons])
    print_table(table)
    fetch = [r for r in rows("fetch_policy.csv", "all") if r.get("configured") in ("True", "true", "1")]
    for r in fetch:
        out.print(f"fetch policy (configured costs, {shown(r.get('method') or '')}): "
                  f"precision {float(r['precision']):.3f}, "
                  f"recall {float(r['recall']):.3f}, median lead {r['median_lead_min']} min, {r['fetches']} fetches",
                  markup=False)
    if not (out_dir / "missing_labels.csv").is_file():
        return
    missing = rows("missing_labels.csv")
    table = Table(title=f"Missing activity labels ({_over(scope.households if scope else ())})")
    for col in ("labels %", "activity F1", "object F1", "lookahead F1 (mean)"):
        table.add_column(col, justify="right")
    for r in missing:
        table.add_row(r["labels_pct"], r["activity_f1"], r["object_f1"], r.get("lookahead_f1_mean") or "–")
    print_table(table)
