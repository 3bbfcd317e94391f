"""The Table I rows: how each method predicts activities and chooses objects.

``ngram_smoothed``, ``routine`` and ``globe_routine`` go beyond the paper; their
hyperparameters are chosen by cross-validation over each household's training days
(:func:`globe.evaluation.tuning.tuned_models`), never by looking at test days.

Three rows are baselines (:data:`BASELINES`), rules every model must clear: persistence (objects
from the n-gram, as the paper's row), the time-of-day mode and hour + current activity, the last
two with the object baseline (the most frequent use given the clock hour and the predicted
activity, :class:`~globe.models.baselines.HourActivityObjects`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable, Sequence

from globe import assembly
from globe.assembly import FittedHousehold
from globe.config import DeployMethod, GlobeConfig, ModelConfig
from globe.data.records import Household
from globe.evaluation.selection import DataKey, FitKey, Memo, Selection
from globe.evaluation.tuning import chosen_alignment, tuned_gate, tuned_models
from globe.models.base import ActivityModelBase
from globe.models.baselines import (
    HOUR_ACTIVITY,
    HourActivityBaseline,
    HourActivityObjects,
    PersistenceModel,
    TimeOfDayBaseline,
)
from globe.reasoning.backends.base import LLMBackend
from globe.reasoning.choice import ObjectChooser
from globe.reasoning.gate import LLMOnlyChooser
from globe.sequences.movements import Alignment
from globe.sequences.runs import object_runs


@dataclass(frozen=True, slots=True)
class Prepared:
    """A method ready to run on one household."""

    activity: ActivityModelBase | TimeOfDayBaseline | HourActivityBaseline
    chooser: ObjectChooser
    train_s: float
    selection: dict[str, Selection] = field(default_factory=dict)
    alignment: Alignment | None = None  # chosen by cross-validation; None: ``sequences.alignment``
    stay_margin: float = 1.0  # the next activity said (models.stay_margin), chosen by cross-validation in a family


@dataclass(frozen=True, slots=True)
class Method:
    name: str
    label: str
    needs_llm: bool
    prepare: Callable[[Household, GlobeConfig, LLMBackend | None, Memo], Prepared]
    family: str | None = None  # the model family chosen by cross-validation, if any
    baseline: bool = False  # a rule every model must clear (said beside its label wherever it is shown)
    deploys: DeployMethod | None = None  # with recognised activities, the session scored (None: a rule on them)

    @property
    def shown(self) -> str:
        """The label as tables and plots show it: a baseline says so."""
        return f"{self.label} (baseline)" if self.baseline else self.label


def _fit(h: Household, cfg: GlobeConfig, memo: Memo, models: ModelConfig | None = None) -> FittedHousehold:
    """Both models of ``models`` (default ``cfg.models``) on ``h``'s training days, fitted once per
    household and configuration: the n-gram rows, GLOBE's variants and every gate threshold of the
    robustness suite train the same models (read-only afterwards)."""
    cfg = cfg if models is None else cfg.model_copy(update={"models": models})
    key = FitKey("household", DataKey.of(h), None, cfg.models, cfg.sequences.alignment)
    return memo.get(key, lambda: assembly.fit_household(h, cfg))


def _persistence(h: Household, cfg: GlobeConfig, backend: LLMBackend | None, memo: Memo) -> Prepared:
    fitted = _fit(h, cfg, memo)
    t = time.perf_counter()
    model = PersistenceModel().fit([d.activities for d in h.train])
    return Prepared(model, ObjectChooser(fitted.objects), time.perf_counter() - t + fitted.train_s)


def object_baseline(h: Household, alignment: Alignment) -> HourActivityObjects:
    """The object baseline counted on ``h``'s training days: every use (:mod:`globe.sequences.movements`:
    a return from a use place is none), credited to its activity by ``alignment`` and to that step's
    minute."""
    return HourActivityObjects().fit(object_runs(h.train, h.objects, alignment, timed=True))


def _time_of_day(h: Household, cfg: GlobeConfig, backend: LLMBackend | None, memo: Memo) -> Prepared:
    t = time.perf_counter()
    model = TimeOfDayBaseline().fit(h.train)
    chooser = ObjectChooser(object_baseline(h, cfg.sequences.alignment))
    return Prepared(model, chooser, time.perf_counter() - t)


def _hour_activity(h: Household, cfg: GlobeConfig, backend: LLMBackend | None, memo: Memo) -> Prepared:
    t = time.perf_counter()
    model = HourActivityBaseline(1).fit(h.train)
    chooser = ObjectChooser(object_baseline(h, cfg.sequences.alignment))
    return Prepared(model, chooser, time.perf_counter() - t)


def _globe(h: Household, cfg: GlobeConfig, backend: LLMBackend | None, memo: Memo) -> Prepared:
    fitted = _fit(h, cfg, memo)
    chooser = assembly.object_chooser(fitted.objects, cfg.gate, backend, marginal=cfg.models.object_marginal)
    return Prepared(fitted.activity, chooser, fitted.train_s, stay_margin=cfg.models.stay_margin)


def _ngram(h: Household, cfg: GlobeConfig, backend: LLMBackend | None, memo: Memo) -> Prepared:
    return _globe(h, cfg, None, memo)  # the same models, the n-gram's choice alone


def _globe_combine(h: Household, cfg: GlobeConfig, backend: LLMBackend | None, memo: Memo) -> Prepared:
    return _globe(h, cfg.with_overrides({"gate.mode": "combine"}), backend, memo)


def personal_examples(cfg: GlobeConfig) -> int:
    """How many of the person's recent runs the personalised rows show the LLM."""
    return cfg.gate.examples or cfg.evaluation.personal_examples


