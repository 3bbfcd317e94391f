"""Cross-validations on several processes give exactly what one process gives."""

from dataclasses import replace

import pytest

from globe.config import GlobeConfig
from globe.evaluation.parallel import precompute_selections, run_parallel, worker_count
from globe.evaluation.selection import Memo
from globe.evaluation.tuning import model_search_key, tuned_models


def _square(x: int) -> int:
    return x * x


def test_run_parallel_keeps_the_order_of_tasks():
    assert run_parallel(_square, list(range(7)), 2) == [x * x for x in range(7)]
    assert run_parallel(_square, [3], 2) == [9]  # one task: no pool
    assert worker_count(3) == 3 and worker_count(None) >= 1


def test_selections_computed_on_other_processes_equal_the_ones_computed_here(households):
    config = GlobeConfig().with_overrides({"evaluation.workers": 2, "selection.folds": 3,
                                           "selection.routine_orders": (2, 3), "selection.time_weights": (0.0, 1.0)})
    small = [replace(h, train=h.train[:15], test=()) for h in households.values()][:2]
    memo = Memo()
    ran = precompute_selections(config, small, ["routine"], memo)
    assert ran == 2 and len(memo) == 2
    for h in small:
        here = tuned_models(h, config, "routine", Memo())
        there = memo.get(model_search_key(h, config, "routine"), lambda: None)
        assert there[0] == here[0]
        assert [s.scores for s in there[1].values()] == [s.scores for s in here[1].values()]
    assert precompute_selections(config, small, ["routine"], memo) == 0  # nothing left to run


def test_a_script_without_a_main_guard_runs_once(tmp_path):
    """Workers must not import the caller's script again (it would run its work twice)."""
    import subprocess
    import sys

    script = tmp_path / "unguarded.py"
    script.write_text("from globe.evaluation.parallel import run_parallel\n"
                      "print('ran', run_parallel(abs, [-1, -2, -3], 2))\n", encoding="utf-8")
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.splitlines() == ["ran [1, 2, 3]"]


def test_run_forked_runs_closures_in_order_and_does_not_nest():
    from globe.evaluation.parallel import run_forked

    data = {"offset": 10}  # a closure over live objects: nothing of it is pickled
    inner = run_forked(lambda i: run_forked(lambda j: (i, j), 2, 2), 3, 2)
    assert inner == [[(i, 0), (i, 1)] for i in range(3)]
    assert run_forked(lambda i: i + data["offset"], 5, 2) == [10, 11, 12, 13, 14]
    assert run_forked(lambda i: i, 1, 2) == [0]


def test_run_forked_starts_the_costliest_first_and_keeps_index_order(tmp_path):
    import time

    from globe.evaluation.parallel import run_forked

    log = tmp_path / "started"

    def task(i: int) -> int:
        with log.open("a") as fh:  # the order the tasks started in, seen across processes
            fh.write(f"{i}\n")
        time.sleep(0.2)  # long enough that a third task cannot start before the second is logged
        return i * i

    assert run_forked(task, 6, 2, cost=[1, 5, 2, 9, 0, 3]) == [0, 1, 4, 9, 16, 25]
    started = [int(x) for x in log.read_text().split()]
    assert sorted(started) == list(range(6))
    assert sorted(started[:2]) == [1, 3]  # the two costliest went first
    with pytest.raises(ValueError, match="cost estimates"):
        run_forked(task, 6, 2, cost=[1, 2])


def test_missing_labels_on_other_processes_equal_one_process(households):
    from globe.evaluation.missing_labels import run_missing_labels

    small = [replace(h, train=h.train[:12], test=h.test[:1]) for h in households.values()][:2]
    base = {"selection.folds": 3, "selection.routine_orders": (2,), "selection.time_weights": (1.0,),
            "filter.fractions": (0.0, 1.0), "filter.emission_weights": (0.5, 1.0),
            "filter.emission_previous_shares": (0.5,), "filter.emission_boundaries": (False,),
            "lookahead.horizon_minutes": 20, "lookahead.thresholds": (0.3, 0.5)}
    one = run_missing_labels(GlobeConfig().with_overrides({**base, "evaluation.workers": 1}), small)
    two = run_missing_labels(GlobeConfig().with_overrides({**base, "evaluation.workers": 2}), small)
    def numbers(rows):  # everything but the time each part took
        return [{k: v for k, v in r.items() if k != "seconds"} for r in rows]

    assert numbers(one.rows) == numbers(two.rows) and one.selection_rows == two.selection_rows
    assert len(one.rows) == 6 and len(one.selection_rows) == 4
    assert all(r["lookahead_f1_10min"] is not None for r in one.rows)
