"""The interface every LLM backend implements."""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Protocol

from globe.reasoning.context import ChoiceContext


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

    @abstractmethod
    def choose(self, context: ChoiceContext, candidates: tuple[str, ...]) -> Choice: ...


class ScoringBackend(Protocol):
    """A model that scores continuations of a text (log-probabilities, higher is better): what
    the HOMER-Noise generator needs (the embedded backend provides it, cached)."""

    name: str

    @property
    def model_name(self) -> str: ...

    def generate_scores(self, prefix: str, continuations: list[str]) -> list[float]: ...
