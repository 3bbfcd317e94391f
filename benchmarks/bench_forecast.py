"""The forecaster, numpy and Python against compiled, on the anticipation stages' main costs.

Per household, on one core, twice: with the numpy and Python forecaster (the reference) and with
the compiled one (``globe.models._forecast_core``: the hazards, destinations and first places, and
the routine model's forward pass), times
- the lookahead of every method (:func:`globe.evaluation.lookahead.evaluate_lookahead`: the
  movement settings chosen by 5-fold cross-validation on training days, then the test days; the
  methods share the folds' movement models, as in the main job), and
- the missing-label lookahead (:func:`globe.evaluation.missing_labels.filtered_lookahead` on the
  test days at every label share, over the lookahead's chosen setting and the filter with the
  configured movement evidence; the filter's own time is printed apart, it is the same code).
Prints the seconds, the speed-ups and whether the two give the same results, compared with ==
(every pair's probability, hit and change, the chosen settings and thresholds, every candidate's
cross-validated F1). Usage: python benchmarks/bench_forecast.py [--data DIR] [--households A,B]
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from common import setup
from globe import assembly
from globe.evaluation import lookahead as lk
from globe.evaluation import missing_labels as ml
from globe.evaluation.anticipation import method_models
from globe.evaluation.tuning import Selection
from globe.models import forecast
from globe.models.forecast import Forecaster


def same_run(a: lk.LookaheadRun, b: lk.LookaheadRun) -> bool:
    """Whether two runs hold the same pairs, to the bit, and the same activity counts."""
    for pa, pb in zip(a.pairs, b.pairs):
        for name in ("probability", "hit", "true"):
            x, y = getattr(pa, name), getattr(pb, name)
            if len(x) != len(y) or not all(np.array_equal(u, v) for u, v in zip(x, y)):
                return False
    return np.array_equal(a.activity_correct, b.activity_correct) and np.array_equal(a.activity_total, b.activity_total)


def lookahead(h: Any, cfg: Any, cache: dict, compiled: bool) -> tuple[float, list[lk.LookaheadResult]]:
    """Seconds of every method's lookahead on ``h`` (one forecaster kind) and the results. As in
    the main job, the methods share a cache (the folds' movement models), a fresh one per run."""
    forecast.COMPILED = compiled
    fresh: dict = {}
    try:
        started = time.perf_counter()
        results = [lk.evaluate_lookahead(h, cfg, method_models(m, h, cfg, cache), m, fresh) for m in cfg.lookahead.methods]
        return time.perf_counter() - started, results
    finally:
        forecast.COMPILED = True


def same_lookahead(a: list[lk.LookaheadResult], b: list[lk.LookaheadResult]) -> bool:
    return all(x.counts == y.counts and x.thresholds == y.thresholds and x.activity_accuracy == y.activity_accuracy
               and x.selection.best == y.selection.best and x.selection.scores == y.selection.scores for x, y in zip(a, b))


def missing_label_lookahead(h: Any, cfg: Any, cache: dict, setting: lk.Setting, compiled: bool) -> tuple[float, float, list]:
    """(seconds of the filtered lookahead at every label share, seconds of its filter alone, the
    runs), over freshly fitted models (no memo carried over from the other kind)."""
    evidence = {"boundary": cfg.filter.emission_boundary, "previous_share": cfg.filter.emission_previous_share,
                "weight": cfg.filter.emission_weight, "switch": cfg.filter.emission_switch}
    fs = ml.setup_household(h, cfg, cache, Selection(evidence))
    la = cfg.lookahead
    movements = assembly.movement_model(la, *setting).fit(h.train, h.objects)
    forecaster = Forecaster(fs.activity, movements, min_path_probability=la.min_path_probability, max_paths=la.max_paths)
    spent = [0.0]
    plain = ml.filtered_references

    def timed(*args: Any, **kwargs: Any) -> Any:
        started = time.perf_counter()
        out = plain(*args, **kwargs)
        spent[0] += time.perf_counter() - started
        return out

    forecast.COMPILED = compiled
    ml.filtered_references = timed  # type: ignore[assignment]
    try:
        runs = []
        started = time.perf_counter()
        for fraction in cfg.filter.fractions:
            masks = {d.name: ml.day_mask(cfg.filter, h.name, d, fraction) for d in h.test}
            runs.append(ml.filtered_lookahead(forecaster, fs, cfg.filter, h.test, masks, la.horizons, la.first_reference,
                                              la.last_reference))
        return time.perf_counter() - started, spent[0], runs
    finally:
        ml.filtered_references = plain  # type: ignore[assignment]
        forecast.COMPILED = True


def main() -> None:
    cfg, homes, args = setup(__doc__, {"--households": {"default": None, "help": "comma-separated household names"}})
    if args.households:
        homes = [h for h in homes if h.name in args.households.split(",")]
    if forecast._native is None:
        print("globe.models._forecast_core is not compiled here: there is nothing to compare")
        return
    cache: dict = {}
    print(f"methods {', '.join(cfg.lookahead.methods)}; label shares {', '.join(map(str, cfg.filter.fractions))}; seconds\n")
    print(f"{'home':5s} {'lookahead: python':>18s} {'compiled':>9s} {'speed-up':>9s} {'same':>5s}   "
          f"{'missing labels: python':>22s} {'compiled':>9s} {'speed-up':>9s} {'same':>5s}  (filter alone)")
    totals = np.zeros(4)
    for h in homes:
        for m in cfg.lookahead.methods:  # the activity models' own cross-validation, outside the timings
            method_models(m, h, cfg, cache)
        fast_s, fast = lookahead(h, cfg, cache, True)
        ref_s, ref = lookahead(h, cfg, cache, False)
        routine = next((r for r in fast if r.method == "routine"), fast[-1])
        setting = (routine.run_end, routine.run_memory, routine.run_next)
        ml_fast_s, filter_fast_s, ml_fast = missing_label_lookahead(h, cfg, cache, setting, True)
        ml_ref_s, filter_ref_s, ml_ref = missing_label_lookahead(h, cfg, cache, setting, False)
        same_ml = all(same_run(a, b) for a, b in zip(ml_ref, ml_fast))
        totals += (ref_s, fast_s, ml_ref_s, ml_fast_s)
        print(f"{h.name:5s} {ref_s:18.2f} {fast_s:9.2f} {ref_s / fast_s:8.2f}x {'yes' if same_lookahead(ref, fast) else 'NO':>5s}   "
              f"{ml_ref_s:22.2f} {ml_fast_s:9.2f} {ml_ref_s / ml_fast_s:8.2f}x {'yes' if same_ml else 'NO':>5s}  "
              f"({filter_ref_s:.2f} / {filter_fast_s:.2f})")
    if len(homes) > 1:
        print(f"{'all':5s} {totals[0]:18.2f} {totals[1]:9.2f} {totals[0] / totals[1]:8.2f}x {'':5s}   "
              f"{totals[2]:22.2f} {totals[3]:9.2f} {totals[2] / totals[3]:8.2f}x")


if __name__ == "__main__":
    main()
