"""Hyperparameters chosen by k-fold cross-validation over *training* days only.

Test days are never looked at: a home the model has not seen (or a real routine dataset kept
outside the project) must get the same treatment. Folds are contiguous blocks of days, so a
validation fold is a stretch of days the model has not seen.
"""

from __future__ import annotations

import itertools
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Sequence

from sklearn.metrics import f1_score


@dataclass(frozen=True, slots=True)
class Selection:
    """The chosen parameters, every candidate's mean validation score, and the time it took."""

    best: dict[str, Any]
    scores: list[tuple[dict[str, Any], float]] = field(default_factory=list)
    seconds: float = 0.0


def grid(space: Mapping[str, Sequence[Any]]) -> list[dict[str, Any]]:
    keys = list(space)
    return [dict(zip(keys, values)) for values in itertools.product(*(space[k] for k in keys))]


def folds(n: int, k: int) -> list[tuple[list[int], list[int]]]:
    """Contiguous k-fold split of n items: (train indices, validation indices)."""
    k = max(2, min(k, n))
    bounds = [round(i * n / k) for i in range(k + 1)]
    return [([j for j in range(n) if not bounds[i] <= j < bounds[i + 1]], list(range(bounds[i], bounds[i + 1])))
            for i in range(k)]


def _weighted_f1(true: list[str], pred: list[str]) -> float:
    return float(f1_score(true, pred, average="weighted", zero_division=0)) if true else 0.0


def select(items: Sequence[Any], candidates: list[dict[str, Any]], make: Callable[[dict[str, Any]], Any],
           predict_fold: Callable[[Any, Sequence[Any]], tuple[list[str], list[str]]], k: int = 5) -> Selection:
    """Pick the candidate with the best mean weighted F1 over k folds (ties: listed first)."""
    started = time.perf_counter()
    splits = folds(len(items), k)
    scored = []
    for params in candidates:
        fold_scores = []
        for train_idx, val_idx in splits:
            model = make(params).fit([items[i] for i in train_idx])
            true, pred = predict_fold(model, [items[i] for i in val_idx])
            fold_scores.append(_weighted_f1(true, pred))
        scored.append((params, sum(fold_scores) / len(fold_scores)))
    best = max(scored, key=lambda ps: ps[1])[0] if scored else {}
    return Selection(dict(best), scored, time.perf_counter() - started)


def activity_fold(model, days: Sequence[Sequence[str]]) -> tuple[list[str], list[str]]:
    """Next-activity predictions at steps 1..T-1 of held-out days."""
    true, pred = [], []
    for day in days:
        for t, dist in enumerate(model.scan_proba(day)):
            if t == 0:
                continue
            ranked = model.ranked(dist)
            true.append(day[t])
            pred.append(ranked[0] if ranked else "<none>")
    return true, pred


def object_fold(model, runs: Sequence[tuple[str, Sequence[str]]]) -> tuple[list[str], list[str]]:
    """Next-object predictions inside held-out activity runs (true activity)."""
    true, pred = [], []
    for activity, objects in runs:
        for i, obj in enumerate(objects):
            true.append(obj)
            pred.append(model.predict(activity, tuple(objects[:i])) or "<none>")
    return true, pred
