"""Training and inference time of the n-gram models per household (no LLM).

Median of several runs on the full HOMER+ split, printed beside the paper's figures
(training 8.33 s, inference 0.86 s) and the targets (<= 0.05 s each per household).
Usage: python benchmarks/bench_core.py [--repeats 7] [--data DIR]
"""

from __future__ import annotations

import statistics
import time

from common import setup
from globe.assembly import fit_household
from globe.evaluation.protocol import evaluate_days
from globe.evaluation.published import TABLE2
from globe.reasoning.choice import ObjectChooser

(PAPER_TRAIN_S, PAPER_INFER_S), TARGET_S = TABLE2["ngram"], 0.05


def main() -> None:
    cfg, homes, args = setup(__doc__, {"--repeats": {"type": int, "default": 7, "help": "runs per figure (median)"}})
    print(f"{'household':9s} {'preprocess s':>12s} {'train s':>9s} {'inference s':>12s} {'paper train/ours':>17s} "
          f"{'paper infer/ours':>17s}  target <= {TARGET_S} s")
    for h in homes:
        pre, train, infer = [], [], []
        for _ in range(args.repeats):
            fitted = fit_household(h, cfg)
            pre.append(fitted.preprocess_s)
            train.append(fitted.train_s)
            t = time.perf_counter()
            evaluate_days(h, h.test, fitted.activity, ObjectChooser(fitted.objects), alignment=cfg.sequences.alignment)
            infer.append(time.perf_counter() - t)
        p, tr, inf = (statistics.median(x) for x in (pre, train, infer))
        ok = "ok" if tr <= TARGET_S and inf <= TARGET_S else "MISSED"
        print(f"{h.name:9s} {p:12.4f} {tr:9.4f} {inf:12.4f} {PAPER_TRAIN_S / tr:16.0f}x "
              f"{PAPER_INFER_S / inf:16.0f}x  {ok}")


if __name__ == "__main__":
    main()
