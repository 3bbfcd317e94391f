"""The record every object prediction produces, whoever made it (n-gram, gate, LLM only)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Mapping, Protocol, Sequence


class NextObjectModel(Protocol):
    """What choosers need of an object model (:class:`globe.models.objects.ObjectModel`, or the
    object baseline :class:`globe.models.baselines.HourActivityObjects`, which reads ``minute``:
    the clock minute of the step the activity is predicted for)."""

    def predict_proba(self, activity: str, history: Sequence[str] = (), minute: int | None = None
                      ) -> dict[str, float]: ...

    def ranked(self, activity: str, distribution: dict[str, float]) -> list[str]: ...

    def candidates(self, activity: str) -> tuple[str, ...]: ...

    def recent_runs(self, activity: str, k: int) -> tuple[tuple[str, ...], ...]: ...


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


ContextFor = Callable[[str], tuple[str, ...]]
Ranking = tuple[list[str], dict[str, float]]
"""The n-gram's objects, most probable first, and their probabilities."""


def run_context(run_activity: str | None, objects: tuple[str, ...]) -> ContextFor:
    """Context for a hypothesised activity: the current run's objects if that activity continues
    the run, else none (a new run starts empty)."""
    objects = tuple(objects)
    return lambda activity: objects if activity == run_activity else ()

MIN_BELIEF = 1e-3  # activities less likely than this cannot change the mixed object ranking much


def object_distribution(model: NextObjectModel, activity: str, belief: Mapping[str, float] | None,
                        context_for: ContextFor, marginal: bool, minute: int | None = None) -> dict[str, float]:
    """The next-object distribution for the predicted ``activity``, or, with ``marginal``, mixed
    over every activity the activity model finds possible: sum_a P(a) P(o | a, context(a)), at
    the clock ``minute`` of the step predicted for (read by a model that reads the clock)."""
    if not marginal or not belief:
        return model.predict_proba(activity, context_for(activity), minute)
    mixed: dict[str, float] = {}
    for a, pa in belief.items():
        if pa < MIN_BELIEF:
            continue
        for o, po in model.predict_proba(a, context_for(a), minute).items():
            mixed[o] = mixed.get(o, 0.0) + pa * po
    total = sum(mixed.values())
    return {o: p / total for o, p in mixed.items()} if total > 0 else {}


class ObjectChooser:
    """Chooses the next object. The plain n-gram chooser; the uncertainty gate and the LLM-only
    chooser override :meth:`choose_given`.

    ``choose_given(activity, belief, context_for)`` gets the predicted activity, the activity
    model's whole distribution and, for any activity, the objects that count as context
    (the current run's objects if that activity continues the run, else none); ``ranking``,
    when given, is :meth:`ngram_ranking` of the same, computed once by an evaluation that asks
    several choosers over the same models; ``minute``, the clock minute of the step the activity
    is predicted for (the protocol's and the session's alike).
    """

    name = "ngram"
    uses_ranking = True  # whether choose_given reads the n-gram ranking (precomputed rankings can be passed)

    def __init__(self, model: NextObjectModel, *, marginal: bool = False) -> None:
        self.model = model
        self.marginal = marginal

    def ngram_ranking(self, activity: str, belief: Mapping[str, float] | None, context_for: ContextFor,
                      minute: int | None = None) -> Ranking:
        dist = object_distribution(self.model, activity, belief, context_for, self.marginal, minute)
        return self.model.ranked(activity, dist), dist

    def choose_given(self, activity: str, belief: Mapping[str, float] | None, context_for: ContextFor,
                     ranking: Ranking | None = None, minute: int | None = None) -> ObjectChoice:
        ranked, dist = ranking or self.ngram_ranking(activity, belief, context_for, minute)
        if not ranked:
            return ObjectChoice(None, 0.0)
        return ObjectChoice(ranked[0], dist[ranked[0]], ngram_choice=ranked[0])

    def choose(self, activity: str, history: tuple[str, ...], minute: int | None = None) -> ObjectChoice:
        """The next object for a known activity and the objects moved so far in its run."""
        return self.choose_given(activity, None, run_context(activity, history), minute=minute)
