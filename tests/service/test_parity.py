"""What the service does at a step is what the evaluation scored at that step.

HOMER+ test days are replayed through a real ``globe serve`` (over HTTP, the household created
with its training days and its models chosen by cross-validation in the background, as a user's
would be) and offline through :mod:`globe.evaluation.online` with the deployment the service chose:
one day from 06:00, one from 13:00 with an hour nobody watched, one from 18:00, learning each day
as it ends. Every prediction, every fetch and the online scores must be equal, step for step,
on 10-minute days and on the same days resampled to 5 minutes.
"""

from __future__ import annotations

import datetime as dt
import time
from dataclasses import replace

import pytest

from globe.config import Deployment, GlobeConfig
from globe.data.csv_logs import load_household
from globe.evaluation.online import close_day, day_observations, replay
from globe.service.client import household_payload
from globe.session import build_session
from tests.service.conftest import BASE, REPLAY_ENV

pytestmark = [pytest.mark.service, pytest.mark.slow]
TRAIN_DAYS = 15  # enough for 5-fold cross-validation; the selection runs in seconds


def plan(household, first: dt.date):
    """(day name, row, observation) of three test days: from 06:00; from 13:00 with 15:00-16:00
    missing; from 18:00 (rows by the household's step)."""
    step = household.test[0].minutes[1] - household.test[0].minutes[0]

    def row(minute: int) -> int:
        return (minute - 360) // step

    rows = [range(len(household.test[0])),
            [t for t in range(row(13 * 60), len(household.test[1])) if not row(15 * 60) <= t < row(16 * 60)],
            range(row(18 * 60), len(household.test[2]))]
    return [(day.name, t, obs) for i, (day, keep) in enumerate(zip(household.test, rows))
            for t, obs in day_observations(household, day, first + dt.timedelta(days=i), rows=keep)]


def served(srv, name: str, household, steps):
    """Create the household, wait for its selection, then replay ``steps``: (the predictions,
    the scores, the deployment it chose)."""
    with srv.client() as c:
        payload = household_payload(household)
        info = c.create_household(name, payload["nodes"], payload["days"], timezone="UTC")
        assert info["selecting"] is True
        deadline = time.time() + 300
        while c.stats(name)["selecting"]:
            assert time.time() < deadline, "the selection did not end within 5 minutes"
            time.sleep(0.5)
        deployment = Deployment.model_validate(c.export_model(name)["deployment"])
        assert deployment.cross_validated and deployment.method == "routine"
        c.set_shadow(name, False)
        predictions = []
        for _, _, obs in steps:
            c.observe(name, obs.time, obs.activity, obs.locations)
            predictions.append(c.prediction(name))
        return predictions, c.stats(name)["scores"], deployment


@pytest.mark.parametrize("name, step", [("A", 10), ("B", 10), ("C", 10), ("A", 5)])
def test_the_service_serves_what_the_evaluation_scores(make_server, homer_root, name, step):
    h = load_household(homer_root, name, step_minutes=step, resample="locf" if step != 10 else "none")
    h = replace(h, train=h.train[:TRAIN_DAYS], test=h.test[:3])
    steps = plan(h, BASE.date())
    srv = make_server({**REPLAY_ENV, "GLOBE_SELECTION__DEPLOY": "routine"})
    predictions, scores, deployment = served(srv, name, h, steps)

    config = GlobeConfig().with_overrides({"llm.backend": "none"})
    session = build_session(h, config, deployment, None)
    assert session.grid.step_minutes == step
    records, offline = replay(session, steps)
    close_day(session, offline)
    fetched = 0
    for (day, row, _), p, r in zip(steps, predictions, records, strict=True):
        d = r.decision
        assert (p.day, p.step, p.activity, p.activity_probability) == (d.day, d.step, d.activity,
                                                                        d.activity_probability), (day, row)
        assert (p.object, p.object_probability) == (d.choice.obj, d.choice.confidence), (day, row)
        assert [(f.object, f.to, f.probability) for f in p.fetches] == [
            (c.obj, c.to_location, c.probability) for c in d.fetches], (day, row)
        fetched += len(d.fetches)
    assert fetched > 0 and session.days_learned == TRAIN_DAYS + 2  # the first two days were learned
    rows = scores["days"]
    totals = {k: sum(d[k] for d in rows) for k in ("predictions", "correct", "fetches", "useful_fetches", "uses",
                                                     "uses_fetched")}
    f = offline.fetch
    assert totals == {"predictions": offline.predictions, "correct": offline.correct, "fetches": f.fetches,
                      "useful_fetches": f.useful_fetches, "uses": f.used_objects,
                      "uses_fetched": f.used_fetched_in_advance}
    assert offline.predictions > 200 and f.used_objects > 0
