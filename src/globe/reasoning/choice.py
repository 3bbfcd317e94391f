"""The record every object prediction produces, whoever made it (n-gram, gate, LLM only)."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True, slots=True)
class ObjectChoice:
    """The chosen object and how it was chosen.

    ``asked``: the LLM was consulted; ``fallback``: why its answer was not used (None if it
    was, or if it was not asked); ``candidates``: what it was offered.
    """

    obj: str | None
    confidence: float
    ngram_choice: str | None = None
    asked: bool = False
    candidates: tuple[str, ...] = field(default_factory=tuple)
    answer: str | None = None
    latency_s: float = 0.0
    fallback: str | None = None


class ObjectChooser:
    """Chooses the next object for (activity, objects so far). The plain n-gram chooser; the
    uncertainty gate and the LLM-only chooser override :meth:`choose`."""

    name = "ngram"

    def __init__(self, model) -> None:  # model: globe.models.objects.ObjectModel
        self.model = model

    def ngram_ranking(self, activity: str, history: tuple[str, ...]) -> tuple[list[str], dict[str, float]]:
        dist = self.model.predict_proba(activity, history)
        return self.model.ranked(activity, dist), dist

    def choose(self, activity: str, history: tuple[str, ...]) -> ObjectChoice:
        ranked, dist = self.ngram_ranking(activity, history)
        if not ranked:
            return ObjectChoice(None, 0.0)
        return ObjectChoice(ranked[0], dist[ranked[0]], ngram_choice=ranked[0])
