"""The models beyond the paper against the issue's targets, per household and averaged.

Prints weighted F1 (activity, activity at change steps, object with the predicted activity),
training time without CV, and the CV time, for the paper's n-gram, persistence and the
routine model. Targets: activity >= 0.83, object >= 0.70, training < 0.1 s per household.
Usage: python benchmarks/bench_models.py [--data DIR]
"""

from __future__ import annotations

import statistics

from common import setup
from globe.evaluation.methods import METHODS
from globe.evaluation.metrics import records_f1
from globe.evaluation.protocol import evaluate_days


def main() -> None:
    cfg, homes, _ = setup(__doc__)
    print(f"{'method':15s} {'home':4s} {'act F1':>7s} {'change F1':>9s} {'obj F1':>7s} {'train s':>8s} {'CV s':>6s}")
    for method in ("persistence", "ngram", "routine"):
        rows = []
        cache: dict = {}
        for h in homes:
            prepared = METHODS[method].prepare(h, cfg, None, cache)
            cv = sum(s.seconds for s in prepared.selection.values())
            ev = evaluate_days(h, h.test, prepared.activity, prepared.chooser)
            ch = [r for r in ev.activity if r.is_change]
            row = (records_f1(ev.activity), records_f1(ch), records_f1(ev.objects), prepared.train_s, cv)
            rows.append(row)
            print(f"{method:15s} {h.name:4s} {row[0]:7.3f} {row[1]:9.3f} {row[2]:7.3f} {row[3]:8.4f} {row[4]:6.2f}")
        mean = [statistics.fmean(r[i] for r in rows) for i in range(5)]
        verdict = ""
        if method == "routine":
            ok = mean[0] >= 0.83 and mean[2] >= 0.70 and max(r[3] for r in rows) < 0.1
            verdict = "  targets (act >= 0.83, obj >= 0.70, train < 0.1 s): " + ("ok" if ok else "MISSED")
        print(f"{method:15s} {'mean':4s} {mean[0]:7.3f} {mean[1]:9.3f} {mean[2]:7.3f} {mean[3]:8.4f} "
              f"{mean[4]:6.2f}{verdict}")
    print("published: GLOBE 0.80 / 0.65, SLaTe-PRO 0.78 / 0.69 (activity / object F1)")


if __name__ == "__main__":
    main()
