"""What a step's sensors say about the change after it: a step's evidence on the pair (its
activity, the next step's).

A step's label is the activity under way at its start, its features are read over the whole step
(:mod:`globe.recognition.features`). Where the activity changes inside the step, the step shows
the next activity too: the kettle switched on as breakfast begins fires in the step still
labelled grooming. An emission of the step's own activity
(:class:`~globe.recognition.emission.SensorEmission`) can only learn "a kettle means grooming",
and the filter then reads breakfast's first whole step as grooming if the kettle fires early in it
(or reads the step before a change as the next activity). The evidence of step t is on the pair:

    P(x_t | a_t, a_{t+1}) = P(x_t | a_t) * R(x_t; a_t, a_{t+1})

P(x_t | a_t) is the step's own emission (every next activity summed over, as it is counted) and R
how much likelier the step's features are when a_{t+1} follows a_t than whatever follows it. The
filter takes P(x_t | a_t) at step t and R at step t + 1, as evidence on each transition from a_t
to a_{t+1} (:meth:`~globe.inference.activity_filter.ActivityFilter.update`'s ``edges``): their
product is the pair's likelihood, so what is recognised at step t is P(a_t | x_0..x_t) with
nothing looked ahead, and the first step of a new activity is read with what the step before
showed of the change.

R is naive Bayes over the feature columns, as the emission: per pair (a, b) of consecutive
labelled steps, each column's values are counted; the pair's distribution is shrunk toward a's
(every pair from a pooled; ``strength`` pseudo-steps), a's toward the home at large (``smoothing``),
so a pair seen rarely says little (R near 1) and a pair never seen nothing (R = 1). ``weight``
tempers it as the emission's weight does (sensors that fire together are not independent).
Only counts are kept: a service adds each finished day.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from globe.errors import ConfigError
from globe.models.base import CountingModel
from globe.recognition.emission import home_shares, shrunk_shares
from globe.recognition.features import column_offsets


class SensorEdges(CountingModel):
    """Per step, the evidence of its features on each (activity, next activity) pair (see module doc)."""

    _parameter_constraints = {"strength": float, "smoothing": float, "weight": float}
    kind = "sensor_edges"

    def __init__(self, *, strength: float = 2.0, smoothing: float = 1.0, weight: float = 1.0) -> None:
        self.strength = strength
        self.smoothing = smoothing
        self.weight = weight

    def _validate_params(self) -> None:
        super()._validate_params()
        if not self.strength > 0 or not self.smoothing > 0:
            raise ConfigError(f"SensorEdges: strength={self.strength}, smoothing={self.smoothing}; expected "
                              "positive numbers")
        if not 0 < self.weight <= 1:
            raise ConfigError(f"SensorEdges: weight={self.weight}; expected a number in (0, 1]")

    def fit(self, features: Sequence[np.ndarray], activities: Sequence[Sequence[str | None]], sizes: np.ndarray,
            weights: Sequence[np.ndarray] | None = None) -> "SensorEdges":
        """Count each day's (steps x columns) ``features`` against the pairs of its consecutive
        activities (a step or its next one None: not counted); ``sizes`` is each column's number
        of values; ``weights`` (per day, per step) weigh the steps. Reset, then :meth:`partial_fit`."""
        self._reset()
        return self.partial_fit(features, activities, sizes, weights)

    def partial_fit(self, features: Sequence[np.ndarray], activities: Sequence[Sequence[str | None]],
                    sizes: np.ndarray, weights: Sequence[np.ndarray] | None = None) -> "SensorEdges":
        """Add days to the counts (a service's finished day)."""
        sizes = np.asarray(sizes, dtype=np.int64)
        if not hasattr(self, "training_data_"):
            self._validate_params()
            self.sizes_ = sizes
            self.offsets_ = column_offsets(sizes)
            self.pairs_: dict[tuple[str, str], np.ndarray] = {}  # (a, b) -> the (weighted) count of each cell
            self.training_data_ = 0.0
        elif not np.array_equal(sizes, self.sizes_):
            raise ValueError(f"features of {len(sizes)} columns for edges of {len(self.sizes_)}")
        cells_total = int(sizes.sum())
        for q, (x, acts) in enumerate(zip(features, activities)):
            if len(x) != len(acts):
                raise ValueError(f"{len(x)} feature rows for {len(acts)} activities")
            w = np.ones(len(acts)) if weights is None else np.asarray(weights[q], dtype=np.float64)
            cells = np.asarray(x, dtype=np.int64) + self.offsets_[None, :]
            for t in range(len(acts) - 1):
                a, b = acts[t], acts[t + 1]
                if a is None or b is None or not w[t] > 0:
                    continue
                row = self.pairs_.get((a, b))
                if row is None:
                    row = self.pairs_[(a, b)] = np.zeros(cells_total)
                np.add.at(row, cells[t], w[t])
                self.training_data_ += float(w[t])
        self._derive()
        return self

    def _derive(self) -> None:
        """Each pair's log-ratio per cell (see the module doc)."""
        sizes = self.sizes_
        pairs = sorted(self.pairs_)
        self.pair_list_: tuple[tuple[str, str], ...] = tuple(pairs)
        if not pairs:
            self.log_ratio_ = np.zeros((0, int(sizes.sum())))
            return
        counts = np.stack([self.pairs_[p] for p in pairs])
        first = sorted({a for a, _ in pairs})  # the activities changes are counted from
        of = np.array([first.index(a) for a, _ in pairs])
        own = np.zeros((len(first), counts.shape[1]))
        np.add.at(own, of, counts)  # every pair from a pooled: a's steps, whatever follows
        usual = shrunk_shares(own, home_shares(counts.sum(axis=0), sizes)[None, :], self.smoothing, sizes)
        given = shrunk_shares(counts, usual[of], self.strength, sizes)
        self.log_ratio_ = np.log(given) - np.log(usual[of])

    def tables(self, features: np.ndarray, labels: Sequence[str]) -> np.ndarray:
        """(steps x ``labels`` x ``labels``): R(x_t; a, b) of each step's features for each pair
        (a at the step, b at the next), scaled so each step's largest is 1 (what the filter
        multiplies its transitions by); 1 for a pair never counted."""
        self._check_fitted()
        cells = np.asarray(features, dtype=np.int64) + self.offsets_[None, :]
        width = len(labels)
        out = np.zeros((len(cells), width, width))
        code = {a: i for i, a in enumerate(labels)}
        known = [(i, code[a], code[b]) for i, (a, b) in enumerate(self.pair_list_) if a in code and b in code]
        if known and len(cells):
            rows = np.array([i for i, _, _ in known], dtype=np.int64)
            log = self.log_ratio_[rows][:, cells].sum(axis=2)  # pairs x steps
            out[:, [a for _, a, _ in known], [b for _, _, b in known]] = self.weight * log.T
        return np.exp(out - out.max(axis=(1, 2), keepdims=True)) if len(out) else out
