"""Experiments: run methods over households, then turn records into score rows."""

from __future__ import annotations

import logging
import statistics
from dataclasses import dataclass, field
from typing import Iterable, Sequence, cast

from globe import assembly
from globe.config import GlobeConfig
from globe.data.records import Household
from globe.evaluation.methods import METHODS
from globe.evaluation.metrics import AVERAGES, Average, calibration, log_loss, records_f1, rounded
from globe.evaluation.protocol import ActivityPredictor, DayPredictor, Evaluation, evaluate_days
from globe.evaluation.recognised import Recognised, served_scan
from globe.evaluation.selection import Memo
from globe.models.base import ActivityModelBase
from globe.reasoning.backends.base import LLMBackend

log = logging.getLogger(__name__)


@dataclass(slots=True)
class MethodRun:
    method: str
    household: str
    evaluation: Evaluation
    oracle: Evaluation
    train_s: float
    selection: dict = field(default_factory=dict)
    built: dict = field(default_factory=dict)  # what really ran: :func:`globe.assembly.describe`

    @property
    def llm_calls(self) -> int:
        return sum(r.asked for r in self.evaluation.objects)

    @property
    def llm_s(self) -> float:
        """The time the LLM took: its batched scoring of the questions, then each answer's read."""
        return self.evaluation.prefetch_s + sum(r.latency_s for r in self.evaluation.objects)


def run_methods(
    config: GlobeConfig,
    households: Iterable[Household],
    methods: Iterable[str],
    backend: LLMBackend | None,
    memo: Memo | None = None,
    recognised: Sequence[Recognised] = (),
) -> list[MethodRun]:
    """Evaluate each method on each household's test days (plus the true-activity oracle).

    ``memo`` keeps cross-validation results and fits between calls on the same households, so
    methods of one family (``routine``, ``globe_routine``) share one search. A household among
    ``recognised`` (its activities recognised from its sensors) is told, by each row a household
    can be deployed with, what the session so deployed said after each step
    (:func:`~globe.evaluation.recognised.served_scan`)."""
    runs = []
    memo = Memo() if memo is None else memo
    replays = {r.household.name: r for r in recognised}
    for name in methods:
        method = METHODS[name]
        if method.needs_llm and backend is None:
            log.warning("skipping %s: no LLM backend configured", name)
            continue
        for h in households:
            prepared = method.prepare(h, config, backend, memo)
            alignment = prepared.alignment or config.sequences.alignment
            predictor: ActivityPredictor | DayPredictor = prepared.activity
            days, margin, replay = h.test, prepared.stay_margin, replays.get(h.name)
            if replay is not None and method.deploys is not None:  # what the session deployed so serves
                served = served_scan(replay, method.deploys, config, memo)
                predictor, days, margin = served.predictor, served.days, served.stay_margin
            ev = evaluate_days(h, days, predictor, prepared.chooser, alignment=alignment, stay_margin=margin)
            oracle = evaluate_days(h, h.test, prepared.activity, prepared.chooser, alignment=alignment, oracle=True,
                                   stay_margin=prepared.stay_margin)
            activity = cast(ActivityModelBase, prepared.activity)  # a baseline too: describe reads get_params()
            runs.append(MethodRun(name, h.name, ev, oracle, prepared.train_s, prepared.selection,
                                  assembly.describe(activity, prepared.chooser, prepared.stay_margin)))
    return runs


def _f1s(ev: Evaluation, average: Average) -> tuple[float | None, float | None]:
    return records_f1(ev.activity, average), records_f1(ev.objects, average)


def table1_rows(runs: Sequence[MethodRun]) -> list[dict]:
    """Rows of ``table1.csv``: method, household (A, B, C, mean), average, the three F1s. An absent
    F1 (nothing to score) is None; the mean row averages the households where each value is
    present and says how many (``n_households``: activity and mean F1, ``n_households_object``)."""
    rows = []
    for method in dict.fromkeys(r.method for r in runs):
        mine = [r for r in runs if r.method == method]
        for average in AVERAGES:
            per: list[tuple[float | None, float | None]] = []
            for run in mine:
                a, o = _f1s(run.evaluation, average)
                per.append((a, o))
                rows.append(_row(method, run.household, average, a, o))
            acts = [a for a, _ in per if a is not None]
            objs = [o for _, o in per if o is not None]
            both = [(a + o) / 2 for a, o in per if a is not None and o is not None]
            rows.append({"method": method, "household": "mean", "average": average,
                         "activity_f1": round(statistics.fmean(acts), 4) if acts else None,
                         "object_f1": round(statistics.fmean(objs), 4) if objs else None,
                         "mean_f1": round(statistics.fmean(both), 4) if both else None,
                         "n_households": len(acts), "n_households_object": len(objs)})
    return rows


