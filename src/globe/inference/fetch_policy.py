"""The robot's fetch decision: fetch when the expected value is positive.

A single threshold on the next-object probability cannot be reasoned about: it says nothing
about *when* the object will be needed or what a wrong fetch costs. Here each candidate fetch
(every tracked object, brought to where it is likely to be needed) gets the probability that
it is *useful*: the person first takes it from where it is now within the lead window, but not
sooner than the robot needs to get it there (``min_lead_steps``). With the cost of a useless
fetch c_u and of a need the robot missed c_m,

    E[fetch] - E[no fetch] = p * c_m - (1 - p) * c_u > 0   <=>   p > c_u / (c_u + c_m),

so the robot team sets two costs, not a bare threshold. Probabilities come from the
:class:`~globe.inference.forecast.Forecaster`, which propagates the activity distribution ahead.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Collection, Sequence

import numpy as np

from globe.data.records import Day
from globe.inference.forecast import Forecast, Forecaster, Forecasts


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


class FetchPolicy:
    """Per step, which objects to fetch now (see module doc). Call :meth:`decide` after each
    observation with the day's activities and object locations so far."""

    def __init__(self, forecaster: Forecaster, *, cost_useless: float = 3.0, cost_missed: float = 1.0,
                 min_lead_steps: int = 1, window_steps: int = 6, max_fetches_per_step: int = 2) -> None:
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

    def learn(self, days: Sequence[Day]) -> None:
        """Add finished days to the movement model (an online assistant learning as it goes; the
        activity model is shared with the assistant, which updates it)."""
        movements = self.forecaster.movements
        movements.partial_fit(days, movements.objects_)

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
        """Every tracked object as a candidate fetch, most likely useful first."""
        return self.candidates_from(self.forecast(activities, locations, weekday))

    def candidates_from(self, forecast: Forecast) -> list[FetchCandidate]:
        p = forecast.useful_probability(self.min_lead_steps, self.window_steps)
        targets = forecast.likely_target(self.min_lead_steps, self.window_steps)
        ev = expected_value(p, self.cost_useless, self.cost_missed)
        order = sorted(range(len(p)), key=lambda j: (-p[j], forecast.objects[j]))
        return [FetchCandidate(forecast.objects[j], float(p[j]), targets[j], float(ev[j])) for j in order]

    def candidates_many(self, forecasts: Forecasts) -> list[list[FetchCandidate]]:
        """:meth:`candidates_from` for every forecast of a batch (the same numbers)."""
        lo, hi = max(self.min_lead_steps - 1, 0), min(self.window_steps, forecasts.departure.shape[1])
        p = np.zeros(forecasts.departure.shape[::2])
        joint = np.zeros(forecasts.destination.shape[:1] + forecasts.destination.shape[2:])
        for k in range(lo, hi):  # summed step by step, as for one forecast
            p = p + forecasts.departure[:, k] if k > lo else forecasts.departure[:, k].copy()
            joint = joint + forecasts.destination[:, k] if k > lo else forecasts.destination[:, k].copy()
        best = joint.argmax(axis=2)
        found = np.take_along_axis(joint, best[..., None], axis=2)[..., 0] > 0
        where = forecasts.targets[np.arange(len(forecasts.objects))[None, :], best]
        ev = expected_value(p, self.cost_useless, self.cost_missed)
        objects, locations = forecasts.objects, forecasts.locations
        out = []
        for q in range(len(p)):
            pq, evq = p[q].tolist(), ev[q].tolist()
            targets = [locations[x] if ok else None for x, ok in zip(where[q].tolist(), found[q].tolist())]
            order = sorted(range(len(pq)), key=lambda j: (-pq[j], objects[j]))
            out.append([FetchCandidate(objects[j], pq[j], targets[j], evq[j]) for j in order])
        return out

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
