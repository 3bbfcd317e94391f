"""The robot's fetch decision: fetch when the expected value is positive.

A single threshold on the next-object probability cannot be reasoned about: it says nothing
about *when* the object will be needed or what a wrong fetch costs. Here each candidate fetch
(every tracked object, brought to where it is likely to be needed) gets the probability that
it is *useful*: the person first takes it from where it is now within the lead window, but not
sooner than the robot needs to get it there (``min_lead_steps``). With the cost of a useless
fetch c_u and of a need the robot missed c_m,

    E[fetch] - E[no fetch] = p * c_m - (1 - p) * c_u > 0   <=>   p > c_u / (c_u + c_m),

so the robot team sets two costs, not a bare threshold. Probabilities come from the
:class:`~globe.inference.forecast.Forecaster`, which propagates the activity distribution ahead,
or, where the household's cross-validation chose it (a home whose uses follow the clock), from a
uses model (``uses``: :class:`~globe.models.baselines.HourActivityAhead`, P(a use within the lead
window | the activity, the clock slot, the day type, the time since each object's last use)). The
policy owns that choice, so the session that serves a home and the evaluation that scores it
fetch from the same candidates (:meth:`FetchPolicy.candidates_at`).
"""

from __future__ import annotations

import functools
import statistics
from dataclasses import dataclass, field
from typing import Callable, Collection, Mapping, Sequence

import numpy as np

from globe.data.records import Day
from globe.inference.forecast import Forecast, Forecaster
from globe.models.baselines import HourActivityAhead, fit_uses_ahead


@dataclass(frozen=True, slots=True)
class FetchCandidate:
    """One possible fetch: the object, P(it is useful), where to bring it, and its value."""

    obj: str
    probability: float
    to_location: str | None
    expected_value: float


def expected_value(probability: np.ndarray, cost_useless: float, cost_missed: float) -> np.ndarray:
    """Value of fetching over not fetching: a missed need avoided, minus a useless trip risked."""
    return probability * cost_missed - (1.0 - probability) * cost_useless


@dataclass(frozen=True, slots=True)
class FetchContext:
    """What the candidates of a step may be read from: the activity under way at the step, its
    clock minute, the day's weekday (None: undated), the minutes since each object's last use
    that day (-1: not used yet; :func:`~globe.models.baselines.minutes_since_use`) and the
    forecast ``horizon`` steps ahead (asked only by the movement candidates: it costs most)."""

    activity: str
    minute: int
    weekday: int | None
    since: np.ndarray
    forecast: Callable[[int], Forecast]


