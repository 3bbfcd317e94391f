"""Independent CPU-bound work on several processes.

The main job's model selection (k-fold cross-validation per household and model family) is pure
counting and scoring, independent across households and datasets, and most of the job's CPU
time once LLM answers are cached. It runs here on ``evaluation.workers`` processes (default: the
machine's cores), before the LLM is asked anything, so the two never compete for cores. So do the
other LLM-free parts (:func:`run_forked`): the lookahead and fetch policy per (household,
method) and the missing-label runs. (The robustness suite's LLM-free rows were tried there too
and gained nothing: the parent must fit the same models again for the gated rows.)
Results are identical to running in one process: each task is deterministic and the parent
stores them under its own cache keys.
"""

from __future__ import annotations

import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor
from typing import Callable, Sequence, TypeVar

from globe.config import GlobeConfig
from globe.data.records import Household
from globe.evaluation.selection import Memo
from globe.evaluation.tuning import model_search_key, tuned_models

T = TypeVar("T")
R = TypeVar("R")


def worker_count(requested: int | None) -> int:
    """``requested`` processes, or one per available core."""
    if requested:
        return requested
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not on Linux
        return max(1, os.cpu_count() or 1)


def run_parallel(fn: Callable[[T], R], tasks: Sequence[T], workers: int,
                 cost: Sequence[float] | None = None) -> list[R]:
    """``[fn(t) for t in tasks]`` on up to ``workers`` processes (in this one when 1 or a single
    task); ``cost``, an estimate per task, starts the longest first.

    Workers are forked where the platform can: a fork server or spawned workers would import
    the caller's main script again, so a user's script without an ``if __name__ ==
    "__main__"`` guard would run twice. The forked workers only count and score; they never
    call into llama.cpp, whose threads the parent may hold."""
    if workers <= 1 or len(tasks) <= 1:
        return [fn(t) for t in tasks]
    if "fork" in multiprocessing.get_all_start_methods():
        return run_forked(lambda i: fn(tasks[i]), len(tasks), workers, cost)
    spawn = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=min(workers, len(tasks)), mp_context=spawn) as pool:
        return list(pool.map(fn, tasks))


_FORKED: Callable[[int], object] | None = None


def _call_forked(i: int) -> object:
    assert _FORKED is not None
    return _FORKED(i)


def run_forked(fn: Callable[[int], R], n: int, workers: int, cost: Sequence[float] | None = None) -> list[R]:
    """``[fn(i) for i in range(n)]``, on up to ``workers`` forked processes that inherit ``fn``
    (a closure over fitted models and caches: nothing is pickled but the index and the
    result). In this process when 1 worker, a single task, or no fork on this platform; inside
    a forked task, nested calls run in that task's process. One call at a time per process
    (the closure is handed to the workers through a module global). ``cost``, an estimate per
    task, starts the longest first (fewer workers idle at the end); results keep index order."""
    global _FORKED
    if cost is not None and len(cost) != n:
        raise ValueError(f"run_forked: {len(cost)} cost estimates for {n} tasks")
    if workers <= 1 or n <= 1 or "fork" not in multiprocessing.get_all_start_methods():
        return [fn(i) for i in range(n)]
    if _FORKED is not None:  # already inside a forked run: no nested pools
        return [fn(i) for i in range(n)]
    order = list(range(n)) if cost is None else sorted(range(n), key=lambda i: -cost[i])
    _FORKED = fn
    try:
        with ProcessPoolExecutor(max_workers=min(workers, n), mp_context=multiprocessing.get_context("fork")) as pool:
            done = list(pool.map(_call_forked, order))
    finally:
        _FORKED = None
    out: list = [None] * n
    for i, result in zip(order, done):
        out[i] = result
    return out


def _select(task: tuple[Household, GlobeConfig, str]) -> tuple:
    household, config, family = task
    return tuned_models(household, config, family, Memo())


def precompute_selections(config: GlobeConfig, households: Sequence[Household], families: Sequence[str],
                          memo: Memo, config_for: Callable[[Household, str], GlobeConfig] | None = None) -> int:
    """Run every (household, family) cross-validation missing from ``memo`` on
    ``config.evaluation.workers`` processes, and keep each result where
    :func:`~globe.evaluation.tuning.tuned_models` looks for it (with ``config_for(household,
    family)`` when given, else ``config``). Returns how many ran."""
    tasks = [(h, config if config_for is None else config_for(h, f), f) for h in households
             for f in dict.fromkeys(families)]
    todo = [(h, c, f) for h, c, f in tasks if model_search_key(h, c, f) not in memo]
    # the routine family's search is about twice the n-gram's (clock models, alignments): first
    results = run_parallel(_select, todo, worker_count(config.evaluation.workers),
                           [2.0 if f == "routine" else 1.0 for _, _, f in todo])
    for (h, c, f), result in zip(todo, results):
        memo.put(model_search_key(h, c, f), result)
    return len(todo)
