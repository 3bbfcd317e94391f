"""Evaluation with activity labels visible on only p % of the history steps.

A robot rarely gets a clean activity label for every step. Per test day, a fixed share of the
steps (``filter.fractions``; which ones is drawn with a seed from ``filter.seed``, the household
and the day, nested across shares) shows its label; the others must be inferred by the activity
filter (:mod:`globe.inference.activity_filter`) from the time of day, the routine and the object
movements it sees. Everything else is the protocol of :func:`globe.evaluation.protocol.evaluate_days`:

- **Activity:** at every step t = 1..T-1, predict a_t from the visible labels among a_0..a_{t-1}
  and the movements seen up to step t-1 (weighted F1 and log loss over all steps).
- **Object:** at every movement event, the object from the filtered activity distribution of
  the event's activity step (the chooser mixes over it), with the protocol's run context. With
  ``sequences.alignment = "previous"`` the event is seen one step after its activity step, so
  that distribution also uses the places seen *at* the activity step (what a robot knows then);
  with every label visible and the movement credited to the earlier activity this is exactly
  the protocol's distribution.
- **Lookahead** (when :mod:`globe.evaluation.lookahead` is present): the relocation F1 at each
  horizon, forecasting from a mixture over the filter's most probable histories with the
  lookahead's own forecaster (movement settings and per-horizon thresholds chosen on fully
  labelled training days by :func:`globe.evaluation.lookahead.choose_settings`), so that with
  every label visible it is exactly the routine row of ``lookahead.csv``.

The activity model is the routine model chosen by cross-validation
(:func:`globe.evaluation.tuning.tuned_models`); the filter's movement evidence (which step's
activity a movement tells about, and how much to trust it) is chosen by cross-validation on
*training* days with every label hidden. Test days are never used to choose anything.
"""

from __future__ import annotations

import time
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from globe import assembly
from globe.config import FilterConfig, GlobeConfig, ModelConfig
from globe.data.records import Day, Household
from globe.errors import ConfigError
from globe.evaluation import lookahead as lk
from globe.evaluation import relocation, report
from globe.evaluation.metrics import f1, log_loss, records_f1
from globe.evaluation.parallel import run_forked, worker_count
from globe.evaluation.protocol import ActivityRecord, FixedScan, ObjectRecord, evaluate_days
from globe.evaluation.selection import DataKey, FitKey, Memo, SearchKey, Selection, best_of, grid
from globe.evaluation.tuning import (
    chosen_alignment,
    data_folds,
    fitted_activity,
    fitted_objects,
    fold_days,
    tuned_models,
)
from globe.inference.activity_filter import ActivityFilter, Belief, as_dicts, filtered_beliefs, label_mask
from globe.inference.beam import tie_key
from globe.inference.emission import MovementEmission
from globe.inference.forecast import Forecaster, first_locations, mix
from globe.inference.paths import Roots
from globe.models.base import ActivityModelBase
from globe.sequences.movements import Alignment, moved_objects

Progress = Callable[[str], None]
METHOD = "routine"


def day_mask(fcfg: FilterConfig, household: str, day: Day, fraction: float) -> list[bool]:
    """The visible steps of ``day`` at ``fraction``: seeded by the configured seed, the household
    and the day's name (stable across runs and Python versions), nested across fractions."""
    seed = (fcfg.seed, zlib.crc32(household.encode()), zlib.crc32(day.name.encode()))
    return label_mask(len(day), fraction, seed)


def check_fractions(fractions: Sequence[float]) -> tuple[float, ...]:
    bad = [f for f in fractions if not 0.0 <= f <= 1.0]
    if bad or not fractions:
        raise ConfigError(f"filter.fractions: {list(fractions)!r}; expected shares between 0 and 1")
    return tuple(fractions)


