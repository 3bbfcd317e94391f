"""The library recognisers (a CRF, a plain HMM) as labellers of unlabelled days, and the
cross-validation that chooses between them and GLOBE's recogniser, on the simulated sensor home."""

from __future__ import annotations

from functools import lru_cache
from typing import Any, Sequence

import numpy as np
import pytest

from globe.data.records import Day
from globe.evaluation import recognition as R
from globe.recognition.labelling import recognise_days
from globe.recognition.library import CRF, HMM, CrfRecogniser, PlainHmmRecogniser
from tests.simulated_sensors import sensor_home


@lru_cache(maxsize=1)
def _home():
    return sensor_home(days=8, test=2, step=10, seed=5)


@pytest.mark.parametrize("make, module", [(CrfRecogniser, "sklearn_crfsuite"), (PlainHmmRecogniser, "hmmlearn")])
def test_a_library_recogniser_labels_days_as_globe_s_does(make, module):
    pytest.importorskip(module)
    home, sensors = _home()
    fitted = make().fit(home.train, sensors, 10)
    assert set(fitted.labels) == {a for d in home.train for a in d.activities}
    paths, posts = fitted.decode(home.test), fitted.smooth(home.test)
    for day, path, post in zip(home.test, paths, posts):
        assert path.shape == post.shape == (len(day), len(fitted.labels))
        assert np.array_equal(path.sum(axis=1), np.ones(len(day)))  # one activity a step
        assert np.allclose(post.sum(axis=1), 1.0, atol=1e-6) and (post >= 0).all()
    found = recognise_days(fitted, home.test)
    read = R.hindsight(fitted, home.test)
    assert [list(f.day.activities) for f in found] == read
    truth = [a for d in home.test for a in d.activities]
    assert R.recognition_scores(truth, [a for p in read for a in p]).time_slice > 0.7
    assert fitted.describe()["recogniser"] == fitted.name


class _Reader:
    """A labeller that reads each day from a table (an oracle, or one always wrong)."""

    def __init__(self, table: dict[str, tuple[str, ...]], labels: Sequence[str]) -> None:
        self.table, self.labels = table, tuple(labels)
        self.fitted_on: list[str] = []

    def fit(self, days: Sequence[Day], *_: Any) -> "_Reader":
        self.fitted_on = [d.name for d in days]
        return self

    def decode(self, days: Sequence[Day]) -> list[np.ndarray]:
        out = []
        for day in days:
            rows = np.zeros((len(day), len(self.labels)))
            rows[np.arange(len(day)), [self.labels.index(a) for a in self.table[day.name]]] = 1.0
            out.append(rows)
        return out

    smooth = decode

    def describe(self) -> dict[str, Any]:
        return {"recogniser": "reader"}


def test_cross_validation_keeps_globe_s_labeller_unless_a_library_one_reads_held_out_days_better(monkeypatch):
    home, sensors = _home()
    labels = sorted({a for d in home.train for a in d.activities})
    oracle = {d.name: d.activities for d in home.train}
    wrong = {d.name: tuple(labels[(labels.index(a) + 1) % len(labels)] for a in d.activities) for d in home.train}
    made: list[_Reader] = []

    def library(table):
        def make(*_a, **_k):
            made.append(_Reader(table, labels))
            return made[-1]
        return make
    monkeypatch.setattr(R.library, "available", lambda: (CRF, HMM))
    monkeypatch.setattr(R, "choose_hmm_features", lambda *a: ("raw",))
    monkeypatch.setattr(R, "CrfRecogniser", library(wrong))
    monkeypatch.setattr(R, "PlainHmmRecogniser", library(wrong))
    kept = R.choose_labeller(home.train, sensors, 10)
    assert kept.name == R.GLOBE_LABELLER and set(kept.held_out) == {R.GLOBE_LABELLER, CRF, HMM}
    assert kept.held_out[CRF] == 0.0 < kept.held_out[R.GLOBE_LABELLER]
    assert kept.describe()["chosen"] == R.GLOBE_LABELLER

    monkeypatch.setattr(R, "PlainHmmRecogniser", library(oracle))
    chosen = R.choose_labeller(home.train, sensors, 10)
    assert chosen.name == HMM and chosen.held_out[HMM] == 1.0
    assert chosen.labeller is made[-1] and made[-1].fitted_on == [d.name for d in home.train]  # refitted on all


def test_one_labelled_day_leaves_nothing_to_hold_out():
    home, sensors = _home()
    choice = R.choose_labeller(home.train[:1], sensors, 10)
    assert choice.name == R.GLOBE_LABELLER and choice.held_out == {}
