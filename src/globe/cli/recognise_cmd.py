"""``globe recognise``: how well a home's activities are recognised from its sensors."""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from globe.cli.common import ConfigOption, DataOption, HouseholdsOption, households_from, out, print_table, resolve
from globe.cli.evaluate_cmd import stage_display
from globe.data.csv_logs import household_step
from globe.data.sensors import check_sensor_data
from globe.errors import DataError
from globe.evaluation.recognition import (
    BUDGETS,
    LEARNING_DAYS,
    RecognitionReport,
    recognition_report,
    write_recognition,
)

log = logging.getLogger("globe.stages")
DEFAULT_DAYS = ",".join("all" if k is None else str(k) for k in LEARNING_DAYS)
DEFAULT_QUESTIONS = ",".join(map(str, BUDGETS))


def _numbers(text: str, option: str, allow_all: bool = False) -> list[int | None]:
    values: list[int | None] = []
    for part in text.split(","):
        part = part.strip()
        if allow_all and part == "all":
            values.append(None)
            continue
        if not part.isdigit():
            raise typer.BadParameter(f"{part!r} is not a whole number{' or all' if allow_all else ''}",
                                     param_hint=f"'{option}'")
        values.append(int(part))
    return values


def recognise(
    data: DataOption = None,
    households: HouseholdsOption = None,
    out_dir: Annotated[Path, typer.Option("--out", help="folder for the tables and the confusion plot")] = Path(
        "results/recognition"),
    labelled_days: Annotated[str, typer.Option(
        "--labelled-days", help="labelled training days of the learning curve (comma-separated, or 'all')")
    ] = DEFAULT_DAYS,
    questions: Annotated[str, typer.Option(
        "--questions", help="questions a day of the asking curve (comma-separated)")] = DEFAULT_QUESTIONS,
    config: ConfigOption = None,
) -> None:
    """Recognise each household's activities from its sensors (sensors.csv and events/, kept by
    'globe data import') and score them against its annotation on the test days: the learning curve,
    the asking curve, a CRF row, per-class F1, the confusion matrix and the effect on GLOBE's
    predictions. Every choice is made on training days."""
    counts = _numbers(labelled_days, "--labelled-days", allow_all=True)
    budgets = [b for b in _numbers(questions, "--questions") if b is not None]
    cfg = resolve(config)
    homes = households_from(cfg, data, households)
    done = 0
    with stage_display() as show:
        def progress(message: str) -> None:
            log.info(message)
            show(message)
        for household in homes:
            step = cfg.data.step_minutes or household_step(household.train + household.test)
            sensors = check_sensor_data(household, step)
            if sensors is None or step is None:
                out.print(f"{household.name}: no sensors (sensors.csv) to recognise from; skipped", markup=False)
                continue
            if not household.test or not household.train:
                raise DataError("recognition needs training and test days", source=household.source)
            report = recognition_report(household, sensors, step, counts, budgets, progress=progress)
            written = write_recognition(report, out_dir)
            _print(report)
            out.print(f"wrote {', '.join(str(p) for p in written)}", markup=False)
            done += 1
    if not done:
        raise DataError("no household with sensors: import one with 'globe data import' (it keeps every sensor)")


def _print(report: RecognitionReport) -> None:
    table = Table(title=f"{report.household}: recognition on the test days (online)")
    for col in ("labelled days", "time-slice", "class", "smoothed time-slice", "smoothed class"):
        table.add_column(col, justify="right")
    for row in report.learning:
        table.add_row(str(row["labelled_days"]), f"{row['time_slice_accuracy']:.3f}", f"{row['class_accuracy']:.3f}",
                      f"{row['smoothed_time_slice_accuracy']:.3f}", f"{row['smoothed_class_accuracy']:.3f}")
    if report.crf is not None:
        table.add_row("CRF, all", f"{report.crf.time_slice:.3f}", f"{report.crf.class_accuracy:.3f}", "", "")
    print_table(table)
    if report.asking:
        asking = Table(title=f"{report.household}: asking the person (class accuracy on the test days)")
        for col in ("questions a day", "where least sure", "at random"):
            asking.add_column(col, justify="right")
        for row in report.asking:
            asking.add_row(str(row["questions_per_day"]), f"{row['worth_class_accuracy']:.3f}",
                           f"{row['random_class_accuracy']:.3f}")
        print_table(asking)
    e2e = report.end_to_end
    out.print(f"GLOBE's next activity (clock model), annotated vs recognised history: one-step F1 "
              f"{e2e['annotated_one_step_f1']:.3f} vs {e2e['recognised_one_step_f1']:.3f}; next different activity "
              f"{e2e['annotated_next_different_accuracy']} vs {e2e['recognised_next_different_accuracy']}",
              markup=False)
