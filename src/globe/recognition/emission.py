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
from globe.recognition.features import column_offsets


def home_shares(overall: np.ndarray, sizes: np.ndarray) -> np.ndarray:
    """Each value's share of its column over every step counted (``overall``: per cell), add-one
    smoothed: the home at large, which a level seen on few steps is shrunk toward."""
    column = np.repeat(np.arange(len(sizes)), sizes)
    return (overall + 1.0) / np.bincount(column, weights=overall + 1.0, minlength=len(sizes))[column]


def shrunk_shares(counts: np.ndarray, prior: np.ndarray, strength: float, sizes: np.ndarray) -> np.ndarray:
    """Per row of ``counts`` (rows x cells), each value's share of its column shrunk toward
    ``prior`` (cells, or rows x cells) by ``strength`` pseudo-steps: (n(v) + s prior(v)) / (n + s)."""
    column = np.repeat(np.arange(len(sizes)), sizes)
    totals = np.add.reduceat(counts, column_offsets(sizes), axis=1) if counts.size else np.zeros(
        (len(counts), len(sizes)))
    return (counts + strength * prior) / (totals[:, column] + strength)


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
        unlabelled step, counted only in the home-at-large rates); ``sizes`` is each column's
        number of values. Reset, then :meth:`partial_fit`."""
        self._reset()
        return self.partial_fit(features, activities, sizes, weights)

    def partial_fit(self, features: Sequence[np.ndarray], activities: Sequence[Sequence[str | None]],
                    sizes: np.ndarray, weights: Sequence[np.ndarray] | None = None) -> "SensorEmission":
        """Add days to the counts (what a service learns at each day's end): only counts are kept,
        never the days, so a home's year costs no more memory than its first day."""
        sizes = np.asarray(sizes, dtype=np.int64)
        if not hasattr(self, "training_data_"):
            self._validate_params()
            self.sizes_ = sizes
            self.offsets_ = column_offsets(sizes)
            self.counts_ = np.zeros((0, int(sizes.sum())))
            self.overall_ = np.zeros(int(sizes.sum()))
            self.classes_: tuple[str, ...] = ()
            self.training_data_ = 0.0  # labelled steps counted (weighted)
        elif not np.array_equal(sizes, self.sizes_):
            raise ValueError(f"features of {len(sizes)} columns for an emission of {len(self.sizes_)}")
        new = sorted({a for day in activities for a in day if a is not None} - set(self.classes_))
        if new:
            self.classes_ += tuple(new)
            self.counts_ = np.vstack([self.counts_, np.zeros((len(new), self.counts_.shape[1]))])
        code = {a: i for i, a in enumerate(self.classes_)}
        width = len(sizes)
        for q, (x, acts) in enumerate(zip(features, activities)):
            if len(x) != len(acts):
                raise ValueError(f"{len(x)} feature rows for {len(acts)} activities")
            w = np.ones(len(acts)) if weights is None else np.asarray(weights[q], dtype=np.float64)
            cells = np.asarray(x, dtype=np.int64) + self.offsets_[None, :]
            np.add.at(self.overall_, cells.ravel(), np.repeat(w, width))
            rows = np.array([code[a] if a is not None else -1 for a in acts], dtype=np.int64)
            keep = rows >= 0
            if keep.any():
                np.add.at(self.counts_, (np.repeat(rows[keep], width), cells[keep].ravel()), np.repeat(w[keep], width))
                self.training_data_ += float(w[keep].sum())
        self._derive()
        return self

    def _derive(self) -> None:
        """The smoothed log-probabilities from the counts (see the class doc)."""
        base = home_shares(self.overall_, self.sizes_)
        self.log_table_ = np.log(shrunk_shares(self.counts_, base[None, :], self.smoothing, self.sizes_))
        self.log_base_ = np.log(base)

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

    def labelled_steps(self, labels: Sequence[str]) -> np.ndarray:
        """Per activity of ``labels``: the labelled steps counted for it (weighted; 0 for one never
        labelled), what the asking policy weighs (:func:`~globe.recognition.asking.worth`)."""
        if not getattr(self, "classes_", ()):
            return np.zeros(len(labels))
        steps = self.counts_[:, : int(self.sizes_[0])].sum(axis=1)  # each step counts once in the first column
        code = {a: i for i, a in enumerate(self.classes_)}
        return np.array([steps[code[a]] if a in code else 0.0 for a in labels])

    def likelihoods(self, features: np.ndarray, labels: Sequence[str]) -> np.ndarray:
        """:meth:`log_likelihoods` as likelihoods scaled so each step's largest is 1 (what the
        activity filter multiplies its histories by)."""
        log = self.log_likelihoods(features, labels)
        return np.exp(log - log.max(axis=1, keepdims=True))
