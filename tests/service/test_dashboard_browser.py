"""The dashboard in a real browser: headless Chromium (Debian's ``chromium`` and
``chromium-driver``) driven by selenium against a real ``globe serve`` process. Log in, open the
household, see the timeline and the forecast, watch the live part refresh without a reload, log
out; a wrong token refused; no console error on any page. Screenshots of every page at a desktop
and a phone width go to ``results/test-run/screenshots/`` (or ``$GLOBE_TEST_RESULTS/screenshots``)."""

from __future__ import annotations

import datetime as dt
import time

import pytest

from tests.helpers import require_system, results_folder
from tests.service.conftest import REPLAY_ENV

pytestmark = pytest.mark.service

DESKTOP, PHONE = (1366, 900), (390, 844)
BASE = dt.datetime.combine(dt.date.today() - dt.timedelta(days=3), dt.time())


def _post(client, h, day, index, steps, predict=True):
    for t in range(steps):
        client.observe("A", BASE + dt.timedelta(days=index, minutes=day.minutes[t]), day.activities[t],
                       dict(zip(h.objects, day.locations[t])))
        if predict:
            client.prediction("A")


@pytest.fixture(scope="module")
def service(tmp_path_factory, households):
    """A real service with household A: a test day observed in full, and today's first 13 steps."""
    from tests.service_process import Server

    require_system("chromium", "chromedriver", install="Debian's chromium and chromium-driver (apt-get install "
                                                       "chromium chromium-driver)")
    tmp = tmp_path_factory.mktemp("browser")
    srv = Server(tmp / "globe.sqlite3", tmp / "server.log", {**REPLAY_ENV, "GLOBE_SERVICE__DASHBOARD_REFRESH_S": "1"})
    srv.start()
    h = households["A"]
    from tests.service.conftest import upload

    with srv.client() as c:
        upload(c, "A", h)
        _post(c, h, h.test[0], 0, len(h.test[0]))
        _post(c, h, h.test[1], 1, 13)
    srv.member = srv.token("A")
    yield srv
    srv.stop()


@pytest.fixture(scope="module")
def driver(service):
    pytest.importorskip("selenium", reason="selenium is not installed: pip install -e '.[dev]'")
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = "/usr/bin/chromium"
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--no-first-run",
                "--disable-extensions", f"--window-size={DESKTOP[0]},{DESKTOP[1]}"):
        options.add_argument(arg)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    d = webdriver.Chrome(options=options, service=Service("/usr/bin/chromedriver"))
    d.set_page_load_timeout(20)
    yield d
    d.quit()


def no_console_errors(driver) -> None:
    severe = [e for e in driver.get_log("browser") if e["level"] == "SEVERE"]
    assert not severe, severe


FITS = """
const wide = document.documentElement.scrollWidth > window.innerWidth + 1;
const boxes = [...document.querySelectorAll('.chartbox, .scroll, table, svg.chart')]
  .filter(e => e.offsetParent !== null && e.scrollWidth > e.clientWidth + 1)
  .map(e => e.className.baseVal ?? e.className);
const now = [...document.querySelectorAll('svg .now')].filter(e => e.getBoundingClientRect().width > 0)
  .map(e => { const r = e.getBoundingClientRect(); return [r.left, r.right]; });
return [wide, boxes, now, window.innerWidth];
"""


def shoot(driver, name: str) -> None:
    """Screenshots of the whole page at both widths (the window grows to the page's height), each
    checked to fit: no sideways scrolling, the page's or any chart's or table's, and "now", where
    the page marks it, inside the window."""
    folder = results_folder("screenshots")
    for label, (w, h) in (("desktop", DESKTOP), ("phone", PHONE)):
        driver.set_window_size(w, h)
        time.sleep(0.15)
        wide, boxes, now, width = driver.execute_script(FITS)
        assert not wide and not boxes, (name, label, wide, boxes)
        assert all(0 <= left and right <= width for left, right in now), (name, label, now)
        if name == "today":
            assert len(now) == 1, (label, now)  # one chart shown at each width, "now" on it
        height = driver.execute_script("return document.documentElement.scrollHeight")
        driver.set_window_size(w, max(h, min(int(height) + 140, 5000)))
        time.sleep(0.15)
        driver.save_screenshot(str(folder / f"{name}-{label}.png"))
    driver.set_window_size(*DESKTOP)


