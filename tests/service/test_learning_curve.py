"""The learning curve through the real service: scored after exactly k learned days it agrees
with the offline protocol, and its tables average what they should."""

from __future__ import annotations

import dataclasses

import pytest

from globe.assembly import fit_household
from globe.errors import DataError
from globe.evaluation.metrics import f1
from globe.evaluation.protocol import evaluate_days
from globe.models.baselines import HourActivityBaseline, mode
from globe.reasoning.choice import ObjectChooser
from globe.service.learning_curve import NO_PREDICTION, CurvePoint, curve_point, learning_curve, mean_rows, table_rows


def _point(household: str, k: int, activity: float | None, fetch_precision: float) -> CurvePoint:
    return CurvePoint(household=household, days_learned=k, activity_f1=activity, object_f1=0.5,
                      fetch_precision=fetch_precision, fetch_recall=0.25, activity_steps=10, object_events=4, fetches=2,
                      observations=20, elapsed_s=0.1)


def test_mean_rows_average_each_checkpoint_over_households_skipping_missing_scores():
    points = [_point("A", 1, 0.6, 0.2), _point("B", 1, 0.8, 0.4), _point("A", 5, None, 0.5), _point("B", 5, 0.9, 0.7)]
    means = {r["days_learned"]: r for r in mean_rows(points)}
    assert means[1]["activity_f1"] == pytest.approx(0.7) and means[1]["fetch_precision"] == pytest.approx(0.3)
    assert means[5]["activity_f1"] == pytest.approx(0.9)  # A had nothing to score: it does not pull the mean down
    rows = table_rows(points)
    assert [r["household"] for r in rows] == ["A", "B", "A", "B", "mean", "mean"]
    assert list(rows[0]) == ["household", "days_learned", "activity_f1", "object_f1", "fetch_precision", "fetch_recall",
                             "persistence_f1", "hour_activity_f1"]


@pytest.fixture(scope="module")
def service(tmp_path_factory):
    """``globe serve`` whose clock-skew window admits replayed days, with an admin token."""
    pytest.importorskip("httpx", reason="the service extra is not installed")
    from tests.service_process import Server

    tmp = tmp_path_factory.mktemp("curve")
    server = Server(tmp / "globe.sqlite3", tmp / "server.log", {"GLOBE_SERVICE__MAX_CLOCK_SKEW": "P30D"}).start()
    url, token = server.url, server.admin
    try:
        yield url, token
    finally:
        server.stop()


@pytest.mark.service
def test_curve_point_through_the_service_matches_the_offline_protocol(service, households, config):
    """Two training days streamed as observations, two test days each in its own household: the
    activity F1 is exactly the protocol's for a model trained on those two days (nothing leaked
    from one test day into the other), and the households are gone afterwards."""
    from globe.service.client import GlobeClient

    h = households["B"]
    small = dataclasses.replace(h, train=h.train[:3], test=h.test[:2])
    url, token = service
    with GlobeClient(url, token=token) as client:
        point = curve_point(client, small, 2, isolate_test_days=True)
        assert client.households() == []
    fitted = fit_household(small, config, days=small.train[:2])
    offline = evaluate_days(small, small.test, fitted.activity, ObjectChooser(fitted.objects))
    assert point.activity_steps == len(offline.activity) == sum(len(d) - 1 for d in small.test)
    expected = f1([r.true for r in offline.activity], [r.predicted for r in offline.activity])
    assert point.activity_f1 == pytest.approx(expected)
    steps = [(d, t) for d in small.test for t in range(1, len(d))]  # the baselines: the same steps
    truth = [d.activities[t] for d, t in steps]
    assert point.persistence_f1 == pytest.approx(f1(truth, [d.activities[t - 1] for d, t in steps]))
    rule = HourActivityBaseline(1).fit(small.train[:2])  # each test day in its own household: 2 days learned
    said = [mode(rule.proba(d.activities[t - 1], d.minutes[t - 1], 1)) or NO_PREDICTION for d, t in steps]
    assert point.hour_activity_f1 == pytest.approx(f1(truth, said))
    assert point.object_events == len(offline.objects)
    streamed = sum(len(d) for d in small.train[:2])  # into each test day's own household
    assert point.observations == len(small.test) * streamed + sum(len(d) for d in small.test)
    assert 0.0 <= point.fetch_precision <= 1.0 and 0.0 <= point.fetch_recall <= 1.0


def test_checkpoints_beyond_the_training_days_are_refused(households):
    h = households["A"]
    with pytest.raises(DataError, match="checkpoint 66"):
        learning_curve(None, h, (1, 66))  # type: ignore[arg-type]  # refused before any request


def test_replays_keep_the_weekday_of_days_named_by_their_date():
    """Dated days are replayed on their own dates moved by whole weeks, ending on or before the
    last date asked, gaps kept; numbered days (or dates out of order) on consecutive dates."""
    import datetime as dt

    from globe.data.records import Day
    from globe.evaluation.online import replay_dates
    from globe.service.learning_curve import required_clock_skew
    from tests.simulated import weekly_home

    def day(name):
        return Day(name, (360,), ("a",), ((),))

    dated = [day("train/2024-01-01"), day("train/2024-01-02"), day("test/2024-01-10")]
    got = replay_dates(dated, dt.date(2026, 3, 1))
    assert [d.weekday() for d in got] == [0, 1, 2] and got[-1] <= dt.date(2026, 3, 1) < got[-1] + dt.timedelta(7)
    assert [(b - a).days for a, b in zip(got, got[1:])] == [1, 8]
    for undated in ([day("d1"), day("d2")], [dated[1], dated[0]]):
        assert replay_dates(undated, dt.date(2026, 3, 1)) == [dt.date(2026, 2, 28), dt.date(2026, 3, 1)]
    home = weekly_home(40, 10, 0)  # the test days follow the training days: the replay spans them all
    assert required_clock_skew(home, [2]).days >= (home.test[-1].calendar_date - home.train[0].calendar_date).days
