"""The Today page of a household with sensors: per step, the activity recognised from the sensors
beside the annotated one (its own label left out) and alone where no label came, in the timeline
and the table of recent steps, with today's labelled, recognised and asked counts."""

from __future__ import annotations

import re

import pytest

from tests.service.dashboard_helpers import BASE, app_client, login, tokens
from tests.service.test_sensor_households import create_body, observations
from tests.simulated_sensors import sensor_home

pytestmark = pytest.mark.service
STEPS = 30


@pytest.fixture(scope="module")
def sensed(tmp_path_factory):
    """Household S (sensors, 4 training days at 10-minute steps) with 30 steps of a test day
    observed with their sensor activations, every third one labelled."""
    home = sensor_home(days=6, test=2, step=10)
    db = tmp_path_factory.mktemp("recognition") / "globe.sqlite3"
    admin, member = tokens(db, "S")
    h, _ = home
    day = h.test[0]
    with app_client(db, admin) as c:
        assert c.post("/households", json=create_body(home)).status_code == 201
        for t, obs in enumerate(observations(home, day, BASE, STEPS)):
            body = {**obs, "activity": day.activities[t]} if t % 3 == 0 else obs
            assert c.post("/households/S/observations", json=body).status_code == 201
            c.get("/households/S/prediction")
    return db, member, day


def test_the_today_page_shows_recognised_beside_annotated_and_the_days_counts(sensed):
    db, member, day = sensed
    with app_client(db) as browser:
        assert login(browser, member["S"]).status_code == 303
        html = browser.get("/dashboard/households/S").text
    labelled = len(range(0, STEPS, 3))
    counts = re.search(r'id="recognition".*?Steps labelled</span><span class="value">(\d+)<.*?Steps recognised'
                       r'</span><span class="value">(\d+)<.*?Questions asked</span><span class="value">(\d+)<', html,
                       re.S)
    assert counts and (int(counts[1]), int(counts[2])) == (labelled, STEPS - labelled), counts
    # every step has its recognition, in the chart for a desktop and in the one for a phone
    recognised = re.findall(r"<title>(\d\d:\d\d) recognised (\w+) \(p = ", html)
    assert len(recognised) == 2 * STEPS
    right = sum(a == day.activities[t] for t, (_, a) in enumerate(recognised[:STEPS]))
    assert right >= 0.6 * STEPS, recognised
    assert ">Sensors</th>" in html
    table = html[html.index('id="recent-steps"'):]
    rows = re.findall(r'<tr><td class="time">.*?</tr>', table[:table.index("</table>")], re.S)
    assert len(rows) == 12 and all('class="recognised">' in r for r in rows)
    both = [r for r in rows if not re.search(r'<td class="time">[^<]*</td><td>–</td>', r)]
    assert len(both) == sum(t % 3 == 0 for t in range(STEPS - 12, STEPS))  # labelled: the label and the sensors' read
    assert all(re.search(r'class="recognised">\w[\w ]*<span class="small opt"> \d\.\d\d<', r) for r in both)


def test_a_household_without_sensors_shows_no_recognition(sensed, households):
    from tests.service.dashboard_helpers import create, observe_days

    db, member, _ = sensed
    admin = tokens(db)[0]
    with app_client(db, admin) as c:
        create(c, "plain", households["B"])
        observe_days(c, "plain", households["B"], households["B"].test[:1], steps=5)
    with app_client(db) as browser:
        assert login(browser, admin).status_code == 303
        html = browser.get("/dashboard/households/plain").text
    assert 'id="recognition"' not in html and "Sensors</th>" not in html and " recognised " not in html
    assert len(re.findall(r"<title>\d\d:\d\d observed ", html)) == 2 * 5