def log_in(driver, url: str, token: str) -> None:
    from selenium.webdriver.common.by import By

    driver.get(url + "/dashboard")
    driver.delete_all_cookies()  # each test starts logged out, whatever the one before left
    driver.get(url + "/dashboard")
    assert driver.current_url.endswith("/dashboard/login")
    driver.find_element(By.ID, "token").send_keys(token)
    driver.find_element(By.ID, "login").click()


def test_a_wrong_token_is_refused(driver, service):
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support import expected_conditions as ec
    from selenium.webdriver.support.ui import WebDriverWait

    log_in(driver, service.url, "globe_wrong-token")
    # the click returns before the refused form's page has loaded on a busy machine: wait for it
    error = WebDriverWait(driver, 10).until(ec.presence_of_element_located((By.ID, "login-error")))
    assert "Unknown or revoked token" in error.text
    assert driver.current_url.endswith("/dashboard/login")
    assert not driver.get_cookies() or all(c["name"] != "globe_session" for c in driver.get_cookies())
    shoot(driver, "login")
    # the refused login is a 401 page, which Chromium logs as a failed resource: the only error allowed
    errors = [e for e in driver.get_log("browser") if e["level"] == "SEVERE" and "401" not in e["message"]]
    assert not errors, errors


def test_log_in_see_the_day_and_the_next_hour_then_log_out(driver, service):
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support import expected_conditions as ec
    from selenium.webdriver.support.ui import WebDriverWait

    log_in(driver, service.url, service.admin)
    WebDriverWait(driver, 10).until(ec.url_contains("/dashboard/households"))
    assert driver.find_element(By.ID, "households").text.startswith("Name")
    no_console_errors(driver)
    shoot(driver, "households")
    session = next(c for c in driver.get_cookies() if c["name"] == "globe_session")
    assert session["httpOnly"] and session["sameSite"] == "Strict" and service.admin not in session["value"]
    assert "globe_session" not in driver.execute_script("return document.cookie")  # out of a script's reach
    assert service.admin not in driver.page_source

    driver.find_element(By.LINK_TEXT, "A").click()
    WebDriverWait(driver, 10).until(ec.presence_of_element_located((By.CSS_SELECTOR, "#timeline svg")))
    timeline = driver.find_element(By.ID, "timeline")
    assert "observed" in timeline.text and "predicted" in timeline.text
    assert len(driver.find_elements(By.CSS_SELECTOR, "#recent-steps tbody tr")) == 12
    forecast = driver.find_element(By.ID, "next-hour")
    assert "Robot takes it to" in forecast.text and forecast.find_elements(By.CSS_SELECTOR, "svg.bars")
    assert driver.find_element(By.ID, "fetches").find_elements(By.CSS_SELECTOR, "tbody tr")
    no_console_errors(driver)
    shoot(driver, "today")

    for page in ("routine", "settings"):
        driver.find_element(By.LINK_TEXT, page.capitalize()).click()
        WebDriverWait(driver, 10).until(ec.url_contains(f"/A/{page}"))
        assert driver.find_element(By.ID, "actogram" if page == "routine" else "shadow").is_displayed()
        no_console_errors(driver)
        shoot(driver, page)

    driver.find_element(By.ID, "logout").click()
    WebDriverWait(driver, 10).until(ec.url_contains("/dashboard/login"))
    driver.get(service.url + "/dashboard/households/A")
    assert driver.current_url.endswith("/dashboard/login")  # the session is gone
    no_console_errors(driver)


