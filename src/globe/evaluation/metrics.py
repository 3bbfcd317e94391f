"""Scores computed from prediction records only, so every number traces back to predictions."""

from __future__ import annotations

from typing import Iterable, Literal, Sequence

from sklearn.metrics import f1_score

Average = Literal["weighted", "micro", "macro"]
AVERAGES: tuple[Average, ...] = ("weighted", "micro", "macro")


def f1(true: Sequence[str], predicted: Sequence[str], average: Average = "weighted") -> float:
    """``sklearn.metrics.f1_score`` with its default labels (union of true and predicted)."""
    if not true:
        return float("nan")
    return float(f1_score(list(true), list(predicted), average=average, zero_division=0))


def accuracy(true: Sequence[str], predicted: Sequence[str]) -> float:
    return sum(t == p for t, p in zip(true, predicted)) / len(true) if true else float("nan")


def scores(records: Iterable, average: Average = "weighted") -> float:
    recs = list(records)
    return f1([r.true for r in recs], [r.predicted for r in recs], average)
