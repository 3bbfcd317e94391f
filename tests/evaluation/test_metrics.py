"""Metrics against hand computation: calibration (ECE) and behavioural-consistency groups."""

from dataclasses import replace

import pytest

from globe.evaluation.metrics import calibration, consistency_groups


def test_calibration_matches_hand_computed_ece():
    # Bin [0.2, 0.3): confidences 0.2, 0.2 with 1 of 2 right -> |0.2 - 0.5| = 0.3, weight 2/4.
    # Bin [0.9, 1.0]: confidences 0.9, 1.0 with both right -> |0.95 - 1.0| = 0.05, weight 2/4.
    ece, (conf, acc, counts) = calibration([0.2, 0.2, 0.9, 1.0], [True, False, True, True], bins=10)
    assert ece == pytest.approx(0.5 * 0.3 + 0.5 * 0.05)
    assert conf == pytest.approx([0.2, 0.95]) and acc == [0.5, 1.0] and counts == [2, 2]


def test_perfectly_calibrated_predictions_have_zero_ece():
    ece, _ = calibration([0.5, 0.5, 1.0], [True, False, True], bins=4)
    assert ece == pytest.approx(0.0)


def test_consistency_groups_split_activities_into_thirds(households):
    small = replace(households["C"], train=households["C"].train[:10])
    groups = consistency_groups([small], "start_time")["C"]
    counts = {g: sum(v == g for v in groups.values()) for g in ("more", "moderate", "less")}
    assert max(counts.values()) - min(counts.values()) <= 1
    assert set(groups) == {a for d in small.train for a in d.activities}
    with pytest.raises(ValueError, match="unknown consistency definition"):
        consistency_groups([small], "vibes")


def test_f1_equals_scikit_learn_bit_for_bit():
    import random

    from sklearn.metrics import f1_score

    from globe.evaluation.metrics import f1

    rng = random.Random(7)
    for trial in range(300):
        labels = [f"a{i}" for i in range(rng.randint(1, 9))] + ["<none>"]
        n = rng.randint(1, 60)
        true = [rng.choice(labels[:-1]) for _ in range(n)]
        pred = [rng.choice(labels) if rng.random() < 0.6 else t for t in true]
        for average in ("weighted", "micro", "macro"):
            expected = float(f1_score(true, pred, average=average, zero_division=0))
            assert f1(true, pred, average) == expected, (trial, average)
    assert f1([], []) is None
