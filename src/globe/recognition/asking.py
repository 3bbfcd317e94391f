"""When to ask the person "what are you doing?": a budget of questions a day, spent online where an
answer is worth most.

The worth of asking at a step is the chance the recogniser is wrong there, 1 - max P(a_t |
sensors so far): an answer fixes that step, pins the filter's histories (the steps after it
follow from a known activity) and is learnt from. A fixed threshold would spend a quiet day's
budget on nothing and a confusing day's by breakfast, so the policy paces itself: with ``r``
questions left and ``n`` steps left it asks when the step's worth is within the top ``r / n`` of
what worth has looked like (:attr:`QuestionPolicy.reference`, the worths of days already seen),
never twice within ``gap`` steps (an answer is still fresh). :func:`random_steps` spends the same
budget at random times: the comparison the evaluation reports.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np


def worth(posterior: np.ndarray) -> np.ndarray:
    """Per row of (steps x activities) posteriors: the chance the most probable activity is wrong."""
    return 1.0 - np.asarray(posterior).max(axis=-1)


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
    posterior, says whether to ask, and counts what it asked. With ``window`` > 1 a step's worth
    is the mean over the last ``window`` steps: a stretch read unsurely is worth an answer that
    labels all of it; one unsure step at a change is worth little."""

    def __init__(self, policy: QuestionPolicy, steps: int, window: int = 1) -> None:
        self.policy, self.steps, self.window = policy, steps, max(1, window)
        self.asked, self.last = 0, None  # type: int, int | None
        self._recent: list[float] = []

    def __call__(self, step: int, posterior: np.ndarray) -> bool:
        self._recent = (self._recent + [float(worth(posterior))])[-self.window:]
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