def day_beliefs(activity: ActivityModelBase, emission: MovementEmission | None, config: GlobeConfig,
                days: Sequence[Day], masks: Sequence[Sequence[bool]], objects: Sequence[str], alignment: str,
                activity_question: bool = True, emissions: Sequence[MovementEmission | None] | None = None
                ) -> list[tuple[list[dict[str, float]] | None, list[dict[str, float]]]]:
    """Per day and step t: the filter's P(a_t) for the activity question (labels and movements of
    steps < t; None without ``activity_question`` when a nowcast answers the object questions) and
    for the object questions whose activity step is t. A movement seen at step t+1 is credited to
    a_t (``alignment = "previous"``), so its object question may also use the places seen
    at t; under another alignment the object would be seen at t itself, so both questions get the
    predictive distribution. Every day is filtered at once (``emissions``: each day's evidence)."""
    flt = assembly.activity_filter(activity, emission, config.filter)
    nowcast = alignment == "previous"
    ahead, now = filtered_beliefs(flt, days, masks, objects, nowcast=nowcast,
                                  predictive=activity_question or not nowcast, emissions=emissions)
    out: list[tuple[list[dict[str, float]] | None, list[dict[str, float]]]] = []
    for q in range(len(days)):
        predictive = as_dicts(ahead[q], flt.labels) if ahead is not None else None
        for_objects = as_dicts(now[q], flt.labels) if now is not None else predictive
        assert for_objects is not None
        out.append((predictive, for_objects))
    return out


# -- choosing the movement evidence on training days --------------------------------------------

def filter_candidates(fc: FilterConfig) -> list[dict[str, Any]]:
    """The movement evidence's search space, simplest first (ties go to the first listed). The
    switch table only exists with the change flag and a share credited to a_{s-1}, so it is
    tried only there."""
    return [{**params, "switch": switch}
            for params in grid({"boundary": fc.emission_boundaries, "previous_share": fc.emission_previous_shares,
                                "weight": fc.emission_weights})
            for switch in (fc.emission_switches if params["boundary"] and params["previous_share"] > 0 else (False,))]


def evidence_scores(household: Household, config: GlobeConfig, models: ModelConfig,
                    candidates: Sequence[dict[str, Any]], memo: Memo, alignment: Alignment) -> list[float]:
    """Each candidate evidence's mean object F1 over the folds of training days, under the
    protocol with every activity label hidden (the case the evidence is for). On each fold the
    candidates share the models and the counts, and are filtered together, day by day."""
    k = config.selection.folds
    scores = np.zeros((len(data_folds(household, k)), len(candidates)))
    step = assembly.step_minutes(household, config)
    for f, fold in enumerate(data_folds(household, k)):
        train, days = fold_days(household, fold)
        activity = fitted_activity(household, fold, models, memo, step).model
        objects = fitted_objects(household, fold, models, alignment, memo)
        chooser = assembly.object_chooser(objects, config.gate, None, marginal=models.object_marginal)
        counts = memo.get(FitKey("MovementEmission", fold.data, fold, config.filter.emission_smoothing),
                          assembly.movement_emission(config.filter, **candidates[0]).fit, train, household.objects)
        emissions = [counts.with_params(**c) for c in candidates for _ in days]
        hidden = [[False] * len(d) for d in days]  # every label hidden
        found = day_beliefs(activity, None, config, list(days) * len(candidates), hidden * len(candidates),
                            household.objects, alignment, False, emissions)
        for c in range(len(candidates)):
            true, pred = [], []
            for day, (_, objects_dists) in zip(days, found[c * len(days):(c + 1) * len(days)]):
                ev = evaluate_days(household, [day], FixedScan(activity, {day.name: objects_dists}), chooser,
                                   alignment=alignment)
                true += [r.true for r in ev.objects]
                pred += [r.predicted for r in ev.objects]
            scores[f, c] = f1(true, pred) or 0.0  # a fold with nothing to score counts 0
    return scores.mean(axis=0).tolist()


def tune_evidence(household: Household, config: GlobeConfig, models: ModelConfig, memo: Memo, alignment: Alignment,
                  scores: Sequence[float] | None = None) -> Selection:
    """The movement evidence (move rates by activity change or not, share credited to the earlier
    activity, weight) with the best object F1 on held-out training days with no activity labels
    (:func:`evidence_scores`, or the ``scores`` already computed); ties go to the first listed
    candidate, so the simpler evidence (no change-dependent rates) wins them."""
    started = time.perf_counter()
    candidates = filter_candidates(config.filter)
    scores = evidence_scores(household, config, models, candidates, memo, alignment) if scores is None else scores
    scored = list(zip(candidates, scores))
    return Selection(dict(best_of(scored)), scored, time.perf_counter() - started)


# -- evaluation ---------------------------------------------------------------------------------

@dataclass(slots=True)
class FractionResult:
    """One household at one label fraction: the protocol's records and the lookahead counts."""

    household: str
    fraction: float
    activity: list[ActivityRecord] = field(default_factory=list)
    objects: list[ObjectRecord] = field(default_factory=list)
    hidden_steps: int = 0
    lookahead_f1: tuple[float, ...] = ()
    lookahead_accuracy: tuple[float, ...] = ()
    seconds: float = 0.0


