"""``globe data``: validate observation logs, import native HOMER+ files and real homes' logs."""

from __future__ import annotations

import re
from datetime import date
from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from globe.cli.common import (
    ConfigOption,
    DataOption,
    HouseholdsOption,
    count,
    households_from,
    out,
    plain,
    print_table,
    resolve,
)
from globe.data.csv_logs import household_step
from globe.data.importers import GridOptions, ImportResult, import_casas, import_home_assistant, import_kasteren
from globe.data.importers.options import DEFAULT_STEP_MINUTES, DEFAULT_TEST_FRACTION, UNLABELLED_MODES, USE_MODES
from globe.data.importers.text import parse_clock
from globe.data.sensors import check_sensor_data, read_unlabelled_days
from globe.sequences.runs import activity_runs

app = typer.Typer(help="Validate and import household observation logs.", no_args_is_help=True)
import_app = typer.Typer(help="Import a real home's log (CASAS, van Kasteren / Ordóñez, Home Assistant) into a "
                              "household folder on GLOBE's step grid; the folder's import.json says what became of "
                              "each sensor, annotation and day.", no_args_is_help=True)
app.add_typer(import_app, name="import")


@app.command("validate")
def validate(data: DataOption = None, households: HouseholdsOption = None, config: ConfigOption = None) -> None:
    """Load every day file (and the sensors' files and unlabelled days, where a household has them), check it, and
    summarise each household."""
    cfg = resolve(config)
    table = Table(title="Households")
    for col in ("household", "train days", "test days", "step (min)", "objects", "activities", "movements",
                "sensors", "unlabelled days"):
        table.add_column(col)
    for h in households_from(cfg, data, households):
        days = h.train + h.test
        moves = sum(len(r.events) for d in days for r in activity_runs(d, h.objects, cfg.sequences.alignment))
        acts = {a for d in days for a in d.activities}
        step = cfg.data.step_minutes or household_step(days)
        unlabelled = read_unlabelled_days(h, step)
        sensors = check_sensor_data(h, step, unlabelled)
        table.add_row(plain(h.name), str(len(h.train)), str(len(h.test)), str(step or "-"), str(len(h.objects)),
                      str(len(acts)), str(moves), "-" if sensors is None else str(len(sensors.sensors)),
                      str(len(unlabelled)) if unlabelled else "-")
    print_table(table)
    out.print("all files valid", style="green", markup=False)


@app.command("import-pt")
def import_pt(
    source: Annotated[Path, typer.Argument(help="a HOMER+ checkout's processed_seqLM_coarse folder (or its parent)")],
    dest: Annotated[Path, typer.Argument(help="output household folder (nodes.csv, train/, test/)")],
) -> None:
    """Convert native HOMER+ ``.pt`` files into CSV observation logs (needs globe[torch])."""
    from globe.data.homer_pt import import_household

    written = import_household(source, dest)
    out.print(f"wrote {len(written)} day files and nodes.csv to {dest}", markup=False, highlight=False)


DestArgument = Annotated[Path, typer.Argument(
    help="household folder to write (new or empty): nodes.csv, train/, test/, import.json")]
ObjectsOption = Annotated[Path | None, typer.Option(
    "--objects", help="CSV sensor,object[,room][,furniture]: the sensors that are objects (default: by sensor type, "
                      "see docs/your-home.md)")]
StepOption = Annotated[int, typer.Option("--step", help="minutes between rows (1, 2, 5, 10, ...; must divide the day)")]
DayStartOption = Annotated[str, typer.Option("--day-start", help="first row of a day, HH:MM")]
DayEndOption = Annotated[str, typer.Option("--day-end", help="last row of a day, HH:MM (24:00 = midnight)")]
TestDaysOption = Annotated[int | None, typer.Option("--test-days", help="the last N kept days are test days")]
TestFractionOption = Annotated[float | None, typer.Option(
    "--test-fraction", help=f"the last share of kept days that are test days (default {DEFAULT_TEST_FRACTION}, "
                            "at least one when two or more days are kept)")]
OverlapsOption = Annotated[str, typer.Option(
    "--overlaps", help="overlapping annotations: 'error', or 'latest' (the one that began last wins while it lasts)")]
UseOption = Annotated[str, typer.Option(
    "--use", help="'while-on': an object is in use in every step its sensor is on; 'start': only in the step a use "
                  "begins in (either way one use per switch-on)")]
MaxUseOption = Annotated[float | None, typer.Option(
    "--max-use-minutes", help="a use longer than this is a sensor left on, cut to its start and listed in "
                              "import.json (default: by each object's usual uses, see docs/your-home.md)")]
TestFromOption = Annotated[str | None, typer.Option(
    "--test-from", help="YYYY-MM-DD: the kept days from this date on are the test days (instead of --test-days or "
                        "--test-fraction)")]