def _row(method: str, household: str, average: str, a: float | None, o: float | None) -> dict:
    """One household's row; the mean F1 needs both parts (an activity-only home has none)."""
    return {"method": method, "household": household, "average": average,
            "activity_f1": None if a is None else round(a, 4), "object_f1": None if o is None else round(o, 4),
            "mean_f1": None if a is None or o is None else round((a + o) / 2, 4),
            "n_households": int(a is not None), "n_households_object": int(o is not None)}


def detail_rows(runs: Sequence[MethodRun]) -> list[dict]:
    """Weighted-F1 details: change steps, the true-activity oracle, how often the gate opened."""
    rows = []
    for run in runs:
        ev = run.evaluation
        changes = [r for r in ev.activity if r.is_change]
        asked = [r for r in ev.objects if r.asked]
        rows.append({
            "method": run.method, "household": run.household,
            "activity_f1": rounded(_f1s(ev, "weighted")[0]),
            "activity_f1_change_steps": rounded(records_f1(changes)),
            "activity_log_loss": rounded(log_loss([r.p_true for r in ev.activity])),
            "change_steps": len(changes),
            "object_f1": rounded(_f1s(ev, "weighted")[1]),
            "object_f1_oracle_activity": rounded(_f1s(run.oracle, "weighted")[1]),
            "object_events": len(ev.objects),
            "gate_opened": len(asked),
            "gate_rate": round(len(asked) / len(ev.objects), 4) if ev.objects else 0.0,
            "llm_fallbacks": sum(r.choice.fallback is not None for r in asked),
            "llm_changed_choice": sum(r.predicted != r.choice.ngram_choice for r in asked
                                      if r.choice.fallback is None and r.choice.ngram_choice),
        })
    return rows


def timing_rows(runs: Sequence[MethodRun]) -> list[dict]:
    return [{"method": r.method, "household": r.household, "train_s": round(r.train_s, 4),
             "inference_s": round(r.evaluation.inference_s, 4), "llm_calls": r.llm_calls, "llm_s": round(r.llm_s, 4),
             "selection_s": round(sum(s.seconds for s in r.selection.values()), 4)}
            for r in runs]


def selection_rows(runs: Sequence[MethodRun]) -> list[dict]:
    """Every candidate tried by cross-validation on training days, its score, and the choice."""
    rows, seen = [], set()
    for run in runs:
        for part, sel in run.selection.items():
            if id(sel) in seen:  # methods of one family share their search
                continue
            seen.add(id(sel))
            measured = sel.metrics or [{"f1": score} for _, score in sel.scores]
            for (params, _), metrics in zip(sel.scores, measured):
                rows.append({"method": run.method, "household": run.household, "part": part,
                             "params": ";".join(f"{k}={v}" for k, v in params.items()),
                             "criterion": "log_loss" if sel.criterion == "log_loss" else "weighted_f1",
                             "cv_log_loss": rounded(metrics.get("log_loss")),
                             "cv_weighted_f1": rounded(metrics.get("f1")), "chosen": params == sel.best,
                             "at_edge": ";".join(sel.at_edge) if params == sel.best else ""})
    return rows


def calibration_rows(runs: Sequence[MethodRun], bins: int = 10) -> tuple[list[dict], dict[str, dict]]:
    """ECE of the activity and object probabilities per method (pooled over households)."""
    rows: list[dict] = []
    curves: dict[str, dict] = {"activity": {}, "object": {}}
    for method in dict.fromkeys(r.method for r in runs):
        mine = [r for r in runs if r.method == method]
        acts = [x for r in mine for x in r.evaluation.activity]
        objs = [x for r in mine for x in r.evaluation.objects]
        ece_a, curve_a = calibration([x.confidence for x in acts], [x.true == x.predicted for x in acts], bins)
        ece_o, curve_o = calibration([x.confidence for x in objs], [x.true == x.predicted for x in objs], bins)
        curves["activity"][method], curves["object"][method] = curve_a, curve_o
        rows.append({"method": method, "activity_ece": round(ece_a, 4), "object_ece": round(ece_o, 4),
                     "activity_predictions": len(acts), "object_predictions": len(objs)})
    return rows, curves
