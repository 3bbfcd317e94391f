"""Missing activity labels against the issue's target, per household and averaged.

Runs :func:`globe.evaluation.missing_labels.run_missing_labels` (the routine model chosen by CV,
the activity filter's movement evidence chosen by CV on training days with no labels) and prints,
per share p of visible labels, one-step activity F1 and log loss, object F1 and (when the
lookahead module is there) mean lookahead F1, the filter's time per test day, the training time
of the filter's movement model, and whether p = 0 is within 0.05 of p = 100 (object F1 and
lookahead F1). Usage: python benchmarks/bench_missing_labels.py [--data DIR] [--no-lookahead]
"""

from __future__ import annotations

import time

from common import setup
from globe import assembly
from globe.evaluation.missing_labels import run_missing_labels


def main() -> None:
    cfg, homes, args = setup(__doc__, {"--no-lookahead": {"action": "store_true", "help": "skip the lookahead F1"}})
    for h in homes:  # training the filter's evidence is counting: time it alone
        started = time.perf_counter()
        assembly.movement_emission(cfg.filter, previous_share=0.5, weight=1.0).fit(h.train, h.objects)
        print(f"household {h.name}: movement emission trained in {time.perf_counter() - started:.4f} s")
    started = time.perf_counter()
    res = run_missing_labels(cfg, homes, lookahead=not args.no_lookahead)
    total = time.perf_counter() - started
    print(f"\n{'home':5s} {'labels':>6s} {'act F1':>7s} {'act LL':>7s} {'obj F1':>7s} {'look F1':>8s} {'s/day':>6s}")
    for r in res.rows:
        look = "" if r["lookahead_f1_mean"] is None else f"{r['lookahead_f1_mean']:.3f}"
        days = len([h for h in homes if h.name == r["household"]][0].test) if r["household"] != "mean" else None
        per_day = f"{r['seconds'] / days:.2f}" if days else ""
        print(f"{r['household']:5s} {r['labels_pct']:5d}% {r['activity_f1']:7.3f} {r['activity_log_loss']:7.3f} "
              f"{r['object_f1']:7.3f} {look:>8s} {per_day:>6s}")
    mean = {r["labels_pct"]: r for r in res.rows if r["household"] == "mean"}
    if 0 in mean and 100 in mean:
        for key, name in (("object_f1", "object F1"), ("lookahead_f1_mean", "lookahead F1")):
            lo, hi = mean[0][key], mean[100][key]
            if lo is None or hi is None:
                continue
            verdict = "ok" if hi - lo <= 0.05 else "MISSED"
            print(f"{name}: p=0 {lo:.3f} vs p=100 {hi:.3f} (gap {hi - lo:+.3f}; target gap <= 0.05): {verdict}")
    chosen = [f"{r['household']} {r['params']}" for r in res.selection_rows if r["chosen"]]
    print("chosen movement evidence: " + "; ".join(chosen))
    print(f"whole run (CV included): {total:.1f} s")


if __name__ == "__main__":
    main()