@dataclass(frozen=True, slots=True)
class FilterSetup:
    """What one household's missing-label runs share: the models and the chosen evidence."""

    household: Household
    models: ModelConfig
    activity: ActivityModelBase
    emission: MovementEmission
    chooser: Any
    selection: Selection
    train_s: float
    alignment: Alignment  # chosen with the models (:func:`~globe.evaluation.tuning.chosen_alignment`)


def setup_household(household: Household, config: GlobeConfig, memo: Memo,
                    selection: Selection | None = None) -> FilterSetup:
    """The models chosen on training days, fitted on all of them, and the chosen movement emission
    (``selection``: the evidence already chosen by :func:`tune_evidence`)."""
    models, alignment = routine_choice(household, config, memo)
    selection = tune_evidence(household, config, models, memo, alignment) if selection is None else selection
    started = time.perf_counter()
    sequences = config.sequences.model_copy(update={"alignment": alignment})
    cfg = config.model_copy(update={"models": models, "sequences": sequences})
    fitted = memo.get(FitKey("household", DataKey.of(household), None, models, alignment),
                      lambda: assembly.fit_household(household, cfg))
    emission = assembly.movement_emission(config.filter, **selection.best).fit(household.train, household.objects)
    train_s = fitted.train_s + time.perf_counter() - started
    chooser = assembly.object_chooser(fitted.objects, config.gate, None, marginal=models.object_marginal)
    return FilterSetup(household, models, fitted.activity, emission, chooser, selection, train_s, alignment)


def routine_choice(household: Household, config: GlobeConfig, memo: Memo) -> tuple[ModelConfig, Alignment]:
    """The routine family's models and alignment, chosen on the training days."""
    models, selections = tuned_models(household, config, "routine", memo)
    return models, chosen_alignment(selections, config)


def evaluate_fraction(setup: FilterSetup, config: GlobeConfig, fraction: float, memo: Memo,
                      days: Sequence[Day] | None = None, lookahead: bool = True) -> FractionResult:
    """One label fraction on ``days`` (default: the test days)."""
    h = setup.household
    days = h.test if days is None else days
    started = time.perf_counter()
    res = FractionResult(h.name, fraction)
    masks = {day.name: day_mask(config.filter, h.name, day, fraction) for day in days}
    found = day_beliefs(setup.activity, setup.emission, config, days, [masks[d.name] for d in days], h.objects,
                        setup.alignment)
    align = setup.alignment
    for day, (predictive, for_objects) in zip(days, found):
        assert predictive is not None
        ev = evaluate_days(h, [day], FixedScan(setup.activity, {day.name: predictive}), setup.chooser, alignment=align)
        res.activity.extend(ev.activity)
        if for_objects is not predictive:
            ev = evaluate_days(h, [day], FixedScan(setup.activity, {day.name: for_objects}), setup.chooser,
                               alignment=align)
        res.objects.extend(ev.objects)
        res.hidden_steps += sum(not v for v in masks[day.name])
    if lookahead:
        thresholds = label_share_thresholds(setup, config, memo, fraction)
        la = config.lookahead
        run = filtered_lookahead(forecaster_of(setup, config, memo), setup, config.filter, days, masks,
                                 assembly.lookahead_steps(config, h),
                                 la.first_reference, la.last_reference)
        res.lookahead_f1 = tuple(p.counts(t).f1 for p, t in zip(run.pairs, thresholds))
        res.lookahead_accuracy = tuple(float(a) for a in run.activity_accuracy())
    res.seconds = time.perf_counter() - started
    return res


# -- lookahead through the filter -------------------------------------------------------------

@dataclass(frozen=True, slots=True)
class Reference:
    """A reference step r of a day through the filter: the most probable histories a_0..a_{r-1}
    (at most ``forecast_hypotheses``, given the visible labels and every movement up to r) as
    states of the filter's model (``roots``), and their posterior weights, renormalised over those
    kept. With every label visible there is one, the true history."""

    day: Day
    step: int
    roots: Roots
    weights: np.ndarray