class FetchPolicy:
    """Per step, which objects to fetch now (see module doc). Call :meth:`decide` after each
    observation with the day's activities and object locations so far."""

    def __init__(self, forecaster: Forecaster, *, cost_useless: float = 3.0, cost_missed: float = 1.0,
                 min_lead_steps: int = 1, window_steps: int = 6, max_fetches_per_step: int = 2,
                 uses: HourActivityAhead | None = None) -> None:
        if cost_useless < 0 or cost_missed < 0:
            raise ValueError("fetch costs must be >= 0")
        if window_steps < max(min_lead_steps, 1):
            raise ValueError(f"the lead window ({window_steps} steps) ends before the minimum lead "
                             f"({min_lead_steps} steps)")
        self.forecaster = forecaster
        self.cost_useless = cost_useless
        self.cost_missed = cost_missed
        self.min_lead_steps = max(1, min_lead_steps)
        self.window_steps = window_steps
        self.max_fetches_per_step = max_fetches_per_step
        self.uses = uses

    @property
    def source(self) -> str:
        """Where the candidates come from: ``"movements"`` (the forecaster) or ``"clock"`` (the uses model)."""
        return "movements" if self.uses is None else "clock"

    def with_costs(self, cost_useless: float, cost_missed: float) -> "FetchPolicy":
        """The same policy (candidates, lead times, cap) at other costs."""
        return FetchPolicy(self.forecaster, cost_useless=cost_useless, cost_missed=cost_missed,
                           min_lead_steps=self.min_lead_steps, window_steps=self.window_steps,
                           max_fetches_per_step=self.max_fetches_per_step, uses=self.uses)

    def learn(self, days: Sequence[Day]) -> None:
        """Add finished days to the movement model and the uses model (a household's session
        learning as it goes; the activity model is shared with the session, which updates it)."""
        movements = self.forecaster.movements
        movements.partial_fit(days, movements.objects_)
        if self.uses is not None:
            fit_uses_ahead(days, self.uses.objects, self.min_lead_steps, self.window_steps, ahead=self.uses)

    @property
    def threshold(self) -> float:
        """The usefulness probability above which a fetch has positive expected value."""
        total = self.cost_useless + self.cost_missed
        return self.cost_useless / total if total > 0 else 1.0

    def forecast(self, activities: Sequence[str], locations: Sequence[Sequence[str]],
                 weekday: int | None = None) -> Forecast:
        """The forecast the decision is read from (the activity of the last step is known)."""
        return self.forecaster.forecast(activities, locations, self.window_steps - 1, weekday)

    def candidates(self, activities: Sequence[str], locations: Sequence[Sequence[str]],
                   weekday: int | None = None) -> list[FetchCandidate]:
        """Every tracked object as a candidate fetch by the movement forecast, most likely useful
        first (a session reads the policy's own source: :meth:`candidates_at`)."""
        return self.candidates_from(self.forecast(activities, locations, weekday))

    def candidates_at(self, now: FetchContext) -> list[FetchCandidate]:
        """The candidates of a step from the policy's own source: the uses model when it has one,
        else the forecast (``window_steps - 1`` steps ahead)."""
        if self.uses is not None:
            return self.candidates_from_uses(self.uses, now)
        return self.candidates_from(now.forecast(self.window_steps - 1))

    def candidates_from(self, forecast: Forecast) -> list[FetchCandidate]:
        p = forecast.useful_probability(self.min_lead_steps, self.window_steps)
        targets = forecast.likely_target(self.min_lead_steps, self.window_steps)
        return self._ranked(forecast.objects, p, targets)

    def candidates_from_uses(self, uses: HourActivityAhead, now: FetchContext) -> list[FetchCandidate]:
        """Every object as a candidate by ``uses`` (P(used within the lead window), no target
        place: the uses model does not say where)."""
        since = now.since if uses.clock else None
        p = uses.proba(now.activity, now.minute, now.weekday, since)[0]
        return self._ranked(uses.objects, p, [None] * len(p))

    def _ranked(self, objects: Sequence[str], p: np.ndarray, targets: Sequence[str | None]) -> list[FetchCandidate]:
        """Every object as a candidate, most likely useful first (ties: by name)."""
        p = np.asarray(p, dtype=float)
        ev = expected_value(p, self.cost_useless, self.cost_missed).tolist()
        order = np.lexsort((_name_ranks(tuple(objects)), -p)).tolist()
        probability = p.tolist()
        return [FetchCandidate(objects[j], probability[j], targets[j], ev[j]) for j in order]

    def choose(self, candidates: Sequence[FetchCandidate], exclude: Collection[str] = ()) -> list[FetchCandidate]:
        """The candidates worth fetching: positive expected value, not already fetched, at most
        ``max_fetches_per_step``, most likely useful first."""
        chosen: list[FetchCandidate] = []
        if self.max_fetches_per_step <= 0:
            return chosen
        for c in candidates:
            if c.obj not in exclude and self._worth(c.probability):
                chosen.append(c)
                if len(chosen) == self.max_fetches_per_step:
                    break
        return chosen

    def _worth(self, probability: float) -> bool:
        return probability * self.cost_missed - (1.0 - probability) * self.cost_useless > 0

    def decide(self, activities: Sequence[str], locations: Sequence[Sequence[str]],
               exclude: Collection[str] = (), weekday: int | None = None) -> list[FetchCandidate]:
        """What to fetch now, given the day so far (``activities`` and ``locations`` up to and
        including the current step, on a day of ``weekday``), leaving out objects already fetched
        (``exclude``)."""
        return self.choose(self.candidates(activities, locations, weekday), exclude)


