"""The uncertainty gate: the n-gram decides alone when confident; an LLM refines otherwise."""

from __future__ import annotations

import math
import time
from typing import Literal, Mapping

from globe.errors import LLMError
from globe.reasoning.backends.base import LLMBackend
from globe.reasoning.choice import ContextFor, NextObjectModel, ObjectChoice, ObjectChooser, Ranking
from globe.reasoning.context import ChoiceContext

GateMode = Literal["replace", "combine"]


class UncertaintyGate(ObjectChooser):
    """GLOBE's object chooser.

    When the n-gram's top probability is below ``threshold`` (d), its top-``top_k`` objects with
    p > ``min_prob`` go to the LLM with the activity and the run's objects (and, with
    ``examples`` > 0, this person's last runs of the activity, which personalise the prompt). Fewer than two
    candidates: nothing to ask. ``replace`` takes the LLM's pick; ``combine`` adds
    ``combine_weight`` * log p_ngram to the LLM's per-candidate scores. Any LLM failure or
    off-list answer falls back to the n-gram's choice for that one prediction, and is counted.
    """

    name = "globe"

    def __init__(self, model: NextObjectModel, backend: LLMBackend | None, *, threshold: float = 0.5, top_k: int = 5,
                 min_prob: float = 0.1, mode: GateMode = "replace", combine_weight: float = 1.0,
                 marginal: bool = False, examples: int = 0) -> None:
        super().__init__(model, marginal=marginal)
        self.backend = backend
        self.threshold = threshold
        self.top_k = top_k
        self.min_prob = min_prob
        self.mode = mode
        self.combine_weight = combine_weight
        self.examples = examples

    def candidates_for(self, ranked: list[str], dist: dict[str, float]) -> tuple[str, ...]:
        return tuple(o for o in ranked[: self.top_k] if dist[o] > self.min_prob)

    def choose_given(self, activity: str, belief: Mapping[str, float] | None, context_for: ContextFor,
                     ranking: Ranking | None = None, minute: int | None = None) -> ObjectChoice:
        ranked, dist = ranking or self.ngram_ranking(activity, belief, context_for, minute)
        if not ranked:
            return ObjectChoice(None, 0.0)
        top = ranked[0]
        confidence = dist[top]
        if confidence >= self.threshold or self.backend is None:
            return ObjectChoice(top, confidence, ngram_choice=top)
        candidates = self.candidates_for(ranked, dist)
        if len(candidates) < 2:
            return ObjectChoice(top, confidence, ngram_choice=top, candidates=candidates)
        started = time.perf_counter()
        try:
            examples = self.model.recent_runs(activity, self.examples) if self.examples else ()
            answer = self.backend.choose(ChoiceContext(activity, context_for(activity), examples), candidates)
        except LLMError as err:
            reason = type(err).__name__
            return ObjectChoice(top, confidence, top, True, candidates, getattr(err, "raw", None),
                                time.perf_counter() - started, reason)
        latency = time.perf_counter() - started
        if answer.answer not in candidates:
            raw = answer.raw or answer.answer
            return ObjectChoice(top, confidence, top, True, candidates, raw, latency, "off_list")
        chosen = answer.answer
        scores = answer.scores
        if self.mode == "combine" and scores:
            weight = self.combine_weight
            chosen = max(candidates, key=lambda c: (scores.get(c, -math.inf) + weight * math.log(dist[c]), dist[c]))
        return ObjectChoice(chosen, dist[chosen], top, True, candidates, answer.answer, latency, None)


class LLMOnlyChooser(ObjectChooser):
    """Zero-shot baseline: the LLM picks among all of O(â), with no learned statistics."""

    name = "llm_only"
    uses_ranking = False

    def __init__(self, model: NextObjectModel, backend: LLMBackend) -> None:
        super().__init__(model)
        self.backend = backend

    def choose_given(self, activity: str, belief: Mapping[str, float] | None, context_for: ContextFor,
                     ranking: Ranking | None = None, minute: int | None = None) -> ObjectChoice:
        candidates = tuple(sorted(self.model.candidates(activity)))
        if not candidates:
            return ObjectChoice(None, 0.0)
        if len(candidates) == 1:
            return ObjectChoice(candidates[0], 1.0, candidates=candidates)
        started = time.perf_counter()
        try:
            answer = self.backend.choose(ChoiceContext(activity, context_for(activity)), candidates)
        except LLMError as err:
            latency = time.perf_counter() - started
            return ObjectChoice(None, 0.0, None, True, candidates, None, latency, type(err).__name__)
        latency = time.perf_counter() - started
        if answer.answer not in candidates:
            return ObjectChoice(None, 0.0, None, True, candidates, answer.raw, latency, "off_list")
        return ObjectChoice(answer.answer, 1.0 / len(candidates), None, True, candidates, answer.answer, latency, None)