def filtered_references(setup: FilterSetup, fcfg: FilterConfig, days: Sequence[Day], masks: dict[str, list[bool]],
                        horizons: int, first: int, last: int | None, stride: int = 1) -> list[Reference]:
    """:class:`Reference` of every reference step of ``days`` (filtered all at once), in order."""
    flt = assembly.activity_filter(setup.activity, setup.emission, fcfg)
    moved = [moved_objects(day, setup.household.objects) for day in days]
    steps = [set(relocation.reference_steps(day, horizons, first, last, stride)) for day in days]
    found: list[list[Reference]] = [[] for _ in days]
    belief = flt.start(len(days), weekdays=[d.weekday for d in days])
    for t in range(max((len(d) for d in days), default=0)):
        seen = [m[t] if t < len(m) else None for m in moved]
        asked = [q for q, refs in enumerate(steps) if t in refs]
        if asked:  # the movements seen at t tell about a_{t-1} (and a_t)
            peek = flt.update(belief, t, None, seen)
            for q in asked:
                found[q].append(_reference(days[q], t, peek, belief, q, fcfg.forecast_hypotheses, flt))
        labels = [d.activities[t] if t < len(d) and masks[d.name][t] else None for d in days]
        belief = flt.update(belief, t, labels, seen)
    return [ref for refs in found for ref in refs]


def _reference(day: Day, r: int, peek: Belief, before: Belief, q: int, most: int, flt: ActivityFilter) -> Reference:
    """The prefixes a_0..a_{r-1} of day ``q``'s histories after ``peek`` (the update at r): each is
    a history of ``before`` (its entry there), weighted by the posterior of its extensions."""
    beam, prev = peek.beam, before.beam
    mine = np.flatnonzero(beam.query == q)
    parents, inverse = np.unique(beam.parent[mine], return_inverse=True)
    weight = np.bincount(inverse.reshape(-1), weights=beam.weight[mine])
    order = np.lexsort((prev.lex[parents], -tie_key(weight)))[:most]  # most probable first, then by history
    parents, weight = parents[order], weight[order]
    roots = Roots(flt.space, prev.state[parents], prev.act[parents], before.duration[parents])
    return Reference(day, r, roots, weight / weight.sum())


def filtered_lookahead(forecaster: Forecaster, setup: FilterSetup, fcfg: FilterConfig, days: Sequence[Day],
                       masks: dict[str, list[bool]], horizons: int, first: int = 1, last: int | None = None,
                       chunk: int = 512, stride: int = 1) -> relocation.LookaheadRun:
    """The lookahead's pairs when labels are partly hidden: the forecast at reference r mixes
    ``forecaster``'s forecasts from the filter's most probable histories
    (:func:`filtered_references`), weighted by their posterior. With every label visible it is
    the plain forecast. ``forecaster`` must forecast with the filter's activity model (its paths
    start from the filter's states)."""
    run = relocation.LookaheadRun.empty(horizons)
    refs = filtered_references(setup, fcfg, days, masks, horizons, first, last, stride)
    rows: dict = {}
    lo = 0
    while lo < len(refs):
        hi, size = lo, 0
        while hi < len(refs) and (size + len(refs[hi].weights) <= chunk or hi == lo):
            size += len(refs[hi].weights)
            hi += 1
        part = refs[lo:hi]
        roots = Roots(part[0].roots.space, *(np.concatenate([getattr(ref.roots, name) for ref in part])
                                             for name in ("state", "prev", "duration")))
        locations = [ref.day.locations[: ref.step + 1] for ref in part for _ in ref.weights]
        owners = np.repeat(np.arange(len(part)), [len(ref.weights) for ref in part])
        ranks = np.concatenate([np.arange(len(ref.weights)) for ref in part])
        weights = np.concatenate([ref.weights for ref in part])
        fcs = forecaster.forecast_roots(roots, locations, horizons - 1)
        destination = mix(fcs.destination, owners, ranks, weights, len(part))
        activity = mix(fcs.trees.activity_matrix(), owners, ranks, weights, len(part))
        best, prob = first_locations(destination, fcs.targets, horizons)
        top = relocation.top_activities(activity, fcs.trees.names, forecaster.activity, horizons)
        scored = [(ref.day, ref.step) for ref in part]
        relocation.score_arrays(run, scored, best, prob, top, fcs.trees.names, fcs.locations, rows)
        lo = hi
    return run


def lookahead_choice(setup: FilterSetup, config: GlobeConfig, memo: Memo) -> dict[str, Any]:
    """The lookahead's choice on fully labelled training days (movement setting and a threshold per
    horizon); the main job's lookahead stage has made its cross-validation already."""
    return dict(lk.choose_settings(setup.household, config, setup.models, memo).best)


