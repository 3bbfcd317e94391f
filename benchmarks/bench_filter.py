"""The activity filter, Python against compiled, on the missing-label stage's main cost.

Times :func:`globe.evaluation.missing_labels.score_filter_candidates` per household (each
movement-evidence candidate, or the first ``--candidates``, scored on the held-out training days
of every fold with every label hidden) twice: with the Python filter (the reference) and with the
compiled step (``globe.models._filter_core``). Prints the seconds of the whole call and of the
filter alone (``filtered_beliefs``), the speed-ups, and whether the two selections are the same
(every candidate's score, compared with ==); with ``--beliefs``, also whether every belief the
search computed (each step's distribution, keys in order, floats to the bit) is the same (the
digests cost time outside the filter). Usage:
python benchmarks/bench_filter.py [--data DIR] [--candidates N] [--households A,B] [--beliefs]
"""

from __future__ import annotations

import hashlib
import time
from typing import Any, Callable

from common import setup
from globe.evaluation import missing_labels
from globe.evaluation.tuning import Selection, tuned_models
from globe.models import activity_filter


def digest(beliefs: Any) -> str:
    """The bits of a filtered_beliefs result: every distribution's keys, in order, and floats."""
    h = hashlib.sha256()
    for part in beliefs:
        for dist in part or ():
            h.update(repr([(a, p.hex()) for a, p in dist.items()]).encode())
        h.update(b"|")
    return h.hexdigest()


def timed(fn: Callable[..., Any], spent: list[float], digests: list[str] | None) -> Callable[..., Any]:
    """``fn``, adding the seconds of each call to ``spent[0]`` (and its result's digest to ``digests``)."""
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        started = time.perf_counter()
        out = fn(*args, **kwargs)
        spent[0] += time.perf_counter() - started
        if digests is not None:
            digests.append(digest(out))
        return out
    return wrapper


def run(household: Any, cfg: Any, models: Any, candidates: list[dict], compiled: bool,
        digests: list[str] | None) -> tuple[Selection, float, float]:
    """(selection, seconds of the whole search, seconds inside the filter) with one kind of filter."""
    activity_filter.COMPILED = compiled
    spent = [0.0]
    plain = missing_labels.filtered_beliefs
    missing_labels.filtered_beliefs = timed(plain, spent, digests)  # type: ignore[assignment]
    try:
        started = time.perf_counter()
        selection = missing_labels.score_filter_candidates(household, cfg, models, candidates)
        return selection, time.perf_counter() - started, spent[0]
    finally:
        missing_labels.filtered_beliefs = plain  # type: ignore[assignment]
        activity_filter.COMPILED = True


def main() -> None:
    cfg, homes, args = setup(__doc__, {
        "--candidates": {"type": int, "default": None, "help": "score only the first N candidates"},
        "--households": {"default": None, "help": "comma-separated household names (default: all)"},
        "--beliefs": {"action": "store_true", "help": "also compare every belief computed, to the bit"},
    })
    if args.households:
        homes = [h for h in homes if h.name in args.households.split(",")]
    candidates = missing_labels.filter_candidates(cfg.filter)[: args.candidates]
    if activity_filter._native is None:
        print("globe.models._filter_core is not compiled here: only the Python filter runs")
    print(f"{len(candidates)} candidates; seconds (whole search / inside the filter)\n")
    print(f"{'home':5s} {'python':>14s} {'compiled':>14s} {'speed-up':>14s}  same selection"
          + ("  same beliefs (days)" if args.beliefs else ""))
    cache: dict = {}
    totals = [0.0, 0.0, 0.0, 0.0]
    for h in homes:
        models, _ = tuned_models(h, cfg, "routine", cache)
        digests: tuple[list[str], list[str]] | None = ([], []) if args.beliefs else None
        python = run(h, cfg, models, candidates, False, digests and digests[0])
        if activity_filter._native is None:
            print(f"{h.name:5s} {python[1]:6.1f} / {python[2]:5.1f}")
            continue
        compiled = run(h, cfg, models, candidates, True, digests and digests[1])
        same = python[0].scores == compiled[0].scores and python[0].best == compiled[0].best
        beliefs = "" if digests is None else f"  {'yes' if digests[0] == digests[1] else 'NO'} ({len(digests[1])})"
        for i, x in enumerate((python[1], python[2], compiled[1], compiled[2])):
            totals[i] += x
        print(f"{h.name:5s} {python[1]:6.1f} / {python[2]:5.1f} {compiled[1]:6.1f} / {compiled[2]:5.1f} "
              f"{python[1] / compiled[1]:5.1f}x / {python[2] / compiled[2]:4.1f}x  "
              + (f"{'yes' if same else 'NO':14s}{beliefs}" if beliefs else ("yes" if same else "NO")))
    if activity_filter._native is not None and len(homes) > 1:
        print(f"{'all':5s} {totals[0]:6.1f} / {totals[1]:5.1f} {totals[2]:6.1f} / {totals[3]:5.1f} "
              f"{totals[0] / totals[2]:5.1f}x / {totals[1] / totals[3]:4.1f}x")


if __name__ == "__main__":
    main()
