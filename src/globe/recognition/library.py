"""Recognisers from well-kept libraries, read with hindsight, beside GLOBE's own
(:class:`~globe.recognition.recogniser.Recogniser`): the discriminative and the plain generative
model the literature compares against (van Kasteren et al., UbiComp 2008).

- :class:`CrfRecogniser`: a linear-chain CRF (sklearn-crfsuite, L-BFGS with its default
  regularisation) over the step features and the hour.
- :class:`PlainHmmRecogniser`: a plain HMM (hmmlearn's Viterbi and forward-backward): one state
  per activity, time-free transitions and a start counted with add-one smoothing, each feature
  column independent given the activity (naive Bayes, add-one). Its dynamics do not know the
  clock, which is what GLOBE's add.

Both offer what labelling a day needs (:class:`~globe.recognition.labelling.Labeller`):
:attr:`labels`, :meth:`decode` (the most probable sequence, one-hot) and :meth:`smooth` (each
step's marginals), so cross-validation can choose one of them to label the days nobody labelled
(:func:`globe.evaluation.recognition.choose_labeller`). Neither reads a day online: a CRF's
marginals at step t need the whole day. Each needs its optional package (``pip install
globe[recognition]``); :func:`available` says which are installed.
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from globe.data.records import Day
from globe.data.sensors import SensorData
from globe.recognition.features import REPRESENTATIONS, Layout, step_features

CRF, HMM = "crf (sklearn-crfsuite)", "plain hmm (hmmlearn)"
CRF_FEATURES = ("raw", "change", "last", "room")


def available() -> tuple[str, ...]:
    """The library recognisers whose package is installed (:data:`CRF`, :data:`HMM`)."""
    out = []
    for name, module in ((CRF, "sklearn_crfsuite"), (HMM, "hmmlearn")):
        try:
            __import__(module)
        except ImportError:
            continue
        out.append(name)
    return tuple(out)


def _one_hot(codes: Sequence[int], width: int) -> np.ndarray:
    out = np.zeros((len(codes), width))
    out[np.arange(len(codes)), np.asarray(codes, dtype=np.int64)] = 1.0
    return out


class _LibraryRecogniser:
    """What both share: the home's step features of a day, and how they describe themselves."""

    name = ""
    features: tuple[str, ...]
    labels: tuple[str, ...]

    def _fit_layout(self, sensors: SensorData, step_minutes: int) -> None:
        self.sensors_, self.step_minutes_ = sensors, step_minutes
        self.layout_ = Layout.of(sensors.sensors, self.features)

    def _x(self, day: Day) -> np.ndarray:
        return step_features(self.layout_, self.sensors_.of(day.name), day.minutes, self.step_minutes_)

    def describe(self) -> dict[str, Any]:
        return {"recogniser": self.name, "features": list(self.features)}


class CrfRecogniser(_LibraryRecogniser):
    """A linear-chain CRF over the step features and the hour (see module doc)."""

    name = CRF

    def __init__(self, features: tuple[str, ...] = CRF_FEATURES, max_iterations: int = 100) -> None:
        self.features = features
        self.max_iterations = max_iterations

    def fit(self, days: Sequence[Day], sensors: SensorData, step_minutes: int) -> "CrfRecogniser":
        import sklearn_crfsuite

        self._fit_layout(sensors, step_minutes)
        self.crf_ = sklearn_crfsuite.CRF(algorithm="lbfgs", max_iterations=self.max_iterations,
                                         all_possible_transitions=True)
        self.crf_.fit([self._rows(d) for d in days], [list(d.activities) for d in days])
        self.labels = tuple(sorted(self.crf_.classes_))
        return self

    def _rows(self, day: Day) -> list[dict[str, float]]:
        rows = []
        for values, minute in zip(self._x(day).tolist(), day.minutes):
            row = {f"{n}={v}": 1.0 for n, v in zip(self.layout_.names, values)
                   if v or not n.startswith(("raw", "change"))}
            row[f"hour={minute // 60 % 24}"] = 1.0
            rows.append(row)
        return rows

    def decode(self, days: Sequence[Day]) -> list[np.ndarray]:
        """Per day, the most probable sequence (Viterbi), one-hot over :attr:`labels`."""
        code = {a: i for i, a in enumerate(self.labels)}
        paths = self.crf_.predict([self._rows(d) for d in days])
        return [_one_hot([code[a] for a in path], len(self.labels)) for path in paths]

    def smooth(self, days: Sequence[Day]) -> list[np.ndarray]:
        """Per day, (steps x :attr:`labels`): each step's marginal given the whole day."""
        marginals = self.crf_.predict_marginals([self._rows(d) for d in days])
        return [np.array([[step.get(a, 0.0) for a in self.labels] for step in day]) for day in marginals]


class PlainHmmRecogniser(_LibraryRecogniser):
    """A plain HMM over the step features (see module doc)."""

    name = HMM

    def __init__(self, features: tuple[str, ...] = REPRESENTATIONS[0]) -> None:
        self.features = features

    def fit(self, days: Sequence[Day], sensors: SensorData, step_minutes: int) -> "PlainHmmRecogniser":
        from hmmlearn.base import BaseHMM

        self._fit_layout(sensors, step_minutes)
        self.labels = names = tuple(sorted({a for d in days for a in d.activities}))
        code = {a: i for i, a in enumerate(names)}
        start, moves = np.ones(len(names)), np.ones((len(names), len(names)))
        counts = [np.ones((len(names), size)) for size in self.layout_.sizes]
        for day in days:
            x, y = self._codes(day), np.array([code[a] for a in day.activities], dtype=np.int64)
            start[y[0]] += 1
            np.add.at(moves, (y[:-1], y[1:]), 1)
            for c, table in enumerate(counts):
                np.add.at(table, (y, x[:, c]), 1)
        log_emission = [np.log(t / t.sum(axis=1, keepdims=True)) for t in counts]

        class PlainHMM(BaseHMM):  # hmmlearn's documented extension point: the emission's log-likelihood
            def _check(self) -> None:
                self._check_sum_1("startprob_")
                self._check_sum_1("transmat_")

            def _compute_log_likelihood(self, X: np.ndarray) -> np.ndarray:
                return sum(table[:, X[:, c]].T for c, table in enumerate(log_emission))

        self.hmm_ = PlainHMM(n_components=len(names))
        self.hmm_.startprob_, self.hmm_.transmat_ = start / start.sum(), moves / moves.sum(axis=1, keepdims=True)
        return self

    def _codes(self, day: Day) -> np.ndarray:
        return self._x(day).astype(np.int64)

    def _split(self, found: np.ndarray, days: Sequence[Day]) -> list[np.ndarray]:
        return np.split(found, np.cumsum([len(d) for d in days])[:-1].tolist())

    def decode(self, days: Sequence[Day]) -> list[np.ndarray]:
        """Per day, the most probable sequence (Viterbi), one-hot over :attr:`labels`."""
        states = self.hmm_.predict(np.vstack([self._codes(d) for d in days]), [len(d) for d in days])
        return [_one_hot(part.tolist(), len(self.labels)) for part in self._split(states, days)]

    def smooth(self, days: Sequence[Day]) -> list[np.ndarray]:
        """Per day, (steps x :attr:`labels`): each step's posterior given the whole day."""
        post = self.hmm_.predict_proba(np.vstack([self._codes(d) for d in days]), [len(d) for d in days])
        return self._split(post, days)
