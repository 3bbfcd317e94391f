"""A household's session from its map, its training days and its deployment: every part built by
:mod:`globe.assembly` from the configuration with the deployment applied
(:meth:`globe.config.GlobeConfig.deployed`), on the household's own grid; a household with ambient
sensors also gets its sensor emission (:mod:`globe.session.sensing`), with the recogniser's settings
as chosen where the household was created (the default otherwise)."""

from __future__ import annotations

from globe import assembly
from globe.config import Deployment, GlobeConfig, ModelConfig
from globe.data.csv_logs import household_step
from globe.data.records import Household
from globe.data.sensors import SensorData
from globe.inference.activity_filter import ActivityFilter
from globe.reasoning.backends.base import LLMBackend
from globe.recognition.recogniser import RecognitionSettings
from globe.session.grid import DayGrid, check_grid, household_grid
from globe.session.records import NewActivities
from globe.session.sensing import SessionSensors
from globe.session.session import HouseholdSession


def session_grid(household: Household, config: GlobeConfig, stored: DayGrid | None = None) -> DayGrid:
    """The grid ``household`` runs on: ``stored`` (the service keeps each household's), else its
    training days' (:func:`globe.session.grid.household_grid`), checked against the configured
    ``service.step_minutes`` and ``service.day_start_minute``."""
    s = config.service
    if stored is not None:
        return check_grid(stored, s.step_minutes, s.day_start_minute, household.name)
    return household_grid(household.train, config.data.step_minutes or household_step(household.train),
                          configured_step=s.step_minutes, configured_start=s.day_start_minute, name=household.name)


def new_activities_rule(config: GlobeConfig, has_days: bool) -> NewActivities:
    """``service.new_activities`` for a household created with (or without) training days."""
    rule = config.service.new_activities
    if rule == "auto":
        return "refuse" if has_days else "learn"
    return rule


def build_session(household: Household, config: GlobeConfig, deployment: Deployment, backend: LLMBackend | None, *,
                  grid: DayGrid | None = None, learn: bool = True,
                  new_activities: NewActivities | None = None, sensors: SensorData | None = None,
                  recognition: RecognitionSettings | None = None,
                  questions_per_day: int | None = None) -> HouseholdSession:
    """The session of ``household`` running ``deployment`` (its models counted on its training
    days), with ``backend`` behind the object gate (None: the n-gram's choice). With ``sensors``
    (the household's, with its training days' events), its sensor emission is counted on its
    labelled training days with the ``recognition`` settings (chosen by cross-validation where the
    household is created; default: :class:`RecognitionSettings`'s), asking at most
    ``questions_per_day`` a day (default ``service.questions_per_day``)."""
    grid = session_grid(household, config, grid)
    cfg = config.deployed(deployment)
    cfg = cfg.model_copy(update={"data": cfg.data.model_copy(update={"step_minutes": grid.step_minutes})})
    fitted = assembly.fit_household(household, cfg)
    chooser = assembly.object_chooser(fitted.objects, cfg.gate, backend, marginal=cfg.models.object_marginal)
    emission = assembly.household_emission(cfg.filter).fit(household.train, household.objects, fitted.sequences.moves)
    movements = assembly.movement_model(cfg.lookahead, grid.step_minutes, *deployment.movement).fit(
        fitted.sequences.packed, household.objects)
    policy = assembly.fetch_policy(assembly.forecaster_over(fitted.activity, movements, cfg.lookahead), cfg.policy,
                                   grid.step_minutes, household.train if deployment.fetch_objects == "clock" else None)
    fc = cfg.filter
    sensing = None
    if sensors is not None:
        budget = config.service.questions_per_day if questions_per_day is None else questions_per_day
        sensing = SessionSensors(sensors.sensors, recognition or RecognitionSettings(), grid.step_minutes, budget,
                                 fc.change_floor)
        sensing.learn_days(household.train, sensors)
    session = HouseholdSession(household, activity=fitted.activity, chooser=chooser, emission=emission,
                               policy=policy, grid=grid, deployment=deployment, alignment=cfg.sequences.alignment,
                               max_hypotheses=fc.max_hypotheses, min_weight=fc.min_weight,
                               forecast_hypotheses=fc.forecast_hypotheses, learn=learn,
                               new_activities=new_activities or new_activities_rule(config, bool(household.train)),
                               sensing=sensing)
    if sensing is not None and sensors is not None and household.train and sensing.budget > 0:
        reference = ActivityFilter(fitted.activity, max_hypotheses=fc.max_hypotheses, min_weight=fc.min_weight,
                                   change_floor=sensing.change_floor)
        sensing.reference_from(reference, household.train, sensors)
    return session


def activity_model_summary(models: ModelConfig) -> str:
    """The activity model of ``models`` in words, with its units."""
    m = models
    if m.activity_estimator == "persistence":
        return "persistence (the activity goes on)"
    if m.activity_estimator == "longest":
        return "the paper's n-gram (longest context seen)"
    if m.activity_estimator == "witten_bell":
        timed = f", time of day weighted {m.time_weight:g}" if m.time_weight else ""
        return f"a smoothed n-gram (up to {m.activity_max_order} steps back{timed})"
    if m.activity_estimator == "routine":
        return f"the routine model (the last {m.routine_order} activities, how long each lasts, the time of day)"
    days = {"none": "", "weekend": ", weekends apart", "weekday": ", each weekday apart"}[m.clock_day_types]
    if not m.clock_by_activity:
        return f"the time of day alone ({m.clock_slot_minutes}-minute slots of the day{days}, whatever is under way)"
    return f"the clock model ({m.clock_slot_minutes}-minute slots of the day{days})"


def deployment_summary(deployment: Deployment) -> str:
    """What a household runs, in words: its activity and object models and how they were chosen."""
    d = deployment
    estimator = "Witten-Bell" if d.models.object_estimator == "witten_bell" else "longest-context"
    objects = "the most frequent use given the hour and the activity" if d.models.object_model == "hour_activity" \
        else f"a {estimator} n-gram per activity"
    how = "chosen by cross-validation on its training days" if d.cross_validated else "as configured"
    note = f" ({d.note})" if d.note else ""
    fetch = "; fetches by the clock-aware uses model" if d.fetch_objects == "clock" else ""
    return f"{activity_model_summary(d.models)}; objects by {objects}{fetch}; {how}{note}"
