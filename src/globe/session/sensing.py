"""A household's ambient sensors in its session: what makes a home nobody labels still predictable.

A household whose folder has sensors (``sensors.csv``, ``events/<day>.csv``;
:mod:`globe.data.sensors`) gets a :class:`SessionSensors`: the step features of
:mod:`globe.recognition.features` for the recogniser's chosen settings (chosen by
cross-validation on the labelled training days where the household is created,
:func:`globe.evaluation.recognition.choose_settings`, and passed down as the deployment is) and a
:class:`~globe.recognition.emission.SensorEmission` (or the discriminative emission, where chosen)
counted on the labelled training days, with, where chosen, each step's evidence on the change after
it (:class:`~globe.recognition.edges.SensorEdges`). The session's one activity filter takes each
step's likelihood from it beside the step's label and object movements (and the step before's
evidence on each change into it); both learn each finished day from its labelled and answered
steps (an answer labels the whole stretch read as one activity, as :meth:`Recogniser.fit` reads
answers), and the day's worths of asking join the reference the question policy paces itself by.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import asdict, dataclass
from typing import Sequence

import numpy as np

from globe.data.records import Day
from globe.data.sensors import Sensor, SensorData, SensorDay
from globe.inference.activity_filter import ActivityFilter
from globe.recognition.asking import QuestionPolicy, worth
from globe.recognition.features import Layout, step_features
from globe.recognition.recogniser import RecognitionSettings, run_days, sensor_edges, sensor_emission

MAX_OPTIONS = 5
"""The likely activities a question offers, at most."""


@dataclass(frozen=True, slots=True)
class SensorEvent:
    """One sensor activation as a client reports it: the sensor's name, when it began and ended
    (wall times in the household's zone, or aware; a firing has ``end == start``)."""

    sensor: str
    start: dt.datetime
    end: dt.datetime


@dataclass(frozen=True, slots=True)
class Question:
    """"What are you doing?" at ``step`` of ``day``: the likely activities, best first."""

    day: str
    step: int
    options: tuple[tuple[str, float], ...]


def settings_to_dict(settings: RecognitionSettings) -> dict[str, object]:
    """The recogniser's settings as stored with a household (JSON)."""
    return {**asdict(settings), "features": list(settings.features)}  # every field: none forgotten


def settings_from_dict(found: object) -> RecognitionSettings:
    """Stored settings back (a :class:`ValueError` naming what is wrong otherwise)."""
    if not isinstance(found, dict):
        raise ValueError("the stored recognition settings are not a JSON object")
    fields = set(RecognitionSettings.__dataclass_fields__)
    unknown = set(found) - fields
    if unknown:
        raise ValueError(f"unknown recognition settings {sorted(unknown)}")
    values = dict(found)
    if "features" in values:
        values["features"] = tuple(values["features"])
    settings = RecognitionSettings(**values)
    Layout.of((), settings.features)  # checks the feature names
    sensor_emission(settings)  # ... and the emission's kind
    return settings


class SessionSensors:
    """A household's sensors, its feature layout and its sensor emission (see module doc)."""

    def __init__(self, sensors: Sequence[Sensor], settings: RecognitionSettings, step_minutes: int,
                 budget: int = 0, change_floor: float = 0.0) -> None:
        if budget < 0:
            raise ValueError(f"a budget of {budget} questions a day; expected 0 or more")
        self.sensors = tuple(sensors)
        self.settings = settings
        self.step_minutes = step_minutes
        self.budget = budget
        self.change_floor = change_floor  # the session's filter reads the sensors with it (filter.change_floor)
        self.layout = Layout.of(self.sensors, settings.features)
        self.index = {s.name: i for i, s in enumerate(self.sensors)}
        self.reference = np.zeros(0)  # worths of asking seen on the days lived so far
        self._days = 0
        self.emission = sensor_emission(settings).fit([], [], self.layout.sizes)
        edges = sensor_edges(settings)
        self.edges = None if edges is None else edges.fit([], [], self.layout.sizes)

    def features(self, day: SensorDay | None, minutes: Sequence[int]) -> np.ndarray:
        """(steps x columns) features of the steps starting at ``minutes``."""
        return step_features(self.layout, day, minutes, self.step_minutes)

    def likelihoods(self, features: np.ndarray, labels: Sequence[str]) -> np.ndarray:
        """(steps x ``labels``): the likelihood of each step's features under each activity (at
        most 1; every step of a stretch at once, one array operation)."""
        return self.emission.likelihoods(features, labels)

    def edge_tables(self, features: np.ndarray, labels: Sequence[str]) -> np.ndarray | None:
        """(steps x ``labels`` x ``labels``): each step's evidence on the change after it (the
        filter takes step t's at step t + 1), or None where the settings read none."""
        return None if self.edges is None else self.edges.tables(features, labels)

    def learn(self, features: Sequence[np.ndarray], labels: Sequence[Sequence[str | None]]) -> None:
        """Count days' features against their labels (None: an unlabelled step) into the emission."""
        self.emission.partial_fit(features, labels, self.layout.sizes)
        if self.edges is not None:
            self.edges.partial_fit(features, labels, self.layout.sizes)
        self._days += len(features)

    def learn_days(self, days: Sequence[Day], data: SensorData) -> None:
        """Count the recorded ones of labelled ``days`` (their events in ``data``)."""
        found = [(d, data.of(d.name)) for d in days]
        kept = [(d, e) for d, e in found if e is not None]
        self.learn([self.features(e, d.minutes) for d, e in kept], [d.activities for d, _ in kept])

    @property
    def days_counted(self) -> int:
        return self._days

    def policy(self) -> QuestionPolicy | None:
        """Today's question policy (None: no questions)."""
        return QuestionPolicy(self.budget, self.reference) if self.budget > 0 else None

    def add_reference(self, worths: Sequence[float] | np.ndarray) -> None:
        self.reference = np.concatenate([self.reference, np.asarray(worths, dtype=np.float64)])

    def reference_from(self, flt: ActivityFilter, days: Sequence[Day], data: SensorData) -> None:
        """The worths of asking on ``days`` read online with their sensors only (no label): how
        unsure the household's recogniser usually is, so the first day's questions are paced."""
        recorded = [(d, data.of(d.name)) for d in days]
        recorded = [(d, e) for d, e in recorded if e is not None and len(d)]
        if not recorded or self.budget <= 0:
            return
        labels = list(flt.labels)
        features = [self.features(e, d.minutes) for d, e in recorded]
        likes = [self.emission.likelihoods(x, labels) for x in features]
        edges = None if self.edges is None else [self.edges.tables(x, labels) for x in features]
        posteriors = run_days(flt, likes, [d.weekday for d, _ in recorded], edges=edges)
        counts = self.emission.labelled_steps(labels)
        self.add_reference(np.concatenate([worth(p, counts) for p in posteriors]))


def seconds_after_midnight(time: dt.datetime, day: str) -> float:
    """``time`` (a wall time in the household's zone) as seconds after the midnight of ``day``."""
    wall = time.replace(tzinfo=None)
    return (wall - dt.datetime.combine(dt.date.fromisoformat(day), dt.time())).total_seconds()
