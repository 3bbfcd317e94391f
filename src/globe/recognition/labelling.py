"""Labelling the days nobody labelled, with hindsight, so the rest of GLOBE can learn from them.

A home imported with ``--unlabelled keep`` has days the sensors recorded and nobody annotated
(``unlabelled/<day>.csv``, :func:`globe.data.sensors.read_unlabelled_days`). A recogniser chosen
and fitted on the labelled training days reads each of them with hindsight: GLOBE's own (its
settings, self-training on these days included, chosen by cross-validation on them), or a
library's linear-chain CRF or plain HMM where cross-validation on the labelled days says it reads
them better (:func:`globe.evaluation.recognition.choose_labeller`, any :class:`Labeller`). The
labels are the most probable sequence of activities (its ``decode``), and each step's probability
that of its label with every path summed (its ``smooth``, exact forward-backward), which says how
sure the label is (measured for GLOBE's: the steps at 0.9 or more are right more often).

:func:`write_labelled` writes the result as a household folder any GLOBE command loads
(:func:`globe.data.csv_logs.load_household`): the source's files as they are, each recognised day
a training day file (``train/<day>.csv``), and beside it ``recognised/<day>.csv``
(``minute,activity,probability``: the posterior of the activity written, so a user, or a later
filter, can tell a confident step from a guess) and ``recognised.json`` (how they were labelled).
The test days stay as annotated: nothing here reads them.
"""

from __future__ import annotations

import json
import os
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol, Sequence

import numpy as np

from globe.data.csv_logs import _csv_line, _write_atomic, write_day
from globe.data.records import Day, Household
from globe.data.sensors import EVENTS_FOLDER, UNLABELLED_FOLDER, day_stem
from globe.errors import DataError

RECOGNISED_FOLDER, RECOGNISED_FILE = "recognised", "recognised.json"


class Labeller(Protocol):
    """What reads a day with hindsight: GLOBE's :class:`~globe.recognition.recogniser.Recogniser`
    or a library's (:mod:`globe.recognition.library`)."""

    @property
    def labels(self) -> Sequence[str]:
        """The activities of every array returned (columns)."""

    def decode(self, days: Sequence[Day]) -> list[np.ndarray]:
        """Per day, (steps x labels) whose row argmax is the most probable sequence."""

    def smooth(self, days: Sequence[Day]) -> list[np.ndarray]:
        """Per day, (steps x labels): each step's probability given the whole day."""

    def describe(self) -> dict[str, Any]:
        """What was fitted, for ``recognised.json``."""


@dataclass(frozen=True, slots=True)
class RecognisedDay:
    """An unlabelled day labelled: a training day (``train/<day>``) whose activities are the
    most probable with hindsight, and each step's posterior of that activity."""

    day: Day
    probability: tuple[float, ...]

    @property
    def mean_probability(self) -> float:
        return float(np.mean(self.probability)) if self.probability else 0.0


def recognise_days(recogniser: Labeller, days: Sequence[Day]) -> list[RecognisedDay]:
    """Each of ``days`` (unlabelled, with recorded sensors) labelled by ``recogniser`` with
    hindsight: the most probable sequence (:meth:`~globe.recognition.recogniser.Recogniser.decode`),
    each step's probability that of its label with every path summed (``smooth``)."""
    names = recogniser.labels
    out = []
    for day, path, post in zip(days, recogniser.decode(days), recogniser.smooth(days)):
        best = path.argmax(axis=1)
        activities = tuple(names[i] for i in best.tolist())
        probability = tuple(round(float(p), 4) for p in post[np.arange(len(best)), best].tolist())
        out.append(RecognisedDay(Day(f"train/{day_stem(day.name)}", day.minutes, activities, day.locations,
                                     day.source), probability))
    return out


def before_test(household: Household, days: Sequence[Day]) -> tuple[list[Day], list[Day]]:
    """``days`` split into those that may become training days and those left out: a day dated on
    or after the household's first dated test day would put the future into training (the test
    days must stay later than every training day), so it is not labelled into ``train/``."""
    dates = [d.calendar_date for d in household.test if d.calendar_date is not None]
    if not dates:
        return list(days), []
    first = min(dates)
    keep = [d for d in days if d.calendar_date is None or d.calendar_date < first]
    return keep, [d for d in days if d not in keep]


def format_recognised(found: RecognisedDay) -> str:
    """``recognised/<day>.csv``: per step its minute, the activity written and its posterior."""
    lines = [_csv_line(("minute", "activity", "probability"))]
    lines += [_csv_line((m, a, f"{p:.4f}")) for m, a, p in zip(found.day.minutes, found.day.activities,
                                                             found.probability)]
    return "\n".join(lines) + "\n"


def write_labelled(household: Household, recognised: Sequence[RecognisedDay], dest: Path,
                   summary: dict[str, Any]) -> Path:
    """Write the household folder ``dest`` (new or empty): the files of ``household``'s folder but
    its unlabelled days, and the ``recognised`` days as training days with their companions (see
    module doc); ``summary`` (how the recogniser was chosen) goes into ``recognised.json``."""
    source, dest = Path(household.source), Path(dest)
    if dest.exists() and (not dest.is_dir() or any(dest.iterdir())):
        raise DataError("already exists and is not an empty folder; label into a new folder", source=str(dest))
    if dest.resolve() == source.resolve():
        raise DataError("is the household's own folder; label into a new folder", source=str(dest))
    labelled = {day_stem(d.name) for d in household.train + household.test}
    for found in recognised:
        if day_stem(found.day.name) in labelled:
            raise DataError(f"{day_stem(found.day.name)} is a labelled day already", source=str(source))
    tmp = dest.parent / f".{dest.name}.labelling-{os.getpid()}"
    shutil.rmtree(tmp, ignore_errors=True)
    dest.parent.mkdir(parents=True, exist_ok=True)
    try:
        shutil.copytree(source, tmp, ignore=lambda folder, names: [
            n for n in names if Path(folder) == source and n.lower() in (UNLABELLED_FOLDER, RECOGNISED_FOLDER,
                                                                         RECOGNISED_FILE)])
        for found in recognised:
            stem = day_stem(found.day.name)
            write_day(tmp / "train" / f"{stem}.csv", found.day, household.objects)
            _write_atomic(tmp / RECOGNISED_FOLDER / f"{stem}.csv", format_recognised(found))
        report = {**summary, "source": str(source), "days": {
            day_stem(f.day.name): {"mean_probability": round(f.mean_probability, 4),
                                   "activities": sorted(set(f.day.activities))} for f in recognised},
            "events": EVENTS_FOLDER, "rule": "the most probable sequence of activities, read with hindsight from "
                                             "the day's sensors; probability: each step's, every path summed"}
        _write_atomic(tmp / RECOGNISED_FILE, json.dumps(report, indent=2, ensure_ascii=False) + "\n")
        if dest.exists():
            dest.rmdir()
        tmp.rename(dest)
    except OSError as err:
        shutil.rmtree(tmp, ignore_errors=True)
        raise DataError(f"cannot write the labelled household: {err.strerror or err}", source=str(dest)) from None
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return dest
