"""The robot's decision rule: fetch when p * c_missed - (1 - p) * c_useless > 0."""

from __future__ import annotations

import pytest

from globe import assembly
from globe.config import PolicyConfig
from globe.inference.fetch_policy import FetchCandidate, FetchPolicy, expected_value
from tests.inference.test_forecast import toy_forecaster


def cand(obj: str, p: float) -> FetchCandidate:
    return FetchCandidate(obj, p, None, 0.0)


def test_threshold_follows_from_the_costs():
    f = toy_forecaster()
    assert FetchPolicy(f, cost_useless=3, cost_missed=1).threshold == pytest.approx(0.75)
    assert FetchPolicy(f, cost_useless=1, cost_missed=1).threshold == pytest.approx(0.5)
    assert FetchPolicy(f, cost_useless=0, cost_missed=0).threshold == 1.0
    assert expected_value(0.75, 3, 1) == pytest.approx(0.0)
    assert expected_value(0.9, 3, 1) == pytest.approx(0.9 - 0.3)


def test_fetches_only_positive_expected_value_not_pending_and_at_most_the_limit():
    policy = FetchPolicy(toy_forecaster(), cost_useless=1, cost_missed=1, max_fetches_per_step=2)
    ranked = [cand("cup", 0.9), cand("book", 0.8), cand("pen", 0.7), cand("key", 0.5), cand("mug", 0.2)]
    assert [c.obj for c in policy.choose(ranked)] == ["cup", "book"]
    assert [c.obj for c in policy.choose(ranked, exclude={"cup"})] == ["book", "pen"]
    assert [c.obj for c in policy.choose(ranked, exclude={"cup", "book", "pen"})] == []  # 0.5: EV = 0, not > 0
    free = FetchPolicy(toy_forecaster(), cost_useless=0, cost_missed=0)
    assert free.choose(ranked) == []  # nothing to gain, nothing to lose: the robot stays put


def test_bad_settings_are_refused():
    with pytest.raises(ValueError):
        FetchPolicy(toy_forecaster(), cost_useless=-1)
    with pytest.raises(ValueError):
        FetchPolicy(toy_forecaster(), min_lead_steps=4, window_steps=2)


def test_decide_reads_the_forecast_of_the_lead_window():
    """The toy home with b just begun: the cup leaves the shelf next step for sure and the
    book on b's second step, so both are worth fetching and go where they are used."""
    policy = FetchPolicy(toy_forecaster(), cost_useless=3, cost_missed=1, min_lead_steps=1, window_steps=2)
    chosen = policy.decide(("a", "b"), [("shelf", "shelf"), ("shelf", "shelf")])
    assert sorted((c.obj, c.to_location) for c in chosen) == [("book", "sink"), ("cup", "table")]
    assert all(c.probability == pytest.approx(1.0, abs=1e-6) and c.expected_value > 0 for c in chosen)
    # with a minimum lead of two steps only the book (used on the second step) is useful
    late = FetchPolicy(toy_forecaster(), cost_useless=3, cost_missed=1, min_lead_steps=2, window_steps=2)
    assert [c.obj for c in late.decide(("a", "b"), [("shelf", "shelf"), ("shelf", "shelf")])] == ["book"]


def test_assembly_converts_minutes_to_steps():
    policy = assembly.fetch_policy(toy_forecaster(), PolicyConfig(min_lead_minutes=15, lead_window_minutes=60), 10)
    assert (policy.min_lead_steps, policy.window_steps) == (2, 6)