def test_the_live_part_refreshes_without_reloading_the_page(driver, service, households):
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import WebDriverWait

    log_in(driver, service.url, service.member)
    WebDriverWait(driver, 10).until(lambda d: d.current_url.endswith("/dashboard/households/A"))
    driver.execute_script("window.loadedOnce = 42;")  # gone if the page were reloaded
    first = driver.find_element(By.CSS_SELECTOR, "#recent-steps tbody tr td").text
    h = households["A"]
    with service.client() as c:  # the robot observes the next step while the page is open
        day = h.test[1]
        c.observe("A", BASE + dt.timedelta(days=1, minutes=day.minutes[13]), day.activities[13],
                  dict(zip(h.objects, day.locations[13])))
    WebDriverWait(driver, 20).until(  # the page refreshes every second (GLOBE_SERVICE__DASHBOARD_REFRESH_S=1)
        lambda d: d.find_element(By.CSS_SELECTOR, "#recent-steps tbody tr td").text != first,
        message=f"the live part still shows {first}")
    assert driver.execute_script("return window.loadedOnce") == 42
    assert "household A" in driver.find_element(By.CLASS_NAME, "who").text
    no_console_errors(driver)


def test_a_household_with_sensors_shows_recognition_and_fits_a_phone(driver, service):
    """The recognised lane, the recognised column, today's counts and the answer card still fit a
    390 px phone, and an answer chosen there labels the step under way."""
    import httpx
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support import expected_conditions as ec
    from selenium.webdriver.support.ui import WebDriverWait

    from tests.service.test_sensor_households import create_body, observations
    from tests.simulated_sensors import sensor_home

    home = sensor_home(days=6, test=2, step=10)
    day = home[0].test[0]
    auth = {"Authorization": f"Bearer {service.admin}"}
    r = httpx.post(service.url + "/households", json=create_body(home), headers=auth, timeout=60)
    assert r.status_code == 201, r.text
    for t, obs in enumerate(observations(home, day, BASE + dt.timedelta(days=2), 20)):
        body = {**obs, "activity": day.activities[t]} if t % 4 == 0 else obs
        assert httpx.post(service.url + "/households/S/observations", json=body, headers=auth).status_code == 201
    log_in(driver, service.url, service.admin)
    WebDriverWait(driver, 10).until(ec.url_contains("/dashboard/households"))
    driver.get(service.url + "/dashboard/households/S")
    WebDriverWait(driver, 10).until(ec.presence_of_element_located((By.ID, "recognition")))
    assert "Steps recognised" in driver.find_element(By.ID, "recognition").text
    assert "Sensors" in driver.find_element(By.ID, "recent-steps").text
    no_console_errors(driver)
    shoot(driver, "today-sensors")  # the "what are you doing?" card fits too
    # answering from the page: the step under way gets the label, today's labelled count goes up.
    # The live part is redrawn every second here, so an element may be replaced between two reads
    # (in Chromium an error of its own, not always a stale element): each read is retried.
    from selenium.common.exceptions import WebDriverException
    from selenium.webdriver.support.ui import Select

    patient = WebDriverWait(driver, 10, ignored_exceptions=(WebDriverException,))

    def labelled(d) -> str:
        return d.find_element(By.CSS_SELECTOR, "#recognition .tile .value").text
    before = int(patient.until(labelled))

    def answer(d) -> bool:  # a second tap on the same step counts once, so a retried tap is harmless
        card = d.find_element(By.ID, "asking")
        assert "What are you doing?" in card.text
        Select(card.find_element(By.NAME, "other")).select_by_value(day.activities[19])  # step 19: no label
        card.find_element(By.CSS_SELECTOR, "button.secondary").click()
        return True
    patient.until(answer)
    patient.until(lambda d: labelled(d) == str(before + 1))
    patient.until(lambda d: d.find_element(By.CSS_SELECTOR, "#recent-steps tbody tr td:nth-child(2)").text
                  == day.activities[19].replace("_", " "))
    no_console_errors(driver)