def _globe_personal(h: Household, cfg: GlobeConfig, backend: LLMBackend | None, memo: Memo) -> Prepared:
    return _globe(h, cfg.with_overrides({"gate.examples": personal_examples(cfg)}), backend, memo)


def _llm_only(h: Household, cfg: GlobeConfig, backend: LLMBackend | None, memo: Memo) -> Prepared:
    if backend is None:
        raise ValueError("llm_only needs an LLM backend")
    fitted = _fit(h, cfg, memo)  # only O(a), the candidate lists, is taken from training
    model = PersistenceModel().fit([d.activities for d in h.train])
    return Prepared(model, LLMOnlyChooser(fitted.objects, backend), fitted.train_s)


def families(methods: Sequence[str]) -> list[str]:
    """The model families the listed methods choose by cross-validation."""
    return list(dict.fromkeys(f for m in methods if (f := METHODS[m].family)))


def _tuned(family: str, with_gate: bool) -> Callable[[Household, GlobeConfig, LLMBackend | None, Memo], Prepared]:
    def prepare(h: Household, cfg: GlobeConfig, backend: LLMBackend | None, memo: Memo) -> Prepared:
        models, selection = tuned_models(h, cfg, family, memo)
        alignment = chosen_alignment(selection, cfg)
        if alignment != cfg.sequences.alignment:
            cfg = cfg.with_overrides({"sequences.alignment": alignment})
        fitted = _fit(h, cfg, memo, models)
        gate_cfg = cfg.gate
        if with_gate and backend is not None:
            gate_cfg, gate_sel = tuned_gate(h, cfg, models, backend, memo, personal_examples(cfg))
            selection = selection | {"gate": gate_sel}
        chooser = assembly.object_chooser(fitted.objects, gate_cfg, backend if with_gate else None,
                                          marginal=models.object_marginal)
        return Prepared(fitted.activity, chooser, fitted.train_s, selection, alignment, models.stay_margin)

    return prepare


METHODS: dict[str, Method] = {
    m.name: m
    for m in (
        Method("persistence", "Persistence", False, _persistence, baseline=True),
        Method("time_of_day", "Time-of-day mode", False, _time_of_day, baseline=True),
        Method(HOUR_ACTIVITY, "Hour + activity", False, _hour_activity, baseline=True),
        Method("ngram", "n-gram Markov", False, _ngram, deploys="ngram"),
        Method("globe", "GLOBE", True, _globe, deploys="ngram"),
        Method("globe_combine", "GLOBE, LLM + n-gram scores", True, _globe_combine, deploys="ngram"),
        Method("globe_personal", "GLOBE, personalised prompt", True, _globe_personal, deploys="ngram"),
        Method("llm_only", "LLM-only", True, _llm_only),
        Method("ngram_smoothed", "n-gram, Witten-Bell + time (CV)", False, _tuned("witten_bell", False), "witten_bell",
               deploys="ngram_smoothed"),
        Method("routine", "Routine model (CV)", False, _tuned("routine", False), "routine", deploys="routine"),
        Method("globe_routine", "GLOBE + routine model (personalised, gate CV)", True, _tuned("routine", True),
               "routine", deploys="routine"),
    )
}

BASELINES: tuple[str, ...] = tuple(name for name, m in METHODS.items() if m.baseline)
"""The baseline rows, in Table I's order: every evaluation shows them beside the models."""


def with_baselines(methods: Sequence[str]) -> list[str]:
    """``methods`` with every baseline row it lacks, right after the last baseline listed (first,
    when none is): no table of models without the rules they must beat."""
    missing = [b for b in BASELINES if b not in methods]
    at = max((i + 1 for i, m in enumerate(methods) if m in BASELINES), default=0)
    return [*methods[:at], *missing, *methods[at:]]
