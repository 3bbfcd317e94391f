"""GLOBE inference with the embedded LLM per household, with the paper's prompt and with the
personalised one: cold (no cache) and from the cache.

Targets: <= 20 s per household cold on 2 cores (the paper: 192 s with a hosted model); a re-run
from the answer cache within 2x of the n-gram-only inference time.

First, the scorer alone on real questions (every object of the household as a candidate, as the
LLM-only baseline asks): every token node decoded on its own (the reference) against one forest
per question and against all the household's questions as forests at once, with the time per
question, the rows decoded and the largest score difference (must be 0: the same arithmetic).
Usage: python benchmarks/bench_llm.py [--data DIR] [--questions N] [--scorer-only]
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from common import setup
from globe.assembly import fit_household, object_chooser
from globe.data.records import Household
from globe.evaluation.protocol import evaluate_days
from globe.evaluation.published import TABLE2
from globe.reasoning.backends.embedded import EmbeddedBackend, reference_logprobs
from globe.reasoning.cache import AnswerCache
from globe.reasoning.choice import ObjectChooser
from globe.reasoning.context import ChoiceContext
from globe.reasoning.prompts import NULL_PREFIX, cloze_continuation, cloze_prefix, diary_prefix
from globe.sequences.runs import training_sequences

PAPER_S, TARGET_S = TABLE2["globe"][1], 20.0


def questions(h: Household, alignment, n: int, examples: int) -> list[tuple[str, list[str]]]:
    """Up to ``n`` real prompts per kind (cloze and diary) from training runs, each with every object."""
    runs: dict[str, list[tuple[str, ...]]] = {}
    for activity, objs in training_sequences(h, h.train, alignment).runs:
        if objs:
            runs.setdefault(activity, []).append(objs)
    conts = [cloze_continuation(o) for o in h.objects]
    out = []
    for activity, seen in sorted(runs.items())[:n]:
        last = seen[-1]
        out.append((cloze_prefix(ChoiceContext(activity, last[:1])), conts))
        out.append((diary_prefix(ChoiceContext(activity, last[:1], tuple(seen[-1 - examples:-1]))), conts))
    out.append((NULL_PREFIX, conts))
    return out


def compare_scorers(backend: EmbeddedBackend, homes: list[Household], cfg, n: int) -> None:
    rt = backend._shared()
    print(f"llama.cpp rows batch-invariant (forests used): {rt.batched}")
    print(f"{'household':9s} {'prompts':>7s} {'rows alone':>10s} {'rows forest':>11s} {'rows all':>8s} "
          f"{'alone s/q':>9s} {'forest s/q':>10s} {'all s/q':>7s} {'speed-up':>8s} {'max |diff|':>10s}")
    for h in homes:
        qs = questions(h, cfg.sequences.alignment, n, cfg.evaluation.personal_examples)
        k = len(qs)
        rows = rt.rows
        t = time.perf_counter()
        ref = [reference_logprobs(backend, prefix, conts) for prefix, conts in qs]
        t_ref, rows_ref = time.perf_counter() - t, rt.rows - rows
        rows = rt.rows
        t = time.perf_counter()
        one = [backend.continuation_logprobs(prefix, conts) for prefix, conts in qs]
        t_one, rows_one = time.perf_counter() - t, rt.rows - rows
        rows = rt.rows
        t = time.perf_counter()
        together = backend.continuation_logprobs_many(qs)
        t_all, rows_all = time.perf_counter() - t, rt.rows - rows
        diff = max(max(abs(a - b), abs(a - c)) for r, o, g in zip(ref, one, together) for a, b, c in zip(r, o, g))
        print(f"{h.name:9s} {k:7d} {rows_ref:10d} {rows_one:11d} {rows_all:8d} {t_ref / k:9.3f} {t_one / k:10.3f} "
              f"{t_all / k:7.3f} {t_ref / t_all:7.2f}x {diff:10.1e}")


def main() -> None:
    cfg, homes, args = setup(__doc__, {"--questions": {"type": int, "default": 6, "help": "activities per household"},
                                       "--scorer-only": {"action": "store_true", "help": "only the scorer comparison"}})
    with tempfile.TemporaryDirectory() as tmp:
        cache_path = Path(tmp) / "answers.sqlite3"
        warm = EmbeddedBackend(n_threads=cfg.llm.n_threads)
        t = time.perf_counter()
        warm.load()
        print(f"model load: {time.perf_counter() - t:.2f} s "
              "(once per process and shared by every backend; not counted below)")
        compare_scorers(warm, homes, cfg, args.questions)
        if args.scorer_only:
            return
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
