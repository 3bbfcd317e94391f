"""The interface every LLM backend implements."""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol, Sequence

from globe.errors import LLMError, LLMUnavailableError
from globe.reasoning.context import ChoiceContext

if TYPE_CHECKING:
    from globe.reasoning.cache import AnswerCache


@dataclass(frozen=True, slots=True)
class Choice:
    """A backend's pick among the listed candidates, with per-candidate scores if it has them
    (log-domain, higher is better; the gate's ``combine`` mode adds n-gram log p to them)."""

    answer: str
    scores: dict[str, float] | None = None
    raw: str | None = None
    cached: bool = False


class LLMBackend(ABC):
    """``choose`` returns a listed candidate or raises an :class:`~globe.errors.LLMError`."""

    name: str = "llm"
    model_name: str = ""
    cache: AnswerCache | None = None

    @abstractmethod
    def choose(self, context: ChoiceContext, candidates: tuple[str, ...]) -> Choice: ...

    @property
    def status(self) -> str:
        """'ready', or why questions get no answer now ('loading', 'failed: ...')."""
        return "ready"

    def start_loading(self) -> None:  # noqa: B027 - a hook: most backends have nothing to load
        """Get ready to answer in the background (a backend with nothing to load does nothing)."""

    @property
    def prefetches(self) -> bool:
        """Whether answering questions ahead (:meth:`prefetch`) saves work: only with a cache."""
        return self.cache is not None

    def order_key(self, context: ChoiceContext) -> str:
        """Questions with equal keys are answered together (a backend reusing a shared prompt
        prefix groups by that prefix)."""
        return context.activity

    def prefetch(self, questions: Sequence[tuple[ChoiceContext, tuple[str, ...]]]) -> None:
        """Answer ``questions`` into the cache, grouped by :meth:`order_key`. Answers never
        depend on the order they are asked in, so this changes timing only; failures are left
        for the real question to report."""
        unique = dict.fromkeys((c, tuple(sorted(cands))) for c, cands in questions)
        for context, candidates in sorted(unique, key=lambda q: (self.order_key(q[0]), repr(q))):
            try:
                self.choose(context, candidates)
            except LLMError:
                continue


class QuestionRecorder(LLMBackend):
    """Stands in for a backend to collect the questions a chooser would ask; answers none (each
    one then falls back, which is never used: the questions are asked again for real)."""

    def __init__(self, real: LLMBackend) -> None:
        self.name, self.model_name = real.name, real.model_name
        self.questions: list[tuple[ChoiceContext, tuple[str, ...]]] = []

    def choose(self, context: ChoiceContext, candidates: tuple[str, ...]) -> Choice:
        self.questions.append((context, candidates))
        raise LLMUnavailableError("recording questions only")


class ScoringBackend(Protocol):
    """A model that scores continuations of a text (log-probabilities, higher is better): what
    the HOMER-Noise generator needs (the embedded backend provides it, cached)."""

    name: str

    @property
    def model_name(self) -> str: ...

    def generate_scores(self, prefix: str, continuations: list[str]) -> list[float]: ...
