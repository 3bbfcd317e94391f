"""What the LLM is told about one uncertain moment (plain data; prompts are built from it)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class ChoiceContext:
    """The predicted activity, the objects already moved in the current activity run, and (to
    personalise the LLM) this person's most recent runs of the same activity, oldest first."""

    activity: str
    objects: tuple[str, ...]
    examples: tuple[tuple[str, ...], ...] = ()


def humanise(label: str) -> str:
    """``food_peanut_butter`` -> ``food peanut butter`` (how a sentence would say it)."""
    return label.replace("_", " ").strip()


def normalise_answer(text: str) -> str:
    """Case, surrounding punctuation, spaces and underscores do not matter in an answer."""
    cleaned = text.strip().strip("`'\".,;:!*[]()").strip().lower()
    return "_".join(cleaned.replace("-", " ").replace("_", " ").split())