def forecaster_of(setup: FilterSetup, config: GlobeConfig, memo: Memo) -> Forecaster:
    """The lookahead's forecaster (its chosen movement setting) over the filter's own activity
    model, once: its state space is shared across label shares."""
    h, la = setup.household, config.lookahead
    setting = lk.setting_of(lookahead_choice(setup, config, memo))
    key = FitKey("Forecaster:filter", DataKey.of(h), None, (setup.models, la, setting), setup.alignment)
    return memo.get(key, lambda: assembly.forecaster_over(
        setup.activity, lk.movements_on(h, la, None, setting, memo, assembly.step_minutes(h, config)), la))


def label_share_thresholds(setup: FilterSetup, config: GlobeConfig, memo: Memo,
                           fraction: float = 1.0) -> tuple[float, ...]:
    """The lookahead's change threshold per horizon at label share ``fraction``: the lookahead's
    own, chosen on fully labelled training days, or, with ``filter.threshold_per_fraction`` and
    labels missing, the best per horizon on held-out training days with the same share of labels
    visible (a forecast mixed over hidden histories is less sure, so its best threshold may be
    lower); ties go to the first listed."""
    h, la = setup.household, config.lookahead
    chosen = lookahead_choice(setup, config, memo)
    if fraction >= 1.0 or not config.filter.threshold_per_fraction:
        return tuple(float(t) for t in chosen["thresholds"])
    setting = lk.setting_of(chosen)
    key = SearchKey("label-share-thresholds", DataKey.of(h), (la, config.filter, fraction),
                    (setup.models, tuple(sorted(setup.selection.best.items())), setting), config.selection.folds,
                    setup.alignment)

    def thresholds() -> tuple[float, ...]:
        f1s = lk.threshold_f1s(hidden_cv_run(setup, config, fraction, memo, setting), la.thresholds)
        return lk.best_thresholds(f1s, la.thresholds)
    return memo.get(key, thresholds)


def hidden_cv_run(setup: FilterSetup, config: GlobeConfig, fraction: float, memo: Memo,
                  setting: tuple[bool, bool, bool]) -> relocation.LookaheadRun:
    """The lookahead's pairs through the filter on held-out *training* days (contiguous folds,
    every ``cv_stride``-th reference) with ``fraction`` of their labels visible; each fold's
    activity model, movement model (of ``setting``: run end, run memory, next activity) and
    emission (the chosen evidence) are fitted on the other folds."""
    h, la = setup.household, config.lookahead
    horizons = assembly.lookahead_steps(config, h)
    runs = []
    for fold in data_folds(h, config.selection.folds):
        train, held_out = fold_days(h, fold)
        evidence = tuple(sorted(setup.selection.best.items()))
        activity, emission = memo.get(FitKey("filter", fold.data, fold, (setup.models, config.filter, evidence)),
                                      _fold_filter, setup, config, train)
        fold_setup = FilterSetup(h, setup.models, activity, emission, None, setup.selection, 0.0, setup.alignment)
        movements = lk.movements_on(h, la, fold, setting, memo, assembly.step_minutes(h, config))
        forecaster = assembly.forecaster_over(activity, movements, la)
        masks = {d.name: day_mask(config.filter, h.name, d, fraction) for d in held_out}
        runs.append(filtered_lookahead(forecaster, fold_setup, config.filter, held_out, masks, horizons,
                                       la.first_reference, la.last_reference, stride=la.cv_stride))
    return lk.pool(runs, horizons)


def _fold_filter(setup: FilterSetup, config: GlobeConfig,
                 train: Sequence[Day]) -> tuple[ActivityModelBase, MovementEmission]:
    step = assembly.step_minutes(setup.household, config)
    activity = assembly.fitted_activity_model(setup.models, step, train)
    emission = assembly.movement_emission(config.filter, **setup.selection.best)
    return activity, emission.fit(train, setup.household.objects)


# -- the whole run ------------------------------------------------------------------------------

@dataclass(frozen=True, slots=True)
class MissingLabelResults:
    rows: list[dict]
    selection_rows: list[dict]
    results: list[FractionResult]


