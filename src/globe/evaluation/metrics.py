"""Scores computed from prediction records only, so every number traces back to predictions."""

from __future__ import annotations

import math
import statistics
from collections import Counter
from typing import Iterable, Literal, Protocol, Sequence

import numpy as np

from globe.data.records import Household
from globe.sequences.runs import activity_runs

Average = Literal["weighted", "micro", "macro"]
AVERAGES: tuple[Average, ...] = ("weighted", "micro", "macro")


def f1(true: Sequence[str], predicted: Sequence[str], average: Average = "weighted") -> float | None:
    """F1 as ``sklearn.metrics.f1_score(true, predicted, average=average, zero_division=0)``
    with its default labels (the sorted union of true and predicted), computed from the
    confusion counts with the same array operations (so the same bits; tested), without
    scikit-learn's per-call validation, which cost more than the rest of a cross-validation
    fold. None (absent, shown as "–") when there is nothing to score — no test step, or no
    object ever moved — rather than a NaN that would spread into every mean."""
    if not true:
        return None
    if len(true) != len(predicted):
        raise ValueError(f"{len(true)} true and {len(predicted)} predicted labels")
    labels = sorted(set(true) | set(predicted))
    index = {label: i for i, label in enumerate(labels)}
    pairs = Counter(zip(true, predicted))
    tp, true_sum, pred_sum = np.zeros(len(labels)), np.zeros(len(labels)), np.zeros(len(labels))
    for (t, p), n in pairs.items():
        true_sum[index[t]] += n
        pred_sum[index[p]] += n
        if t == p:
            tp[index[t]] += n
    if average == "micro":
        tp, true_sum, pred_sum = np.array([tp.sum()]), np.array([true_sum.sum()]), np.array([pred_sum.sum()])
    denominator = true_sum + pred_sum
    score = np.divide(2 * tp, denominator, out=np.zeros_like(tp), where=denominator != 0)
    if average == "weighted":
        return float(np.average(score, weights=true_sum)) if true_sum.sum() != 0 else 0.0
    return float(np.average(score))


class Scored(Protocol):
    """A record with a true and a predicted label: an activity step or a movement event."""

    @property
    def true(self) -> str: ...

    @property
    def predicted(self) -> str: ...


def records_f1(records: Sequence[Scored], average: Average = "weighted") -> float | None:
    """:func:`f1` of the true and predicted labels of ``records``."""
    return f1([r.true for r in records], [r.predicted for r in records], average)


def calibration(confidences: Sequence[float], correct: Sequence[bool],
                bins: int = 10) -> tuple[float, tuple[list[float], list[float], list[int]]]:
    """Expected calibration error and the reliability curve (mean confidence, accuracy, count per bin)."""
    buckets: list[list[tuple[float, bool]]] = [[] for _ in range(bins)]
    for c, ok in zip(confidences, correct):
        buckets[min(int(c * bins), bins - 1)].append((c, ok))
    conf, acc, counts, ece, n = [], [], [], 0.0, max(len(confidences), 1)
    for b in buckets:
        if not b:
            continue
        mc = sum(c for c, _ in b) / len(b)
        ma = sum(ok for _, ok in b) / len(b)
        conf.append(mc)
        acc.append(ma)
        counts.append(len(b))
        ece += len(b) / n * abs(mc - ma)
    return ece, (conf, acc, counts)


def _tertiles(spread: dict[str, float]) -> dict[str, str]:
    """Lowest third of spread -> 'more' consistent, middle -> 'moderate', top -> 'less'."""
    ordered = sorted(spread, key=lambda a: (spread[a], a))
    n = len(ordered)
    return {a: ("more" if i < n / 3 else "moderate" if i < 2 * n / 3 else "less") for i, a in enumerate(ordered)}


def consistency_groups(households: Sequence[Household], definition: str = "start_time") -> dict[str, dict[str, str]]:
    """Per household: activity -> 'more' / 'moderate' / 'less' consistent, from training days.

    ``start_time``: standard deviation of the activity's first start step across the days it
    occurs in. ``object_sequence``: 1 - the share of the activity's runs (with movements) whose
    object sequence is its most common one.
    """
    groups: dict[str, dict[str, str]] = {}
    for h in households:
        spread: dict[str, float] = {}
        if definition == "start_time":
            starts: dict[str, list[int]] = {}
            for day in h.train:
                seen = set()
                for t, a in enumerate(day.activities):
                    if a not in seen:
                        seen.add(a)
                        starts.setdefault(a, []).append(t)
            spread = {a: statistics.pstdev(s) for a, s in starts.items()}
        elif definition == "object_sequence":
            by_activity: dict[str, Counter[tuple[str, ...]]] = {}
            for day in h.train:
                for run in activity_runs(day, h.objects):
                    if run.objects:
                        by_activity.setdefault(run.activity, Counter())[run.objects] += 1
            spread = {a: 1 - c.most_common(1)[0][1] / sum(c.values()) for a, c in by_activity.items()}
        else:
            raise ValueError(f"unknown consistency definition {definition!r}; expected start_time or object_sequence")
        groups[h.name] = _tertiles(spread)
    return groups


CONSISTENCY_DEFINITIONS = ("start_time", "object_sequence")


LOG_LOSS_FLOOR = 1e-6  # a probability of 0 for what happened costs -log(1e-6) = 13.8 nats, not infinity


def log_loss(p_true: Sequence[float]) -> float | None:
    """Mean negative log-probability of what happened (nats), probabilities floored at
    :data:`LOG_LOSS_FLOOR`; None when there is nothing to score. Unlike F1 it rewards honest
    uncertainty, which is what a robot's decision needs."""
    if not p_true:
        return None
    return statistics.fmean(-math.log(max(p, LOG_LOSS_FLOOR)) for p in p_true)


def rounded(x: float | None) -> float | None:
    """A figure of a results table: 4 decimals; absent stays absent."""
    return None if x is None else round(x, 4)


def mean_present(values: Iterable[float | None]) -> float | None:
    """The mean of the values that are present (None = nothing was scored there), or None."""
    present = [v for v in values if v is not None]
    return statistics.fmean(present) if present else None
