"""GLOBE inference with the embedded LLM per household, with the paper's prompt and with the
personalised one: cold (no cache) and from the cache.

Targets: <= 20 s per household cold on 2 cores (the paper: 192 s with a hosted model); a re-run
from the answer cache within 2x of the n-gram-only inference time.
Usage: python benchmarks/bench_llm.py [--data DIR]
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from common import setup
from globe.assembly import fit_household, object_chooser
from globe.evaluation.protocol import evaluate_days
from globe.evaluation.published import TABLE2
from globe.reasoning.backends.embedded import EmbeddedBackend
from globe.reasoning.cache import AnswerCache
from globe.reasoning.choice import ObjectChooser

PAPER_S, TARGET_S = TABLE2["globe"][1], 20.0


def main() -> None:
    cfg, homes, _ = setup(__doc__)
    with tempfile.TemporaryDirectory() as tmp:
        cache_path = Path(tmp) / "answers.sqlite3"
        warm = EmbeddedBackend(n_threads=cfg.llm.n_threads)
        t = time.perf_counter()
        warm.load()
        print(f"model load: {time.perf_counter() - t:.2f} s (once per process and shared by every backend; not counted below)")
        print(f"{'prompt':9s} {'household':9s} {'ngram s':>8s} {'globe cold s':>12s} {'calls':>6s} {'s/call':>7s} "
              f"{'globe cached s':>14s} {'cached/ngram':>12s} {'paper/cold':>10s}")
        for prompt, examples in (("paper", 0), ("personal", cfg.evaluation.personal_examples)):
            for h in homes:
                fitted = fit_household(h, cfg)
                t = time.perf_counter()
                evaluate_days(h, h.test, fitted.activity, ObjectChooser(fitted.objects))
                ngram_s = time.perf_counter() - t
                timings = []
                for _ in range(2):  # cold, then from the cache
                    backend = EmbeddedBackend(n_threads=cfg.llm.n_threads, cache=AnswerCache(cache_path))
                    gate = object_chooser(fitted.objects, cfg.gate.model_copy(update={"examples": examples}), backend,
                                          marginal=False)
                    t = time.perf_counter()
                    ev = evaluate_days(h, h.test, fitted.activity, gate)
                    timings.append(time.perf_counter() - t)
                calls = sum(r.asked for r in ev.objects)
                cold, cached = timings
                ok = "ok" if cold <= TARGET_S and cached <= 2 * ngram_s else "MISSED"
                print(f"{prompt:9s} {h.name:9s} {ngram_s:8.3f} {cold:12.2f} {calls:6d} {cold / max(calls, 1):7.3f} "
                      f"{cached:14.3f} {cached / ngram_s:11.1f}x {PAPER_S / cold:9.0f}x  {ok}")


if __name__ == "__main__":
    main()
