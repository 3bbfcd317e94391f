"""The evaluation with recognised activities (``globe evaluate --activities recognised``): what
GLOBE scores when nobody annotates the home and its activities come from the sensors.

The truth stays the annotation. What the models are shown of each test day is the activity the
household's session recognises at each step *as the service would*: the household is deployed
as ``globe train`` or ``POST /households`` deploys it (:func:`~globe.evaluation.deploy.choose_deployment`,
its recogniser's settings chosen by cross-validation on the annotated training days,
:func:`~globe.evaluation.recognition.choose_settings`), and each test day is replayed through its
:class:`~globe.session.HouseholdSession` with the sensor activations and object places of each
step and no label; the session's recognised activity after each step (its one activity filter:
the deployed activity model as the dynamics, the sensors and the objects' movements as the
evidence, no look-ahead) is kept as the day's :attr:`~globe.data.records.Day.observed`. Every
table reads :attr:`~globe.data.records.Day.seen` where it conditions on the activity and the
annotation where it scores; the training days stay annotated, so every model is the one the
annotated evaluation fits.

Where a Table I row is a method a household can be deployed with (:attr:`~globe.evaluation.methods.Method.deploys`),
its next activity is not the model's reading of the recognised activities but what the session
deployed with that method *says* after each step (:func:`served_scan`): the filter's predictive,
which weighs every history the sensors allow and reads the last step's sensors as evidence on
the change after it, kept at the recognised activity by the stay margin. That is what the
service serves a home with sensors and no labels, step for step. The baselines (and rows no
household runs) read the recognised activities as a person's rule would.
"""

from __future__ import annotations

import json
import logging
from collections import Counter
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Literal, Sequence

from globe import assembly
from globe.config import Deployment, DeployMethod, GlobeConfig
from globe.data.records import Day, Household
from globe.data.sensors import SensorData, check_sensor_data
from globe.errors import ConfigError, DataError
from globe.evaluation import report
from globe.evaluation.deploy import choose_deployment
from globe.evaluation.fetch import LAST_DATE
from globe.evaluation.online import day_observations, replay_dates
from globe.evaluation.protocol import FixedScan
from globe.evaluation.published import DataScope
from globe.evaluation.recognition import Scores, deployed_settings, recognition_scores
from globe.evaluation.selection import Memo
from globe.models.base import ActivityModelBase
from globe.recognition.recogniser import RecognitionSettings
from globe.session import build_session
from globe.session.build import activity_model_summary
from globe.session.sensing import settings_to_dict

log = logging.getLogger("globe.stages")

Activities = Literal["annotated", "recognised"]
ACTIVITIES: tuple[Activities, ...] = ("annotated", "recognised")
RECOGNITION_COLUMNS = ("household", "test_days", "steps", "time_slice_accuracy", "class_accuracy", "settings")


@dataclass(frozen=True, slots=True)
class ServedDay:
    """One test day as a household's session served it, asking nothing and told no label."""

    recognised: tuple[str, ...]  # after each step: the activity recognised there
    beliefs: tuple[dict[str, float], ...]  # after each step: P(the activity at the next step), as served


@dataclass(frozen=True, slots=True)
class ServedReplay:
    """The test days replayed through the session of one deployment (:func:`served_days`)."""

    deployment: Deployment
    config: GlobeConfig  # what else the session was built with (its filter's floor, its grid)
    model: ActivityModelBase  # the session's activity model: its ranking, and the day's first step
    days: tuple[ServedDay, ...]


@dataclass(frozen=True, slots=True)
class ServedRow:
    """What a Table I row is told of a recognised household's test days (:func:`served_scan`)."""

    predictor: FixedScan  # the next activity's distribution at each step, as served
    days: tuple[Day, ...]  # the test days, each seen as its session recognised it
    stay_margin: float  # the deployment's, which kept the served next activity at the recognised one


