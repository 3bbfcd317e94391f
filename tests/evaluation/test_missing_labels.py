"""Missing activity labels: the protocol is unchanged with every label visible; masks; results."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from globe import assembly
from globe.config import GlobeConfig
from globe.errors import ConfigError
from globe.evaluation import lookahead as lk
from globe.evaluation import relocation
from globe.evaluation.missing_labels import (
    FilterSetup,
    check_fractions,
    day_mask,
    evaluate_fraction,
    filtered_lookahead,
    missing_label_rows,
    write_missing_label_results,
)
from globe.evaluation.protocol import evaluate_days
from globe.evaluation.selection import Memo, Selection


def _setup(h, config: GlobeConfig, previous_share: float) -> FilterSetup:
    models = config.models.model_copy(update={"activity_estimator": "routine", "object_marginal": True})
    fitted = assembly.fit_household(h, config.model_copy(update={"models": models}))
    emission = assembly.movement_emission(config.filter, previous_share=previous_share, weight=0.5)
    emission.fit(h.train, h.objects)
    chooser = assembly.object_chooser(fitted.objects, config.gate, None, marginal=True)
    return FilterSetup(h, models, fitted.activity, emission, chooser, Selection({}), 0.0, config.sequences.alignment)


def test_every_label_visible_is_the_protocol(households):
    """With all labels and the movement credited to the earlier activity (as the protocol does),
    the filter adds nothing: records equal evaluate_days with the plain model."""
    h, config = households["C"], GlobeConfig()
    setup = _setup(h, config, previous_share=1.0)
    days = h.test[:2]
    res = evaluate_fraction(setup, config, 1.0, Memo(), days=days, lookahead=False)
    ref = evaluate_days(h, days, setup.activity, setup.chooser, alignment=config.sequences.alignment)
    assert res.hidden_steps == 0
    assert [(r.step, r.predicted, r.p_true) for r in res.activity] == [(r.step, r.predicted, pytest.approx(r.p_true))
                                                                        for r in ref.activity]
    assert [(r.step, r.true, r.predicted) for r in res.objects] == [(r.step, r.true, r.predicted) for r in ref.objects]


def test_hidden_labels_change_the_activity_beliefs(households):
    h, config = households["C"], GlobeConfig()
    setup = _setup(h, config, previous_share=0.5)
    day = h.test[:1]
    none = evaluate_fraction(setup, config, 0.0, Memo(), days=day, lookahead=False)
    full = evaluate_fraction(setup, config, 1.0, Memo(), days=day, lookahead=False)
    assert none.hidden_steps == len(day[0]) and full.hidden_steps == 0
    assert len(none.activity) == len(full.activity) == len(day[0]) - 1
    assert len(none.objects) == len(full.objects)
    assert [r.p_true for r in none.activity] != [r.p_true for r in full.activity]


def test_lookahead_through_the_filter_with_all_labels_is_the_plain_forecast(households):
    h, config = households["A"], GlobeConfig()
    setup = _setup(h, config, previous_share=0.5)
    movements = assembly.movement_model(config.lookahead, 10).fit(h.train, h.objects)
    fc = assembly.forecaster_over(setup.activity, movements, config.lookahead)  # the filter's own model
    day = h.test[0]
    plain = lk.forecast_days(fc, [day], 3, 30, 45)
    wrapped = filtered_lookahead(fc, setup, config.filter, [day], {day.name: [True] * len(day)}, 3, 30, 45)
    for a, b in zip(plain.pairs, wrapped.pairs):
        np.testing.assert_array_equal(np.concatenate(a.probability), np.concatenate(b.probability))
        np.testing.assert_array_equal(np.concatenate(a.hit), np.concatenate(b.hit))
    assert wrapped.activity_correct.tolist() == plain.activity_correct.tolist()
    hidden = filtered_lookahead(fc, setup, config.filter, [day], {day.name: [False] * len(day)}, 3, 30, 45)
    assert hidden.activity_total.sum() == plain.activity_total.sum()
    for p in hidden.pairs:
        assert np.all(np.concatenate(p.probability) <= 1 + 1e-9)
    assert any(not np.array_equal(np.concatenate(a.probability), np.concatenate(b.probability))
               for a, b in zip(plain.pairs, hidden.pairs))


def test_masks_are_per_day_and_fractions_are_checked(households):
    h, fcfg = households["A"], GlobeConfig().filter
    a, b = day_mask(fcfg, "A", h.test[0], 0.5), day_mask(fcfg, "A", h.test[1], 0.5)
    assert sum(a) == round(0.5 * len(h.test[0])) and a != b
    assert a == day_mask(fcfg, "A", h.test[0], 0.5)
    assert day_mask(fcfg.model_copy(update={"seed": 1}), "A", h.test[0], 0.5) != a
    with pytest.raises(ConfigError):
        check_fractions((0.5, 1.5))
    with pytest.raises(ConfigError):
        GlobeConfig().with_overrides({"filter.max_hypotheses": 0})
    with pytest.raises(ConfigError):
        GlobeConfig().with_overrides({"filter.fractions": [0.5, 1.5]})


def test_results_table_and_plot(households, tmp_path):
    h, config = households["B"], GlobeConfig()
    setup = _setup(h, config, previous_share=0.5)
    results = [evaluate_fraction(setup, config, f, Memo(), days=h.test[:1], lookahead=False) for f in (0.0, 1.0)]
    rows = missing_label_rows(results, horizons=2)
    assert [(r["household"], r["labels_pct"]) for r in rows] == [("B", 0), ("B", 100), ("mean", 0), ("mean", 100)]
    assert rows[2]["object_f1"] == rows[0]["object_f1"] and 0 <= rows[0]["object_f1"] <= 1
    assert rows[0]["lookahead_f1_10min"] is None
    paths = write_missing_label_results(tmp_path, rows, [{"household": "B", "params": {}, "chosen": True}])
    assert all(p.exists() and p.stat().st_size > 0 for p in paths)
    with open(tmp_path / "missing_labels.csv", newline="") as f:
        got = list(csv.DictReader(f))
    assert [g["labels_pct"] for g in got] == ["0", "100", "0", "100"]


def test_threshold_per_label_share_is_chosen_on_training_days_with_that_share(monkeypatch, households):
    """With labels missing, each horizon's threshold is the best on held-out training days masked
    the same way, with the lookahead's movement setting (ties to the first listed); with every
    label, or with the option off, the lookahead's own thresholds."""
    from globe.evaluation import missing_labels as ml

    h, config = households["A"], GlobeConfig().with_overrides({"filter.threshold_per_fraction": True})
    setup = _setup(h, config, previous_share=0.5)
    seen: list[tuple] = []

    def fake_hidden(setup_, cfg, fraction, memo=None, setting=(True, False, False)):
        seen.append((fraction, setting))
        # a change at every pair, found with p = 0.35 (horizon 0) or 0.22 (the others)
        pairs = [relocation.HorizonPairs([np.array([0.35 if s == 0 else 0.22])], [np.array([True])], [np.array([True])])
                 for s in range(6)]
        return relocation.LookaheadRun(6, pairs, np.zeros(6, int), np.zeros(6, int))

    labelled = {"run_end": True, "run_memory": False, "run_next": True, "thresholds": (0.5, 0.4, 0.3, 0.25, 0.2, 0.15)}
    monkeypatch.setattr(ml, "hidden_cv_run", fake_hidden)
    monkeypatch.setattr(lk, "choose_settings", lambda *a, **k: Selection(dict(labelled)))
    # thresholds <= p score F1 1, higher 0: first listed of (0.5, 0.4, 0.3, 0.25, 0.2, 0.15) at or below p
    assert ml.label_share_thresholds(setup, config, Memo(), 0.0) == (0.3,) + (0.2,) * 5
    assert seen == [(0.0, (True, False, True))]
    assert ml.label_share_thresholds(setup, config, Memo(), 1.0) == labelled["thresholds"]
    off = config.with_overrides({"filter.threshold_per_fraction": False})
    assert ml.label_share_thresholds(setup, off, Memo(), 0.25) == labelled["thresholds"]
    assert len(seen) == 1


def test_filter_candidates_try_the_switch_only_where_it_exists(config):
    """The switch table needs the change flag and a share credited to a_{s-1}: elsewhere it would
    repeat a candidate. Each switch candidate follows its plain twin (the simpler wins ties)."""
    from globe.evaluation.missing_labels import filter_candidates

    fc = config.filter.model_copy(update={"emission_boundaries": (False, True), "emission_previous_shares": (0.5, 0.0),
                                          "emission_weights": (1.0,), "emission_switches": (False, True)})
    assert filter_candidates(fc) == [
        {"boundary": False, "previous_share": 0.5, "weight": 1.0, "switch": False},
        {"boundary": False, "previous_share": 0.0, "weight": 1.0, "switch": False},
        {"boundary": True, "previous_share": 0.5, "weight": 1.0, "switch": False},
        {"boundary": True, "previous_share": 0.5, "weight": 1.0, "switch": True},
        {"boundary": True, "previous_share": 0.0, "weight": 1.0, "switch": False}]
