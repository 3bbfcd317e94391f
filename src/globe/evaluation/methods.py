"""The Table I rows: how each method predicts activities and chooses objects.

``ngram_smoothed``, ``routine`` and ``globe_routine`` go beyond the paper; their
hyperparameters are chosen by cross-validation over each household's training days
(:func:`globe.evaluation.tuning.tuned_models`), never by looking at test days.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable

from globe.config import GateConfig, GlobeConfig, ModelConfig
from globe.data.records import Household
from globe.evaluation.protocol import ActivityPredictor
from globe.evaluation.tuning import tuned_gate, tuned_models
from globe.models.baselines import PersistenceModel
from globe.models.selection import Selection
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
    selection: dict[str, Selection] = field(default_factory=dict)


@dataclass(frozen=True, slots=True)
class Method:
    name: str
    label: str
    needs_llm: bool
    prepare: Callable[[Household, GlobeConfig, LLMBackend | None, dict], Prepared]


def _fit(h: Household, cfg: GlobeConfig, models: ModelConfig | None = None) -> FittedHousehold:
    return fit_household(h, models or cfg.models, cfg.sequences.alignment)


def _gate(fitted: FittedHousehold, cfg: GlobeConfig, backend: LLMBackend | None, marginal: bool,
          g: GateConfig | None = None) -> UncertaintyGate:
    g = g or cfg.gate
    return UncertaintyGate(fitted.objects, backend, threshold=g.threshold, top_k=g.top_k, min_prob=g.min_prob,
                           mode=g.mode, combine_weight=g.combine_weight, marginal=marginal, examples=g.examples)


def _persistence(h: Household, cfg: GlobeConfig, backend: LLMBackend | None, cache: dict) -> Prepared:
    fitted = _fit(h, cfg)
    t = time.perf_counter()
    model = PersistenceModel().fit([d.activities for d in h.train])
    return Prepared(model, ObjectChooser(fitted.objects), time.perf_counter() - t + fitted.train_s)


def _ngram(h: Household, cfg: GlobeConfig, backend: LLMBackend | None, cache: dict) -> Prepared:
    fitted = _fit(h, cfg)
    return Prepared(fitted.activity, ObjectChooser(fitted.objects, marginal=cfg.models.object_marginal), fitted.train_s)


def _globe(h: Household, cfg: GlobeConfig, backend: LLMBackend | None, cache: dict) -> Prepared:
    fitted = _fit(h, cfg)
    return Prepared(fitted.activity, _gate(fitted, cfg, backend, cfg.models.object_marginal), fitted.train_s)


def _globe_combine(h: Household, cfg: GlobeConfig, backend: LLMBackend | None, cache: dict) -> Prepared:
    return _globe(h, cfg.with_overrides({"gate.mode": "combine"}), backend, cache)


PERSONAL_EXAMPLES = 4  # the person's last runs of the activity shown to the LLM


def _globe_personal(h: Household, cfg: GlobeConfig, backend: LLMBackend | None, cache: dict) -> Prepared:
    examples = cfg.gate.examples or PERSONAL_EXAMPLES
    return _globe(h, cfg.with_overrides({"gate.examples": examples}), backend, cache)


def _llm_only(h: Household, cfg: GlobeConfig, backend: LLMBackend | None, cache: dict) -> Prepared:
    if backend is None:
        raise ValueError("llm_only needs an LLM backend")
    fitted = _fit(h, cfg)  # only O(a), the candidate lists, is taken from training
    model = PersistenceModel().fit([d.activities for d in h.train])
    return Prepared(model, LLMOnlyChooser(fitted.objects, backend), fitted.train_s)


def _tuned(family: str, with_gate: bool) -> Callable[[Household, GlobeConfig, LLMBackend | None, dict], Prepared]:
    def prepare(h: Household, cfg: GlobeConfig, backend: LLMBackend | None, cache: dict) -> Prepared:
        models, selection = tuned_models(h, cfg, family, cache)
        fitted = _fit(h, cfg, models)
        if with_gate and backend is not None:
            gate_cfg, gate_sel = tuned_gate(h, cfg, models, backend, cache, cfg.gate.examples or PERSONAL_EXAMPLES)
            selection = selection | {"gate": gate_sel}
            chooser: ObjectChooser = _gate(fitted, cfg, backend, models.object_marginal, gate_cfg)
        else:
            chooser = ObjectChooser(fitted.objects, marginal=models.object_marginal)
        return Prepared(fitted.activity, chooser, fitted.train_s, selection)

    return prepare


METHODS: dict[str, Method] = {
    m.name: m
    for m in (
        Method("persistence", "Persistence", False, _persistence),
        Method("ngram", "n-gram Markov", False, _ngram),
        Method("globe", "GLOBE", True, _globe),
        Method("globe_combine", "GLOBE, LLM + n-gram scores", True, _globe_combine),
        Method("globe_personal", "GLOBE, personalised prompt", True, _globe_personal),
        Method("llm_only", "LLM-only", True, _llm_only),
        Method("ngram_smoothed", "n-gram, Witten-Bell + time (CV)", False, _tuned("witten_bell", False)),
        Method("routine", "Routine model (CV)", False, _tuned("routine", False)),
        Method("globe_routine", "GLOBE + routine model (personalised, gate CV)", True, _tuned("routine", True)),
    )
}