UntilOption = Annotated[str | None, typer.Option(
    "--until", help="YYYY-MM-DD: leave out the days after this date (the date itself is kept)")]
UnlabelledOption = Annotated[str, typer.Option(
    "--unlabelled", help="days a sensor was heard on and nobody annotated: 'keep' writes them to unlabelled/ (no "
                         "activity column; 'globe recognise --label' labels them), 'drop' leaves them out")]
SkipBadLinesOption = Annotated[bool, typer.Option(
    "--skip-bad-lines", help="leave out lines that break a rule (corrupt values, times out of order, an annotation "
                             "that ends before it begins), listed in import.json, instead of stopping at the first")]


def _date(value: str | None, name: str) -> date | None:
    if value is None:
        return None
    try:
        if not re.fullmatch(r"\d{4}-\d{2}-\d{2}", value):
            raise ValueError
        return date.fromisoformat(value)
    except ValueError:
        raise typer.BadParameter(f"{value!r} is not a date YYYY-MM-DD", param_hint=f"'{name}'") from None


def _grid(step: int, day_start: str, day_end: str, test_days: int | None, test_fraction: float | None,
          overlaps: str, use: str = "while-on", max_use_minutes: float | None = None, test_from: str | None = None,
          until: str | None = None, unlabelled: str = "keep") -> GridOptions:
    """The grid options from the command line (parsing only; GridOptions.check judges them)."""
    minutes = {}
    for name, value in (("--day-start", day_start), ("--day-end", day_end)):
        try:
            minutes[name] = parse_clock(value)
        except ValueError as err:
            raise typer.BadParameter(str(err), param_hint=f"'{name}'") from None
    if test_days is not None and test_fraction is not None:
        raise typer.BadParameter("give --test-days or --test-fraction, not both", param_hint="'--test-days'")
    if test_from is not None and (test_days is not None or test_fraction is not None):
        raise typer.BadParameter("give --test-from, --test-days or --test-fraction, not two",
                                 param_hint="'--test-from'")
    if overlaps not in ("error", "latest"):
        raise typer.BadParameter(f"{overlaps!r} is not 'error' or 'latest'", param_hint="'--overlaps'")
    mode = next((m for m in USE_MODES if m == use), None)
    if mode is None:
        raise typer.BadParameter(f"{use!r} is not 'while-on' or 'start'", param_hint="'--use'")
    keep = next((m for m in UNLABELLED_MODES if m == unlabelled), None)
    if keep is None:
        raise typer.BadParameter(f"{unlabelled!r} is not 'keep' or 'drop'", param_hint="'--unlabelled'")
    if max_use_minutes is not None and not max_use_minutes > 0:
        raise typer.BadParameter(f"{max_use_minutes:g} is not more than 0", param_hint="'--max-use-minutes'")
    fraction = DEFAULT_TEST_FRACTION if test_fraction is None else test_fraction
    return GridOptions(step_minutes=step, day_start_minute=minutes["--day-start"], day_end_minute=minutes["--day-end"],
                       test_days=test_days, test_fraction=fraction,
                       overlaps="latest" if overlaps == "latest" else "error", use=mode,
                       max_use_minutes=max_use_minutes, test_from=_date(test_from, "--test-from"),
                       until=_date(until, "--until"), unlabelled=keep)


def _summary(result: ImportResult) -> None:
    def say(text: str) -> None:
        out.print(text, markup=False, highlight=False, soft_wrap=True)

    objects = f"objects: {', '.join(result.objects)}" if result.objects else "no objects"
    say(f"wrote {result.train_days} training and {count(result.test_days, 'test day')} to {result.dest} "
        f"({objects}; activities: {', '.join(result.activities)})")
    if result.unlabelled_days:
        say(f"kept {count(result.unlabelled_days, 'day')} with sensor records and no annotation in "
            f"{result.dest / 'unlabelled'} (not training or test days; 'globe recognise --label' labels them)")
    if result.dropped_days:
        say(f"left out {count(result.dropped_days, 'day')} (unannotated, only carrying an annotation over from the day "
            f"before, not covered by the log from first to last row, or after --until): see {result.report}")
    if result.bad_lines:
        say(f"left out {count(result.bad_lines, 'bad line')} (--skip-bad-lines), the first: {result.first_bad_line}; "
            f"all in {result.report} (bad_lines)")
    if result.left_on:
        say(f"cut {count(result.left_on, 'use')} far longer than its object's usual to its start (a sensor left on?): "
            f"see {result.report} (left_on)")
    for note in result.notes:
        say(f"note: {note}")


