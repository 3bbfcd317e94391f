"""``globe recognise``: how well a home's activities are recognised from its sensors, and, with
``--label``, the days nobody labelled labelled from them."""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from globe.cli.common import ConfigOption, DataOption, HouseholdsOption, households_from, out, print_table, resolve
from globe.cli.evaluate_cmd import stage_display
from globe.data.csv_logs import household_step
from globe.data.records import Day, Household
from globe.data.sensors import SensorData, check_sensor_data, read_unlabelled_days
from globe.errors import DataError
from globe.evaluation.recognition import (
    BUDGETS,
    LEARNING_DAYS,
    RecognitionReport,
    choose_labeller,
    recognition_report,
    write_recognition,
)
from globe.recognition.labelling import before_test, recognise_days, write_labelled

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
    label: Annotated[Path | None, typer.Option(
        "--label", help="instead of scoring: label each household's unlabelled days (unlabelled/, kept by 'globe "
                        "data import') with hindsight and write the household with them as training days to "
                        "LABEL/<household>")] = None,
    config: ConfigOption = None,
) -> None:
    """Recognise each household's activities from its sensors (sensors.csv and events/, kept by
    'globe data import') and score them against its annotation on the test days: the learning curve,
    the asking curve, a CRF row, per-class F1, the confusion matrix and the effect on GLOBE's
    predictions. With --label, label the days nobody labelled instead. Every choice is made on training days."""
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
            unlabelled = read_unlabelled_days(household, step)
            sensors = check_sensor_data(household, step, unlabelled)
            if sensors is None or step is None:
                out.print(f"{household.name}: no sensors (sensors.csv) to recognise from; skipped", markup=False)
                continue
            if label is not None:
                progress(f"{household.name}: choosing the recogniser on the labelled days, labelling the others")
                done += _label(household, sensors, step, unlabelled, label)
                continue
            if not household.test or not household.train:
                raise DataError("recognition needs training and test days", source=household.source)
            report = recognition_report(household, sensors, step, counts, budgets, progress=progress)
            written = write_recognition(report, out_dir)
            _print(report)
            out.print(f"wrote {', '.join(str(p) for p in written)}", markup=False)
            done += 1
    if not done:
        if label is not None:
            raise DataError("no household with sensors and unlabelled days: import one with 'globe data import' "
                            "(it keeps the days nobody annotated in unlabelled/)")
        raise DataError("no household with sensors: import one with 'globe data import' (it keeps every sensor)")


def _label(household: Household, sensors: SensorData, step: int, unlabelled: tuple[Day, ...], root: Path) -> int:
    """Label ``household``'s recorded unlabelled days into ``root/<its folder>``; 1 when written."""
    recorded, later = before_test(household, sensors.recorded(unlabelled))
    labelled = sensors.recorded(household.train)
    if later:
        out.print(f"{household.name}: {len(later)} unlabelled days on or after the first test day left out (the "
                  "test days stay later than every training day)", markup=False)
    if not recorded or not labelled:
        why = "no unlabelled day with sensor events" if not recorded else "no labelled training day with sensor events"
        out.print(f"{household.name}: {why}; nothing to label", markup=False)
        return 0
    choice = choose_labeller(labelled, sensors, step, recorded)
    found = recognise_days(choice.labeller, recorded)
    dest = write_labelled(household, found, root / Path(household.source).name,
                          {"labelled_days": len(labelled), "recogniser": choice.describe()})
    table = Table(title=f"{household.name}: days labelled from the sensors (with hindsight)")
    for col in ("day", "mean probability", "activities"):
        table.add_column(col, justify="left")
    for day in found:
        table.add_row(day.day.name.rsplit("/", 1)[-1], f"{day.mean_probability:.3f}",
                      ", ".join(sorted(set(day.day.activities))))
    print_table(table)
    held = ", ".join(f"{name} {acc:.3f}" for name, acc in choice.held_out.items())
    out.print(f"labelled {len(found)} days from {len(labelled)} labelled ones by the {choice.name} recogniser, "
              f"chosen by cross-validation on them{f' (held-out class accuracy: {held})' if held else ''}; wrote "
              f"{dest} (train/ holds them, recognised/ each step's probability)", markup=False)
    return 1


def _print(report: RecognitionReport) -> None:
    table = Table(title=f"{report.household}: recognition on the test days (online)")
    for col in ("labelled days", "time-slice", "class", "smoothed time-slice", "smoothed class"):
        table.add_column(col, justify="right")
    for row in report.learning:
        table.add_row(str(row["labelled_days"]), f"{row['time_slice_accuracy']:.3f}", f"{row['class_accuracy']:.3f}",
                      f"{row['smoothed_time_slice_accuracy']:.3f}", f"{row['smoothed_class_accuracy']:.3f}")
    for name, scores in report.library.items():  # read with hindsight: beside the smoothed columns
        table.add_row(f"{name}, all", "", "", f"{scores.time_slice:.3f}", f"{scores.class_accuracy:.3f}")
    print_table(table)
    if report.asking:
        asking = Table(title=f"{report.household}: asking the person (class accuracy on the test days)")
        for col in ("questions a day", "where worth most", "at random"):
            asking.add_column(col, justify="right")
        for row in report.asking:
            spread = row.get("random_class_accuracy_sd")
            asking.add_row(str(row["questions_per_day"]), f"{row['worth_class_accuracy']:.3f}",
                           f"{row['random_class_accuracy']:.3f}" + (f" ± {spread:.3f}" if spread else ""))
        print_table(asking)
    e2e = report.end_to_end
    out.print(f"GLOBE's next activity (clock model), annotated vs recognised history: one-step F1 "
              f"{e2e['annotated_one_step_f1']:.3f} vs {e2e['recognised_one_step_f1']:.3f}; next different activity "
              f"{e2e['annotated_next_different_accuracy']} vs {e2e['recognised_next_different_accuracy']}",
              markup=False)
    if "filtered_one_step_f1" in e2e:  # the recogniser's own predictive: every history its sensors allow
        out.print(f"... predicted by the recogniser's filter from the sensors (its clock dynamics): one-step F1 "
                  f"{e2e['filtered_one_step_f1']:.3f}; next different activity "
                  f"{e2e['filtered_next_different_accuracy']}", markup=False)