@functools.lru_cache(maxsize=64)
def _name_ranks(objects: tuple[str, ...]) -> np.ndarray:
    """Each object's place in the sorted names (the candidates' tie-break), once per object list."""
    ranks = np.empty(len(objects), dtype=np.int64)
    ranks[sorted(range(len(objects)), key=objects.__getitem__)] = np.arange(len(objects))
    ranks.flags.writeable = False  # shared by every call with these objects
    return ranks


def left_alone(objects: Sequence[str], before: Sequence[str], now: Sequence[str],
               use_places: Collection[str]) -> frozenset[str]:
    """The objects no fetch may touch at a step: those in use now (at a place of class ``in_use``,
    where an imported sensor that is on puts its object) and those just put back (at one the step
    before): fetching them would carry away what the person holds, or count a return as a need.
    ``before`` and ``now``: every object's place at the step before and at this one."""
    if not use_places:
        return frozenset()
    return frozenset(o for o, b, n in zip(objects, before, now) if n in use_places or b in use_places)


@dataclass(slots=True)
class FetchReport:
    """What a robot team cares about, over some days: fetches and how many were useful, uses and
    how many had been fetched in advance (and how long before)."""

    steps: int = 0
    fetches: int = 0
    useful_fetches: int = 0
    used_objects: int = 0
    used_fetched_in_advance: int = 0
    lead_minutes: list[int] = field(default_factory=list)

    @property
    def precision(self) -> float:
        return self.useful_fetches / self.fetches if self.fetches else 0.0

    @property
    def recall(self) -> float:
        return self.used_fetched_in_advance / self.used_objects if self.used_objects else 0.0

    @property
    def median_lead_min(self) -> float | None:
        return float(statistics.median(self.lead_minutes)) if self.lead_minutes else None


Decide = Callable[[int, Mapping[str, int]], Sequence[str]]
"""``decide(t, waiting)``: the objects fetched after step t, given those fetched earlier and still
waiting for their use (object -> the step it was fetched)."""


def follow_fetches(uses: Sequence[Collection[str]], minutes: Sequence[int], decide: Decide, decided_steps: int,
                   min_lead: int, window: int, report: FetchReport | None = None
                   ) -> tuple[FetchReport, dict[str, int]]:
    """The one rule of a day's fetches, for the robot that decides them and for every score of them.

    ``uses[t]``: the objects used at step t (a use is an object leaving its place); ``minutes[t]``:
    when step t begins. After each step t < ``decided_steps``, ``decide`` names the fetches; a fetch
    of o at t is *useful* when o is used at a step u with min_lead <= u - t <= window. A use counts as
    *fetched in advance* when o had been fetched at a step t with min_lead <= u - t <= window. A
    fetched object *waits* for its use: it is not fetched again until it is used or its window has
    passed. Returns the report (added to ``report``) and what still waits after the last step."""
    report = FetchReport() if report is None else report
    lo = max(1, min_lead)
    used_at: dict[str, list[int]] = {}
    for t, objs in enumerate(uses):
        for obj in objs:
            used_at.setdefault(obj, []).append(t)
    waiting: dict[str, int] = {}
    for t, objs in enumerate(uses):
        for obj in sorted(objs):
            report.used_objects += 1
            fetched = waiting.pop(obj, None)
            if fetched is not None and lo <= t - fetched <= window:
                report.used_fetched_in_advance += 1
                report.lead_minutes.append(minutes[t] - minutes[fetched])
        for obj in [o for o, f in waiting.items() if t - f >= window]:
            del waiting[obj]
        if t >= decided_steps:
            continue
        report.steps += 1
        for obj in decide(t, waiting):
            if obj in waiting:  # a decision already waiting (recorded twice) counts once
                continue
            report.fetches += 1
            waiting[obj] = t
            report.useful_fetches += any(lo <= u - t <= window for u in used_at.get(obj, ()))
    return report, waiting