def run_missing_labels(config: GlobeConfig, households: Sequence[Household], progress: Progress | None = None,
                       memo: Memo | None = None, lookahead: bool = True) -> MissingLabelResults:
    """Every household at every label fraction of ``config.filter.fractions`` (the library entry
    point of ``globe reproduce``; ``memo`` shares the main job's cross-validations)."""
    fractions = check_fractions(config.filter.fractions)
    memo = Memo() if memo is None else memo
    workers = worker_count(config.evaluation.workers)
    chosen = {h.name: routine_choice(h, config, memo) for h in households}
    # 1. The movement evidence of every household, its candidates split over the processes.
    candidates = filter_candidates(config.filter)
    size = -(-len(candidates) // max(1, min(workers, len(candidates))))
    parts = [(h, candidates[i:i + size]) for h in households for i in range(0, len(candidates), size)]
    if progress:
        progress("missing labels: choosing the filter's movement evidence (cross-validation, in parallel)")
    def scores_of(i: int) -> list[float]:
        household, part = parts[i]
        models, alignment = chosen[household.name]
        return evidence_scores(household, config, models, part, memo, alignment)

    scored = run_forked(scores_of, len(parts), workers)
    setups: dict[str, FilterSetup] = {}
    selection_rows: list[dict] = []
    for h in households:
        scores = [s for (hh, _), part in zip(parts, scored) if hh is h for s in part]
        models, alignment = chosen[h.name]
        selection = tune_evidence(h, config, models, memo, alignment, scores)
        setup = setups[h.name] = setup_household(h, config, memo, selection)
        for params, score in selection.scores:
            selection_rows.append({"household": h.name, "params": params, "cv_object_f1_no_labels": round(score, 4),
                                   "chosen": params == selection.best})
        if lookahead:  # shared by every label share: made once, before the processes fork
            label_share_thresholds(setup, config, memo)
            forecaster_of(setup, config, memo)
    # 2. Every (household, label share) on its own.
    tasks = [(setups[h.name], fraction) for h in households for fraction in fractions]
    if progress:
        progress(f"missing labels: {len(tasks)} households x label shares (in parallel)")
    weights = [2.0 - fraction for _, fraction in tasks]  # fewer labels, more hypotheses
    results = run_forked(lambda i: evaluate_fraction(tasks[i][0], config, tasks[i][1], memo, lookahead=lookahead),
                         len(tasks), workers, weights)
    step = assembly.common_step(households, config)
    rows = missing_label_rows(results, assembly.steps(config.lookahead.horizon_minutes, step), step)
    return MissingLabelResults(rows, selection_rows, results)


def _round(x: float | None) -> float | None:
    return None if x is None or x != x else round(float(x), 4)


def missing_label_rows(results: Sequence[FractionResult], horizons: int = 6, step_minutes: int = 10) -> list[dict]:
    """``missing_labels.csv``: one row per household and label share, then the mean of households."""
    rows: list[dict] = []
    for r in results:
        acts, objs = r.activity, r.objects
        row: dict[str, Any] = {
            "method": METHOD, "household": r.household, "labels_pct": round(100 * r.fraction),
            "activity_f1": records_f1(acts),
            "activity_log_loss": log_loss([a.p_true for a in acts]),
            "object_f1": records_f1(objs),
            "hidden_steps": r.hidden_steps, "seconds": r.seconds,
        }
        for s in range(horizons):
            row[f"lookahead_f1_{step_minutes * (s + 1)}min"] = r.lookahead_f1[s] if s < len(r.lookahead_f1) else None
        row["lookahead_f1_mean"] = float(np.mean(r.lookahead_f1)) if r.lookahead_f1 else None
        rows.append({k: _round(v) if isinstance(v, float) else v for k, v in row.items()})
    for pct in dict.fromkeys(row["labels_pct"] for row in rows):
        mine = [row for row in rows if row["labels_pct"] == pct and row["household"] != "mean"]
        mean: dict[str, Any] = {"method": METHOD, "household": "mean", "labels_pct": pct}
        for key in mine[0]:
            if key in mean:
                continue
            vals = [row[key] for row in mine if isinstance(row[key], (int, float)) and not isinstance(row[key], bool)]
            mean[key] = _round(float(np.mean(vals))) if len(vals) == len(mine) else None
        rows.append(mean)
    return rows


def write_missing_label_results(out_dir: Path, rows: Sequence[dict], selection_rows: Sequence[dict] = ()) -> list[Path]:
    """``missing_labels.csv``, ``missing_labels.png`` (F1 against the share of visible labels) and,
    when given, ``missing_labels_selection.csv``; returns the paths written."""
    from globe.evaluation.plots_missing import missing_labels_figure

    out_dir.mkdir(parents=True, exist_ok=True)
    written = [out_dir / "missing_labels.csv", out_dir / "missing_labels.png"]
    report.write_csv(written[0], list(rows))
    fig = missing_labels_figure(rows)
    fig.savefig(written[1], dpi=130)
    if selection_rows:
        written.append(out_dir / "missing_labels_selection.csv")
        report.write_csv(written[-1], list(selection_rows))
    return written
