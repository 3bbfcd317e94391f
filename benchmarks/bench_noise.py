"""HOMER-Noise generation time: all homes x noise types at level 1.0, cold and from the cache.

Targets: <= 10 minutes cold with the embedded LLM on 2 cores; <= 10 s from the cache.
Usage: python benchmarks/bench_noise.py [--data DIR]
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from common import setup
from globe.noise.generate import propose
from globe.noise.proposals import LLMScorer
from globe.reasoning.backends.embedded import EmbeddedBackend
from globe.reasoning.cache import AnswerCache


def main() -> None:
    cfg, homes, _ = setup(__doc__)
    n = cfg.noise
    with tempfile.TemporaryDirectory() as tmp:
        cache = Path(tmp) / "scores.sqlite3"
        shared = EmbeddedBackend(n_threads=cfg.llm.n_threads)
        shared.load()
        results = []
        for label in ("cold", "cached"):
            backend = EmbeddedBackend(n_threads=cfg.llm.n_threads, cache=AnswerCache(cache))
            scorer = LLMScorer(backend)
            t = time.perf_counter()
            count = sum(len(propose(h, nt, scorer, seed=n.seed, rate=n.rate, temperature=n.temperature).injections)
                        for nt in n.types for h in homes)
            results.append((label, time.perf_counter() - t, count))
        for (label, seconds, count), target in zip(results, (600.0, 10.0)):
            ok = "ok" if seconds <= target else "MISSED"
            print(f"{label:7s} {seconds:8.2f} s for {count} movements (3 homes x {len(n.types)} types, level 1.0); "
                  f"target <= {target:g} s: {ok}")
        print(f"cache speed-up: {results[0][1] / results[1][1]:.0f}x")


if __name__ == "__main__":
    main()
