"""Anticipation against issue 12's targets: lookahead and the robot's fetch policy.

Prints, per household and averaged over A, B, C: relocation F1 (SLaTe-PRO's metric) at each
horizon 10..60 min for every lookahead method, the forecaster's training time (best of 5), and
the fetch policy's precision, recall and median lead at the configured costs and along the
cost-ratio curve. Targets: lookahead F1 > 0.60 at every horizon (mean of A, B, C; SLaTe-PRO
published 0.57 / 0.60), training < 0.1 s per household, fetch precision >= 0.80 at recall
>= 0.40 with a median lead >= 10 min. With --out DIR it also writes the results folder.
Usage: python benchmarks/bench_anticipation.py [--data DIR] [--out DIR]
"""

from __future__ import annotations

import statistics
import time
from pathlib import Path

from common import setup
from globe import assembly
from globe.evaluation.anticipation import method_models, run_anticipation, write_anticipation_results
from globe.evaluation.fetch import pooled
from globe.evaluation.lookahead import lookahead_rows
from globe.evaluation.published import DataScope
from globe.evaluation.selection import Memo


def main() -> None:
    cfg, homes, args = setup(__doc__, {"--out": {"default": None, "help": "also write the results folder here"}})
    memo = Memo()
    started = time.perf_counter()
    result = run_anticipation(cfg, homes, progress=lambda msg: print(f"[{time.perf_counter() - started:6.1f} s] {msg}",
                                                                     flush=True), memo=memo)
    print(f"total {time.perf_counter() - started:.1f} s")
    rows = lookahead_rows(result.lookahead, cfg.service.step_minutes)
    horizons = sorted({r["horizon_min"] for r in rows})
    print("\nLookahead: relocation F1 (per-horizon thresholds and the run-end setting chosen by CV on training days)")
    print(f"{'method':12s} {'home':5s} " + " ".join(f"{h:>4d}'" for h in horizons) + "   activity accuracy 10'..60'")
    for method in cfg.lookahead.methods:
        for hh in [h.name for h in homes] + ["mean"]:
            mine = [r for r in rows if r["method"] == method and r["household"] == hh]
            line = " ".join(f"{r['f1']:5.3f}" for r in mine)
            acc = " ".join(f"{r['activity_accuracy']:.2f}" for r in mine)
            verdict = ""
            if hh == "mean":
                low = min(r["f1"] for r in mine)
                verdict = f"  min {low:.3f} vs 0.60: {'ok' if low > 0.60 else 'MISSED'} (ratio {low / 0.60:.2f})"
            print(f"{method:12s} {hh:5s} {line}   {acc}{verdict}")
    print("\nTraining time of the forecaster (activity + movement model), best of 5")
    for h in homes:
        models = method_models(cfg.policy.method, h, cfg, memo)
        best = min(assembly.forecaster(h, cfg, models=models).train_s for _ in range(5))
        print(f"  household {h.name}: {best:.4f} s (target < 0.1 s: {'ok' if best < 0.1 else 'MISSED'}, ratio {best / 0.1:.2f})")
    ratio = cfg.policy.cost_useless / cfg.policy.cost_missed
    print(f"\nFetch policy (costs useless {cfg.policy.cost_useless}, missed {cfg.policy.cost_missed}; "
          f"lead {cfg.policy.min_lead_minutes}-{cfg.policy.lead_window_minutes} min)")
    for ev in result.fetch:
        rep = ev.report
        print(f"  household {ev.household}: fetches {rep.fetches:4d}  precision {rep.precision:.3f}  recall {rep.recall:.3f}  "
              f"median lead {rep.median_lead_min} min")
    allrep = pooled([ev.report for ev in result.fetch])
    ok = allrep.precision >= 0.80 and allrep.recall >= 0.40 and (allrep.median_lead_min or 0) >= 10
    print(f"  all: precision {allrep.precision:.3f} recall {allrep.recall:.3f} median lead {allrep.median_lead_min} min  "
          f"target (P >= 0.80 at R >= 0.40, lead >= 10 min): {'ok' if ok else 'MISSED'}")
    print("  curve over the cost ratio useless/missed (all households pooled):")
    for i, (r, thr, _) in enumerate(result.fetch[0].curve):
        rep = pooled([ev.curve[i][2] for ev in result.fetch])
        mark = " <- configured" if abs(r - ratio) < 1e-12 else ""
        print(f"    ratio {r:5.2f} (p > {thr:.2f}): precision {rep.precision:.3f} recall {rep.recall:.3f} "
              f"median lead {rep.median_lead_min} min, leads mean {statistics.fmean(rep.lead_minutes or [0]):.1f}{mark}")
    if args.out:
        for path in write_anticipation_results(Path(args.out), result, DataScope.of(homes)):
            print(f"wrote {path}")


if __name__ == "__main__":
    main()
