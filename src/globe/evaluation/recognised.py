"""The evaluation with recognised activities (``globe evaluate --activities recognised``): what
GLOBE scores when nobody annotates the home and its activities come from the sensors.

The truth stays the annotation. What the models are shown of each test day is the activity the
recogniser (:mod:`globe.recognition`) read from the home's sensors *online*, step by step with no
look-ahead (filtering: what a live service would have known at each step), its most probable
activity per step, kept as the day's :attr:`~globe.data.records.Day.observed`; every table reads
:attr:`~globe.data.records.Day.seen` where it conditions on the activity and the annotation
where it scores. The recogniser's settings are chosen by cross-validation on the annotated
training days (:func:`~globe.evaluation.recognition.fit_recogniser`) and fitted on all of them;
the training days stay annotated, so every model is the one the annotated evaluation fits.
"""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Literal, Sequence

from globe import assembly
from globe.config import GlobeConfig
from globe.data.records import Household
from globe.data.sensors import SensorData, check_sensor_data
from globe.errors import ConfigError
from globe.evaluation import report
from globe.evaluation.published import DataScope
from globe.evaluation.recognition import Scores, fit_recogniser, recognition_scores
from globe.recognition.recogniser import RecognitionSettings

log = logging.getLogger("globe.stages")

Activities = Literal["annotated", "recognised"]
ACTIVITIES: tuple[Activities, ...] = ("annotated", "recognised")
RECOGNITION_COLUMNS = ("household", "test_days", "steps", "time_slice_accuracy", "class_accuracy", "settings")


@dataclass(frozen=True, slots=True)
class Recognised:
    """One household with its test days' activities recognised, and how well they were."""

    household: Household  # test days carrying ``observed``; training days as annotated
    scores: Scores  # online recognition of the test days against their annotation
    settings: dict  # what cross-validation chose (:meth:`~globe.recognition.recogniser.Recogniser.describe`)

    def row(self) -> dict:
        """A ``recognition.csv`` row."""
        test = self.household.test
        return {"household": self.household.name, "test_days": len(test), "steps": sum(len(d) for d in test),
                **self.scores.row(), "settings": json.dumps(self.settings, sort_keys=True)}


def sensors_of(household: Household, step_minutes: int) -> SensorData:
    """The household's sensor data (``sensors.csv`` and ``events/`` in its folder, every rule
    checked), or a :class:`~globe.errors.ConfigError` naming the household and the folder."""
    folder = household.source or "(no folder: the household was not read from one)"
    sensors = check_sensor_data(household, step_minutes) if household.source else None
    if sensors is None:
        raise ConfigError(f"household {household.name} has no sensor data to recognise its activities from (no "
                          f"sensors.csv in {folder}); HOMER+ has none: use --activities annotated, or import a home "
                          "with its sensors ('globe data import')")
    return sensors


def recognise_test_days(household: Household, sensors: SensorData, step_minutes: int,
                        options: Sequence[RecognitionSettings] | None = None) -> Recognised:
    """``household`` with each test day's ``observed`` set to the activities recognised online
    (see the module doc), the recogniser's settings chosen by cross-validation on the training
    days among ``options`` (default: :func:`~globe.evaluation.recognition.candidates`)."""
    if not household.train or not household.test:
        raise ConfigError(f"household {household.name}: recognising activities needs training and test days")
    recogniser = fit_recogniser(list(household.train), sensors, step_minutes, options=options)
    settings = recogniser.describe()
    log.info("%s: recogniser settings chosen on the training days: %s", household.name, settings)
    predicted = recogniser.predict(household.test)
    test = tuple(replace(day, observed=tuple(seen)) for day, seen in zip(household.test, predicted))
    scores = recognition_scores([a for d in household.test for a in d.activities], [a for p in predicted for a in p])
    return Recognised(replace(household, test=test), scores, settings)


def recognise_households(config: GlobeConfig, households: Sequence[Household],
                         options: Sequence[RecognitionSettings] | None = None) -> list[Recognised]:
    """:func:`recognise_test_days` for every household (each with its own step and sensors); a
    household without sensors is an error before any is recognised."""
    found = [(h, assembly.step_minutes(h, config)) for h in households]
    sensors = [sensors_of(h, step) for h, step in found]
    return [recognise_test_days(h, s, step, options) for (h, step), s in zip(found, sensors)]


def write_recognition(out_dir: Path, recognised: Sequence[Recognised]) -> Path:
    """``recognition.csv``: per household, the online recognition of its test days."""
    path = out_dir / "recognition.csv"
    report.write_csv(path, [r.row() for r in recognised], list(RECOGNITION_COLUMNS))
    return path


def activities_of(households: Sequence[Household]) -> Activities:
    """Which activities the models are shown on the test days of ``households``."""
    return "recognised" if any(d.observed is not None for h in households for d in h.test) else "annotated"


def scope_of(households: Sequence[Household]) -> DataScope:
    """:meth:`DataScope.of <globe.evaluation.published.DataScope.of>` ``households``, its title
    saying so when the test days' activities are recognised (every table and plot carries it)."""
    scope = DataScope.of(households)
    if activities_of(households) == "recognised":
        return replace(scope, title=f"{scope.title} (activities recognised from sensors)")
    return scope