@import_app.command("casas")
def import_casas_cmd(
    log_file: Annotated[Path, typer.Argument(help="a CASAS event log: date time sensor value [activity begin|end]")],
    dest: DestArgument,
    objects: ObjectsOption = None,
    step: StepOption = DEFAULT_STEP_MINUTES,
    day_start: DayStartOption = "06:00",
    day_end: DayEndOption = "24:00",
    test_days: TestDaysOption = None,
    test_fraction: TestFractionOption = None,
    overlaps: OverlapsOption = "error",
    use: UseOption = "while-on",
    max_use_minutes: MaxUseOption = None,
    test_from: TestFromOption = None,
    until: UntilOption = None,
    unlabelled: UnlabelledOption = "keep",
    skip_bad_lines: SkipBadLinesOption = False,
    timezone: Annotated[str | None, typer.Option("--timezone", help="the IANA time zone of the log's local times, "
                                                                    "so that the hour logged twice when the clocks go "
                                                                    "back is read in order")] = None,
    resident: Annotated[str | None, typer.Option("--resident", help="in a multi-resident log, the resident whose "
                                                                    "annotations to take (R1: R1_Sleep becomes Sleep; "
                                                                    "other residents' are left out)")] = None,
) -> None:
    """A CASAS event log (without --objects, item sensors I... are the objects)."""
    options = _grid(step, day_start, day_end, test_days, test_fraction, overlaps, use, max_use_minutes, test_from,
                    until, unlabelled)
    _summary(import_casas(log_file=log_file, dest=dest, options=options, objects=objects,
                          skip_bad_lines=skip_bad_lines, timezone=timezone, resident=resident))


@import_app.command("kasteren")
def import_kasteren_cmd(
    sensors: Annotated[Path, typer.Argument(help="sensor intervals: start end id [1], or start end Location Type "
                                                 "Place")],
    activities: Annotated[Path, typer.Argument(help="activity intervals: start end activity (or id)")],
    dest: DestArgument,
    sensor_list: Annotated[Path | None, typer.Option("--sensor-list", help="CSV sensor,name[,type][,room] for "
                                                                           "numeric sensor ids")] = None,
    activity_list: Annotated[Path | None, typer.Option("--activity-list", help="CSV id,activity for numeric "
                                                                               "activity ids")] = None,
    allow_numeric_labels: Annotated[bool, typer.Option(
        "--allow-numeric-labels", help="keep numbered activities that no list names as the activities ('1', '10', "
                                       "...) instead of refusing them")] = False,
    objects: ObjectsOption = None,
    step: StepOption = DEFAULT_STEP_MINUTES,
    day_start: DayStartOption = "06:00",
    day_end: DayEndOption = "24:00",
    test_days: TestDaysOption = None,
    test_fraction: TestFractionOption = None,
    overlaps: OverlapsOption = "error",
    use: UseOption = "while-on",
    max_use_minutes: MaxUseOption = None,
    test_from: TestFromOption = None,
    until: UntilOption = None,
    unlabelled: UnlabelledOption = "keep",
    skip_bad_lines: SkipBadLinesOption = False,
) -> None:
    """A van Kasteren or Ordóñez interval log (without --objects, contact and electric sensors are the objects).

    Doors are left out; the report lists every sensor and why. Files with their own id lists need no lists.
    """
    options = _grid(step, day_start, day_end, test_days, test_fraction, overlaps, use, max_use_minutes, test_from,
                    until, unlabelled)
    _summary(import_kasteren(sensors_file=sensors, activities_file=activities, dest=dest, options=options,
                             objects=objects, sensor_list=sensor_list, activity_list=activity_list,
                             skip_bad_lines=skip_bad_lines, allow_numeric_labels=allow_numeric_labels))


@import_app.command("home-assistant")
def import_home_assistant_cmd(
    history: Annotated[Path, typer.Argument(help="a Home Assistant history CSV: entity_id,state,last_changed")],
    dest: DestArgument,
    activity_entity: Annotated[str, typer.Option("--activity-entity", help="the entity whose state is the activity, "
                                                                           "e.g. input_select.activity")],
    timezone: Annotated[str | None, typer.Option("--timezone", help="the home's IANA time zone (required when "
                                                                    "timestamps carry a UTC offset)")] = None,
    objects: ObjectsOption = None,
    step: StepOption = DEFAULT_STEP_MINUTES,
    day_start: DayStartOption = "06:00",
    day_end: DayEndOption = "24:00",
    test_days: TestDaysOption = None,
    test_fraction: TestFractionOption = None,
    overlaps: OverlapsOption = "error",
    use: UseOption = "while-on",
    max_use_minutes: MaxUseOption = None,
    test_from: TestFromOption = None,
    until: UntilOption = None,
    unlabelled: UnlabelledOption = "keep",
    skip_bad_lines: SkipBadLinesOption = False,
) -> None:
    """A Home Assistant history export (objects only from --objects)."""
    options = _grid(step, day_start, day_end, test_days, test_fraction, overlaps, use, max_use_minutes, test_from,
                    until, unlabelled)
    _summary(import_home_assistant(history=history, dest=dest, activity_entity=activity_entity, options=options,
                                   objects=objects, timezone=timezone, skip_bad_lines=skip_bad_lines))
