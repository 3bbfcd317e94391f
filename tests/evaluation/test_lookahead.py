"""The relocation metric against hand-counted toy days, and the pooled scorer against it."""

from __future__ import annotations

import numpy as np
import pytest

from globe.evaluation.lookahead import LookaheadResult, forecast_days, lookahead_rows
from globe.evaluation.relocation import (
    HorizonPairs,
    LookaheadRun,
    RelocationCounts,
    reference_steps,
    relocation_counts,
    true_first_locations,
)
from globe.evaluation.selection import Memo, Selection

# Steps 0..5 of a toy day; columns: cup (moves twice), book (moves away and back), pen (never moves).
TOY = [
    ("shelf", "desk", "box"),
    ("shelf", "desk", "box"),
    ("table", "bed", "box"),   # step 2: cup -> table, book -> bed
    ("sink", "desk", "box"),   # step 3: cup -> sink (second move), book back to the desk
    ("sink", "desk", "box"),
    ("shelf", "desk", "box"),  # step 5: cup back to the shelf
]


def test_true_first_location_is_the_first_new_place_within_the_horizon():
    # r = 0: step 1 is unchanged, so horizon 0 sees no change; horizon 1 reaches step 2
    assert true_first_locations(TOY, 0, 0) == [None, None, None]
    assert true_first_locations(TOY, 0, 1) == ["table", "bed", None]
    assert true_first_locations(TOY, 1, 0) == ["table", "bed", None]
    # moving twice within the horizon: the first new place counts (table, not sink)
    assert true_first_locations(TOY, 1, 2) == ["table", "bed", None]
    # moving away and back within the horizon still is a change, to where it went
    assert true_first_locations(TOY, 1, 4) == ["table", "bed", None]
    # r = 3: the cup comes back to the shelf at step 5 only (s >= 1); the book stays put
    assert true_first_locations(TOY, 3, 0) == [None, None, None]
    assert true_first_locations(TOY, 3, 1) == ["shelf", None, None]
    # r = 2: the book goes back to where it was before; that is a change to the desk
    assert true_first_locations(TOY, 2, 0) == ["sink", "desk", None]


def test_relocation_counts_by_hand():
    true = ["table", "bed", None, "sink", None]
    predicted = ["table", "desk", "box", None, None]
    # correct: the cup only (the book's place is wrong; the pen never moved; the sink was missed)
    c = relocation_counts(true, predicted)
    assert (c.correct, c.predicted, c.true) == (1, 3, 3)
    assert c.precision == pytest.approx(1 / 3) and c.recall == pytest.approx(1 / 3) and c.f1 == pytest.approx(1 / 3)
    assert RelocationCounts().f1 == 0.0
    with pytest.raises(ValueError):
        relocation_counts(["a"], [])


def test_relocation_counts_pool_over_days_by_adding():
    day1 = relocation_counts(["x", None], ["x", "y"])  # 1 correct, 2 predicted, 1 true
    day2 = relocation_counts(["z", "w"], [None, "w"])  # 1 correct, 1 predicted, 2 true
    both = day1 + day2
    assert (both.correct, both.predicted, both.true) == (2, 3, 3)
    assert both.f1 == pytest.approx(2 / 3)


def test_threshold_turns_probabilities_into_counts():
    pairs = HorizonPairs([np.array([0.9, 0.4, 0.2, 0.0])], [np.array([True, False, True, False])],
                         [np.array([True, True, True, False])])
    assert (pairs.counts(0.5).correct, pairs.counts(0.5).predicted, pairs.counts(0.5).true) == (1, 1, 3)
    c = pairs.counts(0.1)
    assert (c.correct, c.predicted, c.true) == (2, 3, 3)
    assert pairs.counts(0.0).predicted == 3  # zero probability: nothing to predict


def test_reference_steps_keep_the_horizon_inside_the_day(households):
    day = households["A"].test[0]
    steps = reference_steps(day, 6, 1, 102)
    assert steps[0] == 1 and steps[-1] == 102 and steps[-1] + 6 <= len(day) - 1
    assert list(reference_steps(day, 6, 1, 500))[-1] == len(day) - 7


def test_pooled_scorer_agrees_with_hand_counting(households, persistence_forecaster):
    """forecast_days' vectorised pairs give the same counts as relocation_counts on the same
    predictions, at every horizon."""
    h = households["A"]
    day = h.test[0]
    threshold = 0.3
    run = forecast_days(persistence_forecaster, [day], 6, first=10, last=40)
    for s in range(6):
        total = RelocationCounts()
        for r in range(10, 41):
            fc = persistence_forecaster.forecast(day.activities[:r], day.locations[: r + 1], 5)
            where, p = fc.first_location(s)
            predicted = [w if q >= threshold and q > 0 else None for w, q in zip(where, p)]
            total = total + relocation_counts(true_first_locations(day.locations, r, s), predicted)
        assert run.pairs[s].counts(threshold) == total
    assert run.activity_total.tolist() == [31] * 6
    assert all(0 <= a <= 1 for a in run.activity_accuracy())


def test_rows_average_the_households():
    def result(hh: str, correct: int) -> LookaheadResult:
        counts = (RelocationCounts(correct, 10, 10),)
        return LookaheadResult("routine", hh, (0.5,), counts, (0.5,), 0.01, Selection({"thresholds": (0.5,)}))

    rows = lookahead_rows([result("A", 5), result("B", 7)])
    assert [r["household"] for r in rows] == ["A", "B", "mean"]
    assert rows[-1]["f1"] == pytest.approx(0.6) and rows[0]["horizon_min"] == 10


def test_cross_validation_lets_the_simpler_setting_win_ties(monkeypatch, households, config):
    """Equal held-out F1 with and without the run-end feature: the simpler (listed first) wins,
    and each horizon takes the first listed threshold among equals."""
    from globe.evaluation import lookahead as lk

    def fake_runs(household, cfg, models, settings, memo, oracle=False):
        pairs = [HorizonPairs([np.array([0.9, 0.45])], [np.array([True, True])], [np.array([True, True])])
                 for _ in range(6)]
        return {s: LookaheadRun(6, pairs, np.zeros(6, int), np.zeros(6, int)) for s in settings}

    monkeypatch.setattr(lk, "cv_runs", fake_runs)
    cfg = config.with_overrides({"lookahead.run_end": (False, True), "lookahead.run_memory": (False, True),
                                 "lookahead.thresholds": (0.5, 0.4, 0.3)})
    chosen = lk.choose_settings(households["A"], cfg, cfg.models, Memo())
    # threshold 0.5 finds 1 of 2 changes, 0.4 and 0.3 both: 0.4 is listed first among the best
    assert chosen.best == {"run_end": False, "run_memory": False, "run_next": False, "thresholds": (0.4,) * 6}
    # settings: the plain model, then with the run end: x (memory or not) x (next activity or not);
    # memory and the next activity only with the run end
    assert len(chosen.scores) == 5 * 3 * 6
    assert [(p["run_end"], p["run_memory"], p["run_next"]) for p, _ in chosen.scores[::18]] == [
        (False, False, False), (True, False, False), (True, False, True), (True, True, False), (True, True, True)]
