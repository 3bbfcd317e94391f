"""LLM proposals of disturbances: which object a disturber moves, and where to.

A base model cannot follow "generate additional object movements caused by a toddler", so the
embedded model *scores* natural sentences instead: each object as the continuation of "While
the person was eating breakfast, the toddler grabbed the ...", and each destination as the
continuation of "The toddler dropped the cup on the ...", both minus the same words after a
context-free sentence (PMI). The generator samples from these scores with a temperature,
among the candidates the home's rules allow. Scores depend only on (type, activity) and
(type, object), so a whole dataset needs a few hundred cached prompts.
"""

from __future__ import annotations

import math
import random
from typing import Protocol, Sequence

from globe.noise.rules import NoiseType
from globe.reasoning.backends.base import ScoringBackend
from globe.reasoning.context import humanise

OBJECT_PROMPTS: dict[str, str] = {
    "person": "While {activity}, the person tidied up the room and moved the",
    "pet": "While the person was {activity}, the dog ran around and knocked over the",
    "toddler": "While the person was {activity}, the toddler wandered off carrying the",
}
DESTINATION_PROMPTS: dict[str, str] = {
    "person": "To make room, the person put the {obj} on the",
    "pet": "The dog pushed the {obj} off, and it landed on the",
    "toddler": "The toddler dropped the {obj} on the",
}
NULL_OBJECT = "Someone moved the"
NULL_DESTINATION = "Someone put it on the"


class Scorer(Protocol):
    name: str

    def scores(self, prefix: str, continuations: Sequence[str]) -> list[float]: ...


class UniformScorer:
    """No LLM: every candidate scores the same (sampling is uniform over what the rules allow)."""

    name = "uniform"

    def scores(self, prefix: str, continuations: Sequence[str]) -> list[float]:
        return [0.0] * len(continuations)


class LLMScorer:
    """Scores from a backend that scores continuations (the embedded model, cached)."""

    def __init__(self, backend: ScoringBackend) -> None:
        self.backend = backend
        self.name = f"llm:{backend.name}:{backend.model_name}"

    def scores(self, prefix: str, continuations: Sequence[str]) -> list[float]:
        return list(self.backend.generate_scores(prefix, list(continuations)))


def destination_text(cls: str, category: str) -> str:
    return " floor" if category == "Rooms" else " " + humanise(cls)


class ProposalModel:
    """Memoised PMI score tables per (type, activity) and (type, object)."""

    def __init__(self, scorer: Scorer, objects: Sequence[str], destination_texts: Sequence[str]) -> None:
        self.scorer = scorer
        self.objects = list(objects)
        self.destination_texts = sorted(set(destination_texts))
        self._obj: dict[tuple[str, str], dict[str, float]] = {}
        self._dest: dict[tuple[str, str], dict[str, float]] = {}
        self._null_obj: list[float] | None = None
        self._null_dest: list[float] | None = None

    def object_scores(self, noise_type: NoiseType, activity: str) -> dict[str, float]:
        key = (noise_type, activity)
        if key not in self._obj:
            conts = [" " + humanise(o) for o in self.objects]
            if self._null_obj is None:
                self._null_obj = self.scorer.scores(NULL_OBJECT, conts)
            ctx = self.scorer.scores(OBJECT_PROMPTS[noise_type].format(activity=humanise(activity)), conts)
            self._obj[key] = {o: a - b for o, a, b in zip(self.objects, ctx, self._null_obj)}
        return self._obj[key]

    def destination_scores(self, noise_type: NoiseType, obj: str) -> dict[str, float]:
        key = (noise_type, obj)
        if key not in self._dest:
            if self._null_dest is None:
                self._null_dest = self.scorer.scores(NULL_DESTINATION, self.destination_texts)
            ctx = self.scorer.scores(DESTINATION_PROMPTS[noise_type].format(obj=humanise(obj)), self.destination_texts)
            self._dest[key] = {t: a - b for t, a, b in zip(self.destination_texts, ctx, self._null_dest)}
        return self._dest[key]


def sample(options: Sequence[str], scores: Sequence[float], temperature: float, rng: random.Random) -> str:
    """Draw one option with probability proportional to exp(score / temperature)."""
    top = max(scores)
    weights = [math.exp((s - top) / temperature) for s in scores]
    return rng.choices(list(options), weights=weights, k=1)[0]
