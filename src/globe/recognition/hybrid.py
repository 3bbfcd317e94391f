"""A discriminative sensor emission, as in hybrid HMMs: a classifier's posterior over activities
turned into a scaled likelihood for the activity filter.

Naive Bayes (:class:`~globe.recognition.emission.SensorEmission`) counts each feature column as
independent evidence given the activity, so sensors that fire together (a door and the motion
behind it, a mat and the room's motion) are counted twice; its ``weight`` tempers all of them
alike. A discriminative model learns how much each value of each column says *given the
others*. Hybrid HMM/ANN recognisers (Bourlard and Morgan) use a classifier's P(activity | step
features) in the HMM by Bayes' rule:

    p(x | a) / p(x) = P(a | x) / P(a)

with P(a) the share of labelled steps of a, so the filter's dynamics still supply what the
classifier cannot: the time of day and what came before. The classifier is scikit-learn's
multinomial logistic regression over the one-hot values of every feature column (L2, its default
strength), weighted by each step's weight (soft labels); an activity never labelled reads like the
home at large (ratio 1). It needs scikit-learn (``pip install globe[recognition]``); cross-validation
offers it beside naive Bayes only where installed (:func:`available`).

A service learns each finished day: unlike naive Bayes's counts, a logistic regression is not a
sum, so the labelled steps are kept, each distinct reading of the sensors with an activity once
with its weight (a minute's steps mostly repeat the one before), and the classifier is refitted on
them, from the day before's weights (a warm start: a few iterations).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from globe.errors import ConfigError
from globe.recognition.features import column_offsets

FLOOR = 1e-6
"""The least posterior a classifier's answer is read as (a log of 0 would veto an activity)."""


def available() -> bool:
    """Whether scikit-learn, which the discriminative emission needs, is installed."""
    try:
        import sklearn.linear_model  # noqa: F401
    except ImportError:
        return False
    return True


