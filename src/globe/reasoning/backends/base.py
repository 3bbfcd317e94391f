"""The interface every LLM backend implements."""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

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
