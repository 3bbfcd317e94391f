"""P(what the sensors show at a step | the activity): naive Bayes over the step's feature columns.

The generative recogniser's emission, as in van Kasteren et al.'s HMM: each feature column
(:mod:`globe.recognition.features`) is a categorical variable, independent of the others given
the activity, counted on labelled steps with a Dirichlet prior of ``smoothing`` pseudo-counts
spread over the column's values in proportion to its frequency over all steps (an activity seen
on few steps reads like the home at large, not like noise). ``weight`` (< 1) tempers the
independence assumption: sensors that fire together (a door and the motion behind it) are not
independent evidence. Steps may carry weights (soft labels: an answered question, a posterior
from unlabelled days).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from globe.errors import ConfigError
from globe.models.base import CountingModel


class SensorEmission(CountingModel):
    """Naive-Bayes likelihoods of a step's features under each activity (see module doc)."""

    _parameter_constraints = {"smoothing": float, "weight": float}
    kind = "sensor_emission"

    def __init__(self, *, smoothing: float = 1.0, weight: float = 1.0) -> None:
        self.smoothing = smoothing
        self.weight = weight

    def _validate_params(self) -> None:
        super()._validate_params()
        if not self.smoothing > 0:
            raise ConfigError(f"SensorEmission: smoothing={self.smoothing}; expected a positive number")
        if not 0 < self.weight <= 1:
            raise ConfigError(f"SensorEmission: weight={self.weight}; expected a number in (0, 1]")

    def fit(self, features: Sequence[np.ndarray], activities: Sequence[Sequence[str | None]], sizes: np.ndarray,
            weights: Sequence[np.ndarray] | None = None) -> "SensorEmission":
        """Count each day's (steps x columns) ``features`` against its activities (None: an
        unlabelled step, skipped); ``sizes`` is each column's number of values."""
        self._validate_params()
        sizes = np.asarray(sizes, dtype=np.int64)
        offsets = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
        labels = sorted({a for day in activities for a in day if a is not None})
        code = {a: i for i, a in enumerate(labels)}
        counts = np.zeros((len(labels), int(sizes.sum())))
        overall = np.zeros(int(sizes.sum()))
        for q, (x, acts) in enumerate(zip(features, activities)):
            if len(x) != len(acts):
                raise ValueError(f"{len(x)} feature rows for {len(acts)} activities")
            w = np.ones(len(acts)) if weights is None else np.asarray(weights[q], dtype=np.float64)
            cells = x + offsets[None, :]
            np.add.at(overall, cells.ravel(), np.repeat(w, x.shape[1]))
            rows = np.array([code.get(a, -1) if a is not None else -1 for a in acts], dtype=np.int64)
            keep = rows >= 0
            if keep.any():
                np.add.at(counts, (np.repeat(rows[keep], x.shape[1]), cells[keep].ravel()),
                          np.repeat(w[keep], x.shape[1]))
        column = np.repeat(np.arange(len(sizes)), sizes)
        base = (overall + 1.0) / np.bincount(column, weights=overall + 1.0, minlength=len(sizes))[column]
        totals = np.zeros((len(labels), len(sizes)))
        for c in range(len(sizes)):
            totals[:, c] = counts[:, offsets[c]:offsets[c] + sizes[c]].sum(axis=1)
        prob = (counts + self.smoothing * base[None, :]) / (totals[:, column] + self.smoothing)
        self.training_data_ = int(counts.sum() / max(len(sizes), 1))  # labelled steps (weighted)
        self.classes_ = tuple(labels)
        self.sizes_ = sizes
        self.offsets_ = offsets
        self.log_table_ = np.log(prob)
        self.log_base_ = np.log(base)
        return self

    def log_likelihoods(self, features: np.ndarray, labels: Sequence[str]) -> np.ndarray:
        """(steps x ``labels``): the tempered log-likelihood of each step's features under each
        activity; an activity never labelled reads like the home at large."""
        self._check_fitted()
        cells = np.asarray(features, dtype=np.int64) + self.offsets_[None, :]
        known = self.log_table_[:, cells].sum(axis=2).T  # (steps x classes)
        base = self.log_base_[cells].sum(axis=1)
        code = {a: i for i, a in enumerate(self.classes_)}
        out = np.empty((len(cells), len(labels)))
        for j, label in enumerate(labels):
            i = code.get(label)
            out[:, j] = known[:, i] if i is not None else base
        return self.weight * out

    def likelihoods(self, features: np.ndarray, labels: Sequence[str]) -> np.ndarray:
        """:meth:`log_likelihoods` as likelihoods scaled so each step's largest is 1 (what the
        activity filter multiplies its histories by)."""
        log = self.log_likelihoods(features, labels)
        return np.exp(log - log.max(axis=1, keepdims=True))
