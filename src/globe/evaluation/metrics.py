"""Scores computed from prediction records only, so every number traces back to predictions."""

from __future__ import annotations

from typing import Literal, Sequence

from sklearn.metrics import f1_score

Average = Literal["weighted", "micro", "macro"]
AVERAGES: tuple[Average, ...] = ("weighted", "micro", "macro")


def f1(true: Sequence[str], predicted: Sequence[str], average: Average = "weighted") -> float:
    """``sklearn.metrics.f1_score`` with its default labels (union of true and predicted)."""
    if not true:
        return float("nan")
    return float(f1_score(list(true), list(predicted), average=average, zero_division=0))
