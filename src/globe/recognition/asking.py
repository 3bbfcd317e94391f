"""When to ask the person "what are you doing?": a budget of questions a day, spent online where an
answer is worth most.

What an answer buys is judged by class accuracy (the mean over activities of each one's share of
steps right), which weighs a rare activity as much as the commonest: an answer labels the stretch
the recogniser read as one activity, and those steps teach the emission of that activity the more
the fewer steps of it are labelled already. So the worth of asking at a step is

    worth = (1 - max_a P(a)) * sum_a P(a) / sqrt(1 + n_a)

where P is the recogniser's posterior (sensors so far) and n_a the steps of activity a labelled so
far (labelled days, answers spread over their stretches): the chance its best guess is wrong,
times how little the likely activities have been taught (a square root: the error of a count
shrinks as 1 / sqrt(n)). Without counts it is the chance of being wrong alone. Asking where the
recogniser is merely unsure spends the budget on confusions it has seen hundreds of times
(wandering between rooms); asking where a common activity is likely teaches it what it knows.
The rule is fixed by that argument, not tuned; on the simulated sensor home it is measured
against the plain chance of being wrong and against random times (docs/recognition.md).

A fixed threshold would spend a quiet day's budget on nothing and a confusing day's by breakfast,
so the policy paces itself: with ``r`` questions left and ``n`` steps left it asks when the step's
worth is within the top ``r / n`` of what worth has looked like (:attr:`QuestionPolicy.reference`,
the worths of days already seen, under the same counts), never twice within ``gap`` steps (an
answer is still fresh). :func:`random_steps` spends the same budget at random times: the
comparison the evaluation reports.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np


def worth(posterior: np.ndarray, labelled: Sequence[float] | np.ndarray | None = None) -> np.ndarray:
    """Per row of (steps x activities) posteriors: the worth of an answer (see module doc); with
    ``labelled`` None, the chance the most probable activity is wrong. ``labelled`` counts the
    labelled steps of each column's activity; columns past its end (activities named since) count 0."""
    post = np.asarray(posterior, dtype=np.float64)
    wrong = 1.0 - post.max(axis=-1)
    if labelled is None:
        return wrong
    counts = np.zeros(post.shape[-1])
    given = np.asarray(labelled, dtype=np.float64)[: post.shape[-1]]
    counts[: len(given)] = given
    return wrong * (post / np.sqrt(1.0 + counts)).sum(axis=-1)


class QuestionPolicy:
    """Whether to ask at a step, given the day's budget so far (see module doc)."""

    def __init__(self, budget: int, reference: Sequence[float] | np.ndarray, *, gap: int = 10) -> None:
        if budget < 0:
            raise ValueError(f"a budget of {budget} questions a day; expected 0 or more")
        self.budget = budget
        self.reference = np.sort(np.asarray(reference, dtype=np.float64))
        self.gap = gap

    def ask(self, value: float, asked: int, step: int, steps: int, last_asked: int | None) -> bool:
        """Whether to ask at ``step`` of ``steps`` where asking is worth ``value``, ``asked``
        questions of the budget spent, the last at ``last_asked``."""
        left = self.budget - asked
        if left <= 0 or value <= 0.0 or (last_asked is not None and step - last_asked < self.gap):
            return False
        remaining = max(steps - step, 1)
        if left >= remaining:
            return True
        if not len(self.reference):
            return True
        share = left / remaining
        bar = float(np.quantile(self.reference, 1.0 - share))
        return value >= bar


class DayAsker:
    """One day's questions under a :class:`QuestionPolicy`: called at each step with the
    posterior, says whether to ask, and counts what it asked. With ``labelled`` (steps labelled
    per activity, the columns of the posteriors) a step's worth weighs how little its likely
    activities are taught. With ``window`` > 1 a step's worth is the mean over the last ``window`` steps: a stretch read
    unsurely is worth an answer that labels all of it; one unsure step at a change is worth little."""

    def __init__(self, policy: QuestionPolicy, steps: int, window: int = 1,
                 labelled: Sequence[float] | np.ndarray | None = None) -> None:
        self.policy, self.steps, self.window = policy, steps, max(1, window)
        self.labelled = None if labelled is None else np.asarray(labelled, dtype=np.float64)
        self.asked, self.last = 0, None  # type: int, int | None
        self._recent: list[float] = []

    def __call__(self, step: int, posterior: np.ndarray) -> bool:
        self._recent = (self._recent + [float(worth(posterior, self.labelled))])[-self.window:]
        value = sum(self._recent) / len(self._recent)
        if not self.policy.ask(value, self.asked, step, self.steps, self.last):
            return False
        self.asked, self.last = self.asked + 1, step
        self._recent = []
        return True


def random_steps(steps: int, budget: int, seed: Sequence[int]) -> list[int]:
    """``budget`` steps of ``steps`` drawn at random (sorted): asking at random times."""
    rng = np.random.default_rng(list(seed))
    return sorted(rng.choice(steps, size=min(budget, steps), replace=False).tolist())
