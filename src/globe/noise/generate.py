"""Generate HOMER-Noise: propose disturbances for every activity run, insert them at a level.

Each proposal gets a uniform draw u; it is inserted at noise level L when u < L, so the
movements at 0.25 are a subset of those at 0.5, and those of 1.0. An inserted movement puts the
object at its new place from that step until the routine next moves it. Proposals whose
effects would overlap for one object, that coincide with a routine movement, or that would hide
the next routine movement, are dropped (and counted), so every level is consistent on its own
and the manifest equals the difference between clean and noisy logs.
"""

from __future__ import annotations

import math
import random
from collections import Counter
from dataclasses import dataclass, field, replace
from typing import Sequence

from globe.data.records import Day, Household
from globe.noise.proposals import ProposalModel, Scorer, destination_text, sample
from globe.noise.rules import HomeRules, NoiseType
from globe.sequences.runs import run_bounds


@dataclass(frozen=True, slots=True)
class Injection:
    household: str
    day: str  # "train/012"
    step: int
    minute: int
    obj: str
    source: str
    target: str
    noise_type: str
    u: float
    origin: str
    window_end: int  # last step the object stays at the target


@dataclass(slots=True)
class Proposals:
    household: str
    noise_type: str
    injections: list[Injection] = field(default_factory=list)
    dropped: Counter[str] = field(default_factory=Counter)

    def at_level(self, level: float) -> list[Injection]:
        return [i for i in self.injections if i.u < level]


def _poisson(rate: float, rng: random.Random) -> int:
    threshold, k, p = math.exp(-rate), 0, rng.random()
    while p > threshold:
        k += 1
        p *= rng.random()
    return k


def propose(household: Household, noise_type: NoiseType, scorer: Scorer, *, seed: int, rate: float,
            temperature: float) -> Proposals:
    """Disturbances for every day (train and test) of a household, at noise level 1.0."""
    rules = HomeRules(household)
    rng = random.Random(f"{seed}:{household.name}:{noise_type}")
    dest_text = {n: destination_text(rules.cls[n], rules.category[n]) for n in rules.static}
    model = ProposalModel(scorer, household.objects, list(dest_text.values()))
    out = Proposals(household.name, noise_type)
    objects = household.objects
    col = {o: j for j, o in enumerate(objects)}
    for day in household.train + household.test:
        busy: dict[str, list[tuple[int, int]]] = {}
        for first, last in run_bounds(day.activities):
            activity = day.activities[first]
            for _ in range(_poisson(rate, rng)):
                t = rng.randint(max(first, 1), max(last, 1))
                u = rng.random()
                before = dict(zip(objects, day.locations[t - 1]))
                candidates = [o for o in objects
                              if rules.reachable_source(noise_type, o, rules.support(before[o], before))]
                if not candidates:
                    out.dropped["no reachable object"] += 1
                    continue
                scores = model.object_scores(noise_type, activity)
                obj = sample(candidates, [scores[o] for o in candidates], temperature, rng)
                support = rules.support(before[obj], before)
                dests = rules.destinations(noise_type, support)
                if not dests:
                    out.dropped["no destination"] += 1
                    continue
                dscores = model.destination_scores(noise_type, obj)
                target = sample(dests, [dscores[dest_text[d]] for d in dests], temperature, rng)
                reason = _conflict(day, col[obj], t, target, busy.get(obj, []))
                if reason is None:
                    reason = rules.valid(noise_type, obj, before[obj], target, before)
                if reason is not None:
                    out.dropped[reason] += 1
                    continue
                end = _window_end(day, col[obj], t)
                busy.setdefault(obj, []).append((t, end))
                out.injections.append(Injection(household.name, day.name, t, day.minutes[t], obj, before[obj], target,
                                                noise_type, u, scorer.name, end))
    return out


def _window_end(day: Day, j: int, t: int) -> int:
    for r in range(t + 1, len(day)):
        if day.locations[r][j] != day.locations[r - 1][j]:
            return r - 1
    return len(day) - 1


def _conflict(day: Day, j: int, t: int, target: str, windows: list[tuple[int, int]]) -> str | None:
    if day.locations[t][j] != day.locations[t - 1][j]:
        return "coincides with a routine movement"
    end = _window_end(day, j, t)
    if end + 1 < len(day) and day.locations[end + 1][j] == target:
        return "would hide the next routine movement"
    if any(not (end < s or e < t) for s, e in windows):
        return "overlaps another disturbance of the object"
    return None


def apply(household: Household, injections: Sequence[Injection]) -> Household:
    """The household's days with the injections applied (same nodes, same CSV format)."""
    by_day: dict[str, list[Injection]] = {}
    for inj in injections:
        by_day.setdefault(inj.day, []).append(inj)
    col = {o: j for j, o in enumerate(household.objects)}

    def noisy(day: Day) -> Day:
        mine = by_day.get(day.name)
        if not mine:
            return day
        rows = [list(r) for r in day.locations]
        for inj in mine:
            for r in range(inj.step, inj.window_end + 1):
                rows[r][col[inj.obj]] = inj.target
        return replace(day, locations=tuple(tuple(r) for r in rows), source="")

    return replace(household, train=tuple(map(noisy, household.train)), test=tuple(map(noisy, household.test)))
