"""GET /households/{name}/stats: beside the one-step activity accuracy, persistence's and hour +
activity's over the same scored steps (counted per day in the store, so they survive a restart),
and the dashboard's scores tile shows them."""

from __future__ import annotations

import pytest

from globe.models.baselines import HourActivityBaseline, mode
from tests.service.dashboard_helpers import app_client, create, login, observe_days, tokens

pytestmark = pytest.mark.service


def test_the_stats_show_the_baselines_on_the_steps_the_model_was_scored_on(tmp_path, households):
    db = tmp_path / "globe.sqlite3"
    admin, _ = tokens(db, "A")
    h = households["A"]
    day0, day1 = h.test[0], h.test[1]
    with app_client(db, admin) as c:
        create(c, "A", h)
        observe_days(c, "A", h, [day0, day1], steps=30, predict=False)
        scores = c.get("/households/A/stats").json()["scores"]
    rule = HourActivityBaseline(1).fit(h.train)
    expected = []
    for day, last in ((day0, len(day0)), (day1, 29)):  # day 1: steps 1..28 closed
        steps = range(1, last)
        expected.append((len(steps), sum(day.activities[t - 1] == day.activities[t] for t in steps),
                         sum(mode(rule.proba(day.activities[t - 1], day.minutes[t - 1], 1)) == day.activities[t]
                             for t in steps)))
        rule.partial_fit([day])  # learned when day 1 began
    days = scores["days"]
    assert [(d["predictions"], d["persistence_correct"], d["hour_activity_correct"]) for d in days] == expected
    total = sum(e[0] for e in expected)
    assert scores["persistence_accuracy"] == round(sum(e[1] for e in expected) / total, 4)
    assert scores["hour_activity_accuracy"] == round(sum(e[2] for e in expected) / total, 4)
    with app_client(db, admin) as c:  # a restart reads them back from the store
        again = c.get("/households/A/stats").json()["scores"]
    with app_client(db) as browser:
        assert login(browser, admin).status_code == 303
        page = browser.get("/dashboard/households/A").text
    assert again["days"][0] == days[0] and again["persistence_accuracy"] is not None
    assert "same steps: persistence" in page