class DiscriminativeEmission:
    """Scaled likelihoods P(a | x) / P(a) of a step's features under each activity (see module doc)."""

    def __init__(self, *, weight: float = 1.0, strength: float = 1.0) -> None:
        self.weight = weight
        self.strength = strength

    def _validate_params(self) -> None:
        if not 0 < self.weight <= 1:
            raise ConfigError(f"DiscriminativeEmission: weight={self.weight}; expected a number in (0, 1]")
        if not self.strength > 0:
            raise ConfigError(f"DiscriminativeEmission: strength={self.strength}; expected a positive number")

    def fit(self, features: Sequence[np.ndarray], activities: Sequence[Sequence[str | None]], sizes: np.ndarray,
            weights: Sequence[np.ndarray] | None = None) -> "DiscriminativeEmission":
        """Learn from each day's (steps x columns) ``features`` and its activities (None: an
        unlabelled step, not learnt from); ``sizes`` is each column's number of values."""
        for name in ("sizes_", "classes_", "model_"):
            self.__dict__.pop(name, None)
        return self.partial_fit(features, activities, sizes, weights)

    def partial_fit(self, features: Sequence[np.ndarray], activities: Sequence[Sequence[str | None]],
                    sizes: np.ndarray, weights: Sequence[np.ndarray] | None = None) -> "DiscriminativeEmission":
        """Add days' labelled steps and refit the classifier on every one kept (see module doc)."""
        sizes = np.asarray(sizes, dtype=np.int64)
        if not hasattr(self, "sizes_"):
            self._validate_params()
            self.sizes_ = sizes
            self.offsets_ = column_offsets(sizes)
            self.classes_: tuple[str, ...] = ()
            self._x = np.zeros((0, len(sizes)), dtype=np.int32)
            self._y = np.zeros(0, dtype=np.int64)
            self._w = np.zeros(0)
            self.training_data_ = 0.0
        elif not np.array_equal(sizes, self.sizes_):
            raise ValueError(f"features of {len(sizes)} columns for an emission of {len(self.sizes_)}")
        new = sorted({a for day in activities for a in day if a is not None} - set(self.classes_))
        self.classes_ += tuple(new)
        code = {a: i for i, a in enumerate(self.classes_)}
        for q, (x, acts) in enumerate(zip(features, activities)):
            if len(x) != len(acts):
                raise ValueError(f"{len(x)} feature rows for {len(acts)} activities")
            w = np.ones(len(acts)) if weights is None else np.asarray(weights[q], dtype=np.float64)
            rows = np.array([code[a] if a is not None else -1 for a in acts], dtype=np.int64)
            keep = rows >= 0
            self._x = np.vstack([self._x, np.asarray(x, dtype=np.int32)[keep]])
            self._y = np.concatenate([self._y, rows[keep]])
            self._w = np.concatenate([self._w, w[keep]])
        self._compact()
        self.training_data_ = float(self._w.sum())
        self._refit()
        return self

    def _compact(self) -> None:
        """Steps with the same features and activity kept as one, their weights summed: the
        classifier's loss is a weighted sum over steps, so it is the same; what is kept grows with
        the distinct readings a home gives, not with its days (a minute's steps mostly repeat)."""
        if not len(self._y):
            return
        rows = np.column_stack([self._x, self._y]).astype(np.int64)
        unique, inverse = np.unique(rows, axis=0, return_inverse=True)
        self._w = np.bincount(inverse.ravel(), weights=self._w, minlength=len(unique)).astype(np.float64)
        self._x, self._y = unique[:, :-1].astype(np.int32), unique[:, -1].astype(np.int64)

    def _onehot(self, features: np.ndarray):  # noqa: ANN202 - a scipy sparse matrix
        from scipy.sparse import csr_matrix

        cells = np.asarray(features, dtype=np.int64) + self.offsets_[None, :]
        n, width = cells.shape
        return csr_matrix((np.ones(n * width), cells.ravel(), np.arange(0, n * width + 1, width)),
                          shape=(n, int(self.sizes_.sum())))

    def _refit(self) -> None:
        """The classifier and the activities' shares from the steps kept."""
        weighted = np.bincount(self._y, weights=self._w, minlength=len(self.classes_))
        self.log_prior_ = np.log(np.maximum(weighted, FLOOR) / max(weighted.sum(), FLOOR))
        present = np.flatnonzero(weighted > 0)
        before = getattr(self, "model_", None)
        self.model_ = None
        if len(present) < 2:  # one activity (or none) labelled: the sensors cannot tell any apart yet
            return
        from sklearn.linear_model import LogisticRegression

        if before is not None and before.classes_.tolist() == present.tolist():
            model = before  # a day more: starts from yesterday's weights (warm start), far fewer iterations
        else:
            model = LogisticRegression(C=1.0 / self.strength, max_iter=300, warm_start=True)
        model.fit(self._onehot(self._x), self._y, sample_weight=self._w)
        self.model_ = model

    def _posterior(self, features: np.ndarray) -> np.ndarray:
        """The classifier's P(a | x) (steps x its classes), as its ``predict_proba`` computes it,
        read off the one-hot cells directly (a step in the service costs no sparse matrix)."""
        model = self.model_
        assert model is not None
        cells = np.asarray(features, dtype=np.int64) + self.offsets_[None, :]
        scores = model.coef_[:, cells].sum(axis=2).T + model.intercept_[None, :]  # (steps x rows of coef_)
        if scores.shape[1] == 1:  # two classes: one row of weights, for the second
            scores = np.hstack([np.zeros_like(scores), scores])
        scores -= scores.max(axis=1, keepdims=True)
        expd = np.exp(scores)
        return expd / expd.sum(axis=1, keepdims=True)

    def log_likelihoods(self, features: np.ndarray, labels: Sequence[str]) -> np.ndarray:
        """(steps x ``labels``): the tempered log of P(a | x) / P(a) (0, the home at large, for an
        activity never labelled or while fewer than two are)."""
        if not hasattr(self, "sizes_"):
            raise ValueError("DiscriminativeEmission is not fitted yet")
        out = np.zeros((len(features), len(labels)))
        if self.model_ is None or not len(features):
            return out
        post = np.log(np.maximum(self._posterior(features), FLOOR))
        column = {int(c): j for j, c in enumerate(self.model_.classes_.tolist())}
        code = {a: i for i, a in enumerate(self.classes_)}
        for j, label in enumerate(labels):
            i = code.get(label)
            if i is not None and i in column:
                out[:, j] = post[:, column[i]] - self.log_prior_[i]
        return self.weight * out

    def likelihoods(self, features: np.ndarray, labels: Sequence[str]) -> np.ndarray:
        """:meth:`log_likelihoods` as likelihoods scaled so each step's largest is 1."""
        log = self.log_likelihoods(features, labels)
        return np.exp(log - log.max(axis=1, keepdims=True)) if log.size else log

    def labelled_steps(self, labels: Sequence[str]) -> np.ndarray:
        """Per activity of ``labels``: the labelled steps learnt from (weighted; 0 for one never labelled)."""
        if not getattr(self, "classes_", ()):
            return np.zeros(len(labels))
        steps = np.bincount(self._y, weights=self._w, minlength=len(self.classes_))
        code = {a: i for i, a in enumerate(self.classes_)}
        return np.array([steps[code[a]] if a in code else 0.0 for a in labels])
