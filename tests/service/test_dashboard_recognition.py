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


def _form(html: str) -> dict[str, str]:
    card = html[html.index('id="asking"'):]
    card = card[:card.index("</form>")]
    return dict(re.findall(r'<input type="hidden" name="(\w+)" value="([^"]*)">', card))


def test_an_answer_on_the_today_page_labels_the_step_under_way_once_and_never_a_left_one(sensed):
    db, member, day = sensed
    admin = tokens(db)[0]
    home = sensor_home(days=6, test=2, step=10)
    steps = observations(home, day, BASE, 13)
    with app_client(db, admin) as c:
        assert c.post("/households", json=create_body(home, "Q")).status_code == 201
        for obs in steps[:12]:
            assert c.post("/households/Q/observations", json=obs).status_code == 201
    with app_client(db) as browser:
        assert login(browser, admin).status_code == 303
        html = browser.get("/dashboard/households/Q").text
        form = _form(html)
        assert form["step"] == "11" and "What are you doing?" in html
        assert re.search(r'<select name="other"[^>]*>(<option value="\w+">[\w ]+</option>)+</select>', html)
        said = {**form, "activity": "", "other": day.activities[11]}
        assert browser.post("/dashboard/households/Q/answer", data=said, follow_redirects=False).status_code == 303
        after = browser.get("/dashboard/households/Q").text
        assert re.search(r'Steps labelled</span><span class="value">1<', after)
        first = re.search(r'<tbody>\s*<tr><td class="time">[^<]*</td><td>([^<]*)</td>', after)
        assert first and first[1] == day.activities[11].replace("_", " ")
        again = browser.post("/dashboard/households/Q/answer", data=said, follow_redirects=False)  # a second tap
        assert again.status_code == 303
        forged = browser.post("/dashboard/households/Q/answer", data={**said, "csrf": "x"}, follow_redirects=False)
        assert forged.status_code == 403
    with app_client(db, admin) as c:
        assert c.get("/households/Q/stats").json()["observations"] == 13  # 12 steps and one answer
        assert c.post("/households/Q/observations", json=steps[12]).status_code == 201
    with app_client(db) as browser:
        assert login(browser, admin).status_code == 303
        fresh = _form(browser.get("/dashboard/households/Q").text)
        assert fresh["step"] == "12"
        late = browser.post("/dashboard/households/Q/answer", data={**said, "csrf": fresh["csrf"]},  # the old step
                            follow_redirects=False)
        assert late.status_code == 422 and "came after the step it answers" in late.text
        assert login(browser, member["S"]).status_code == 303
        other = browser.post("/dashboard/households/Q/answer", data={**said, "csrf": _form(
            browser.get("/dashboard/households/S").text)["csrf"]}, follow_redirects=False)
        assert other.status_code == 403 and "does not give access" in other.text
