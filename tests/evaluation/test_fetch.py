"""The offline robot loop: fetch precision, recall and lead times counted by hand on a toy day."""

from __future__ import annotations

import pytest

from globe.data.records import Day, Household, Node
from globe.evaluation.fetch import ReplayedDay, evaluate_fetch, fetch_rows, follow_policy, lead_time_rows, pooled
from globe.inference.fetch_policy import FetchCandidate, FetchPolicy, FetchReport, left_alone
from globe.sequences.movements import moved_objects
from tests.inference.test_forecast import toy_forecaster

HOME = Household("T", (Node("cup#1", "cup", "object", True, "shelf"), Node("book#2", "book", "object", True, "shelf")),
                 ("cup", "book"), (), ())
# steps 0..6; the cup is used at steps 2 and 6, the book at step 5
DAY = Day("test/000", (0, 10, 20, 30, 40, 50, 60), tuple("aabbbbb"),
          (("shelf", "shelf"), ("shelf", "shelf"), ("table", "shelf"), ("table", "shelf"), ("table", "shelf"),
           ("table", "sink"), ("shelf", "sink")))


def table(fetch_at: dict[int, list[tuple[str, float]]], alone: dict[int, set[str]] | None = None) -> ReplayedDay:
    """The toy day as a session saw it, with these candidates after each step."""
    return ReplayedDay(DAY.minutes, tuple(moved_objects(DAY, HOME.objects)),
                       tuple(tuple(FetchCandidate(o, p, None, 0.0) for o, p in fetch_at.get(t, []))
                             for t in range(len(DAY))),
                       tuple(frozenset((alone or {}).get(t, ())) for t in range(len(DAY))), FetchReport())


def policy(window: int = 2, min_lead: int = 1) -> FetchPolicy:
    return FetchPolicy(toy_forecaster(), cost_useless=1, cost_missed=1, min_lead_steps=min_lead, window_steps=window,
                       max_fetches_per_step=2)


def test_uses_are_the_steps_an_object_moved():
    assert moved_objects(DAY, HOME.objects) == [set(), set(), {"cup"}, set(), set(), {"book"}, {"cup"}]


def test_replay_counts_by_hand():
    # t=0: cup (used at 2: lead 20 min, useful);
    # t=1: cup again is pending -> skipped, book (used at 5: too late, useless)
    # t=4: book again (its first fetch expired at 1 + 2 = 3), used at 5: useful, lead 10 min
    # t=5: cup with p = 0.4 is not worth it (EV < 0)
    cands = table({0: [("cup", 0.9)], 1: [("cup", 0.9), ("book", 0.8)], 4: [("book", 0.7)], 5: [("cup", 0.4)]})
    rep = follow_policy(policy(), cands)
    assert (rep.fetches, rep.useful_fetches) == (3, 2)
    assert (rep.used_objects, rep.used_fetched_in_advance) == (3, 2)  # cup@2 and book@5 fetched ahead; cup@6 not
    assert rep.precision == pytest.approx(2 / 3) and rep.recall == pytest.approx(2 / 3)
    assert sorted(rep.lead_minutes) == [10, 20] and rep.median_lead_min == 15.0


def test_minimum_lead_excludes_uses_that_come_too_soon():
    cands = table({1: [("cup", 0.9)]})  # the cup is used at step 2, one step later
    rep = follow_policy(policy(window=3, min_lead=2), cands)
    assert (rep.fetches, rep.useful_fetches, rep.used_fetched_in_advance) == (1, 0, 0)


def test_nothing_in_use_or_just_put_back_is_fetched():
    """The book is in use at steps 2-3 (a place of class in_use), back at 4: candidates for it
    there are passed over whatever their probability."""
    cands = table({2: [("book", 0.99)], 3: [("book", 0.99)], 4: [("book", 0.99)]}, {2: {"book"}, 3: {"book"},
                                                                                     4: {"book"}})
    assert follow_policy(policy(), cands).fetches == 0
    assert left_alone(("cup", "book"), ("shelf", "in_use#9"), ("shelf", "shelf"), {"in_use#9"}) == {"book"}
    assert left_alone(("cup", "book"), ("shelf", "shelf"), ("in_use#9", "shelf"), {"in_use#9"}) == {"cup"}
    assert left_alone(("cup",), ("shelf",), ("table",), set()) == frozenset()


def test_curve_rows_and_lead_times_on_homer(households, config):
    """End to end on two real test days through a session: thresholds rise with the cost ratio,
    so fetches fall; at the configured costs the curve is what the session decided."""
    from globe.config import Deployment
    from globe.session import build_session

    h = households["A"]
    session = build_session(h, config, Deployment.configured(config, "persistence"), None, learn=False)
    ev = evaluate_fetch(session, h, h.test[:2], (0.5, 3.0, 9.0))
    fetches = [rep.fetches for _, _, rep in ev.curve]
    assert fetches == sorted(fetches, reverse=True) and fetches[0] > 0
    assert ev.curve[1][2] == ev.report  # 3.0 is the configured ratio
    rows = fetch_rows([ev], 3.0)
    assert [r["configured"] for r in rows if r["household"] == "A"] == [False, True, False]
    assert {r["household"] for r in rows} == {"A", "all"}
    leads = lead_time_rows([ev])
    assert sum(r["uses"] for r in leads) == ev.report.used_fetched_in_advance
    assert all(r["lead_min"] >= config.policy.min_lead_minutes for r in leads)
    with pytest.raises(ValueError, match="learn nothing"):
        evaluate_fetch(build_session(h, config, Deployment.configured(config), None), h, h.test[:1], (3.0,))


def test_pooled_adds_counts():
    a = FetchReport(steps=5, fetches=4, useful_fetches=3, used_objects=10, used_fetched_in_advance=2, lead_minutes=[10])
    b = FetchReport(steps=5, fetches=6, useful_fetches=3, used_objects=10, used_fetched_in_advance=6, lead_minutes=[30])
    p = pooled([a, b])
    assert p.precision == pytest.approx(0.6) and p.recall == pytest.approx(0.4) and p.median_lead_min == 20.0