@dataclass(frozen=True, slots=True)
class Recognised:
    """One household with its test days' activities recognised, and how well they were."""

    household: Household  # test days carrying ``observed``; training days as annotated
    scores: Scores  # online recognition of the test days against their annotation
    settings: dict  # what cross-validation chose (:meth:`~globe.recognition.recogniser.Recogniser.describe`)
    sensors: SensorData  # the household's
    recognition: RecognitionSettings  # the recogniser's settings, as chosen
    replays: list[ServedReplay] = field(default_factory=list)  # one per deployment replayed, first the household's

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
                        options: Sequence[RecognitionSettings] | None = None, config: GlobeConfig | None = None,
                        memo: Memo | None = None) -> Recognised:
    """``household`` with each test day's ``observed`` set to the activities its session
    recognises online (see the module doc), deployed by ``config`` (default: the defaults) with
    the recogniser's settings chosen by cross-validation on the training days among ``options``
    (default: :func:`~globe.evaluation.recognition.candidates`); ``memo`` shares the deployment's
    cross-validation with the tables."""
    if not household.train or not household.test:
        raise ConfigError(f"household {household.name}: recognising activities needs training and test days")
    config = config or GlobeConfig()
    settings = deployed_settings(household, sensors, step_minutes, options)
    deployment = choose_deployment(household, config, memo)
    described = {**settings_to_dict(settings), "dynamics": activity_model_summary(deployment.models)}
    log.info("%s: recognised as served: %s", household.name, described)
    replay = served_days(household, sensors, config, deployment, settings)
    test = tuple(replace(day, observed=s.recognised) for day, s in zip(household.test, replay.days))
    scores = recognition_scores([a for d in household.test for a in d.activities],
                                [a for s in replay.days for a in s.recognised])
    return Recognised(replace(household, test=test), scores, described, sensors, settings, [replay])


def served_days(household: Household, sensors: SensorData, config: GlobeConfig, deployment: Deployment,
                settings: RecognitionSettings) -> ServedReplay:
    """Per test day of ``household``, what its session (built as the service builds it, running
    ``deployment``, asking nothing, learning nothing) recognises after each step and says of the
    next, the test days replayed in order on consecutive dates with each step's sensor
    activations (those beginning in it; the first step also those before it) and object places,
    and no label. Each row must be the session's next step (else a
    :class:`~globe.errors.DataError`): a belief is kept per row as P(the next row's activity)."""
    session = build_session(household, config, deployment, None, learn=False, sensors=sensors, recognition=settings,
                            questions_per_day=0)
    dates = replay_dates(household.test, LAST_DATE)  # as the fetch policy's replay
    # where the session says nothing (no belief yet), the training days' commonest activity, never the annotation
    usual = Counter(a for d in household.train for a in d.activities).most_common(1)[0][0]
    out = []
    for day, date in zip(household.test, dates):
        seen: list[str] = []
        beliefs: list[dict[str, float]] = []
        first: int | None = None  # the session's step of the day's first row (a day may begin late)
        for row, obs in day_observations(household, day, date, visible=lambda _row: False, sensors=sensors):
            session.observe(obs)
            step = session.step
            first = step - row if first is None and step is not None else first
            if step is None or first is None or step != first + row:
                raise DataError(f"row {row} ({day.minutes[row]} min) is step {step} of the household's "
                                f"{session.grid.step_minutes}-minute grid, not the step after the row before's: "
                                "the rows of a day recognised as served must follow its grid",
                                source=day.source or day.name, line=row + 2 if day.source else None, field="minute")
            found = session.recognised()
            seen.append(found[0] if found is not None else (seen[-1] if seen else usual))
            beliefs.append(dict(session.belief()))
        out.append(ServedDay(tuple(seen), tuple(beliefs)))
    return ServedReplay(deployment, config, session.activity_model, tuple(out))


def served_scan(recognised: Recognised, method: DeployMethod, config: GlobeConfig,
                memo: Memo | None = None) -> ServedRow:
    """What the Table I row of a method a household can be deployed with is told of
    ``recognised``'s test days: at each test step, what the session deployed with ``method`` (as
    ``globe train`` deploys it, the recogniser's settings as chosen) said of it after the step
    before (:func:`served_days`; the first step of a day, which nothing of the day precedes, as
    the session's activity model says it), each day seen as that session recognised it, and the
    deployment's stay margin: the row's next activity is the session's, step for step. A replay
    is kept per deployment and configuration."""
    household = recognised.household
    deployment = choose_deployment(household, config, memo, method)
    replay = next((r for r in recognised.replays if r.deployment == deployment and r.config == config), None)
    if replay is None:
        replay = served_days(household, recognised.sensors, config, deployment, recognised.recognition)
        recognised.replays.append(replay)
    pairs = list(zip(household.test, replay.days))
    dists = {day.name: [replay.model.predict_proba((), day.weekday), *s.beliefs[:-1]] for day, s in pairs}
    return ServedRow(FixedScan(replay.model, dists), tuple(replace(day, observed=s.recognised) for day, s in pairs),
                     deployment.models.stay_margin)


def recognise_households(config: GlobeConfig, households: Sequence[Household],
                         options: Sequence[RecognitionSettings] | None = None,
                         memo: Memo | None = None) -> list[Recognised]:
    """:func:`recognise_test_days` for every household (each with its own step and sensors); a
    household without sensors is an error before any is recognised."""
    found = [(h, assembly.step_minutes(h, config)) for h in households]
    sensors = [sensors_of(h, step) for h, step in found]
    return [recognise_test_days(h, s, step, options, config, memo) for (h, step), s in zip(found, sensors)]


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
