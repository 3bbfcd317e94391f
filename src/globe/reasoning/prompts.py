"""Prompt text only: what each backend is shown. No model calls here."""

from __future__ import annotations

from globe.reasoning.context import ChoiceContext, humanise


def remote_prompt(context: ChoiceContext, candidates: tuple[str, ...]) -> str:
    """The paper's prompt (activity, ``a -> b -> c`` sequence, answer from a list), preceded by
    this person's recent sessions of the activity when there are examples."""
    sequence = " -> ".join(context.objects) if context.objects else "(none yet)"
    habits = ""
    if context.examples:
        habits = f"Objects this person used in their last sessions of {context.activity}:\n" + "".join(
            f"- {' -> '.join(run)}\n" for run in context.examples)
    return (
        habits
        + f"A person at home is doing the activity: {context.activity}.\n"
        f"Objects they have used so far in this activity, in order: {sequence}.\n"
        "Which object will they need next?\n"
        f"Return only one object name from this list: [{', '.join(candidates)}]"
    )


def diary_prefix(context: ChoiceContext) -> str:
    """Personalised prompt for the base model: the person's own recent runs of the activity as
    diary lines, then today's line so far; the model continues it with the next object.

    A base model copies patterns from its context, so it reads this person's habits directly;
    the names need no PMI correction here (the examples already set what is plausible).
    """
    activity = humanise(context.activity)
    lines = [f"Day {i + 1}, {activity}: " + ", ".join(humanise(o) for o in run) + "."
             for i, run in enumerate(context.examples)]
    today = f"Day {len(context.examples) + 1}, {activity}:" + "".join(f" {humanise(o)}," for o in context.objects)
    return "\n".join([*lines, today])


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
