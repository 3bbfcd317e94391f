"""Nothing to score is *absent* (None), never NaN, and means over households skip it and count."""

from __future__ import annotations

import math
from types import SimpleNamespace

from globe.evaluation.experiments import table1_rows
from globe.evaluation.metrics import f1


def _records(pairs):
    return [SimpleNamespace(true=t, predicted=p) for t, p in pairs]


def _run(household: str, activity, objects):
    ev = SimpleNamespace(activity=_records(activity), objects=_records(objects))
    return SimpleNamespace(method="ngram", household=household, evaluation=ev, oracle=ev)


def test_f1_of_nothing_is_absent():
    assert f1([], []) is None
    assert f1(["a", "b"], ["a", "a"]) == 0.5 * (1 / 1.5) + 0.5 * 0  # weighted: a has F1 2/3, b 0


def test_means_skip_absent_households_and_say_how_many():
    runs = [
        _run("A", [("x", "x"), ("y", "x")], [("cup", "cup")]),
        _run("B", [("x", "x")], []),  # objects never move: object F1 absent
    ]
    rows = table1_rows(runs)
    b = next(r for r in rows if r["household"] == "B" and r["average"] == "weighted")
    assert b["object_f1"] is None and b["mean_f1"] is None and b["activity_f1"] == 1.0
    mean = next(r for r in rows if r["household"] == "mean" and r["average"] == "weighted")
    a_act = f1(["x", "y"], ["x", "x"])
    assert mean["activity_f1"] == round((a_act + 1.0) / 2, 4) and mean["n_households"] == 2
    assert mean["object_f1"] == 1.0 and mean["n_households_object"] == 1
    assert mean["mean_f1"] == round((a_act + 1.0) / 2, 4)  # only A has both parts
    assert not any(isinstance(v, float) and math.isnan(v) for r in rows for v in r.values())


def test_a_method_with_nothing_anywhere_has_absent_means():
    rows = table1_rows([_run("A", [], [])])
    mean = next(r for r in rows if r["household"] == "mean" and r["average"] == "macro")
    assert (mean["activity_f1"], mean["object_f1"], mean["mean_f1"], mean["n_households"]) == (None, None, None, 0)
