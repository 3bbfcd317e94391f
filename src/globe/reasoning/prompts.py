"""Prompt text only: what each backend is shown. No model calls here."""

from __future__ import annotations

from globe.reasoning.context import ChoiceContext, humanise


def remote_prompt(context: ChoiceContext, candidates: tuple[str, ...]) -> str:
    """The paper's prompt: activity, ``a -> b -> c`` sequence, answer from a list."""
    sequence = " -> ".join(context.objects) if context.objects else "(none yet)"
    return (
        f"A person at home is doing the activity: {context.activity}.\n"
        f"Objects they have used so far in this activity, in order: {sequence}.\n"
        "Which object will they need next?\n"
        f"Return only one object name from this list: [{', '.join(candidates)}]"
    )


def cloze_prefix(context: ChoiceContext) -> str:
    """A sentence the embedded base model continues with a candidate object's name."""
    text = f"While {humanise(context.activity)}, the person used"
    if context.objects:
        text += " the " + ", then the ".join(humanise(o) for o in context.objects[-4:]) + "."
        text += " Next, the person used the"
    else:
        text += " the"
    return text


NULL_PREFIX = "The person used the"
"""The context-free sentence: subtracting its score removes each name's prior (PMI)."""


def cloze_continuation(candidate: str) -> str:
    return " " + humanise(candidate)
