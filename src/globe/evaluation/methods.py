"""The Table I rows: how each method predicts activities and chooses objects."""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable

from globe.config import GlobeConfig
from globe.data.records import Household
from globe.evaluation.protocol import ActivityPredictor
from globe.models.baselines import PersistenceModel
from globe.pipeline import FittedHousehold, fit_household
from globe.reasoning.backends.base import LLMBackend
from globe.reasoning.choice import ObjectChooser
from globe.reasoning.gate import LLMOnlyChooser, UncertaintyGate


@dataclass(frozen=True, slots=True)
class Prepared:
    """A method ready to run on one household."""

    activity: ActivityPredictor
    chooser: ObjectChooser
    train_s: float


@dataclass(frozen=True, slots=True)
class Method:
    name: str
    label: str
    needs_llm: bool
    prepare: Callable[[Household, GlobeConfig, LLMBackend | None], Prepared]


def _fit(h: Household, cfg: GlobeConfig) -> FittedHousehold:
    return fit_household(h, cfg.models, cfg.sequences.alignment)


def _gate(fitted: FittedHousehold, cfg: GlobeConfig, backend: LLMBackend | None) -> UncertaintyGate:
    g = cfg.gate
    return UncertaintyGate(fitted.objects, backend, threshold=g.threshold, top_k=g.top_k,
                           min_prob=g.min_prob, mode=g.mode, combine_weight=g.combine_weight)


def _persistence(h: Household, cfg: GlobeConfig, backend: LLMBackend | None) -> Prepared:
    fitted = _fit(h, cfg)
    t = time.perf_counter()
    model = PersistenceModel().fit([d.activities for d in h.train])
    return Prepared(model, ObjectChooser(fitted.objects), time.perf_counter() - t + fitted.train_s)


def _ngram(h: Household, cfg: GlobeConfig, backend: LLMBackend | None) -> Prepared:
    fitted = _fit(h, cfg)
    return Prepared(fitted.activity, ObjectChooser(fitted.objects), fitted.train_s)


def _globe(h: Household, cfg: GlobeConfig, backend: LLMBackend | None) -> Prepared:
    fitted = _fit(h, cfg)
    return Prepared(fitted.activity, _gate(fitted, cfg, backend), fitted.train_s)


def _llm_only(h: Household, cfg: GlobeConfig, backend: LLMBackend | None) -> Prepared:
    if backend is None:
        raise ValueError("llm_only needs an LLM backend")
    fitted = _fit(h, cfg)  # only O(a), the candidate lists, is taken from training
    model = PersistenceModel().fit([d.activities for d in h.train])
    return Prepared(model, LLMOnlyChooser(fitted.objects, backend), fitted.train_s)


METHODS: dict[str, Method] = {
    m.name: m
    for m in (
        Method("persistence", "Persistence", False, _persistence),
        Method("ngram", "n-gram Markov", False, _ngram),
        Method("globe", "GLOBE", True, _globe),
        Method("llm_only", "LLM-only", True, _llm_only),
    )
}
