"""The dashboard in-process over a real database: login and logout, the session cookie's flags,
CSRF refusals, household isolation, no token in any page, the pages' content and headers."""

import re

import pytest

from globe.service.auth import Caller
from globe.service.client import household_payload
from globe.service.dashboard.sessions import SESSION_COOKIE, Sessions
from tests.service.dashboard_helpers import app_client, create, csrf_of, login, observe_days, tokens

pytestmark = pytest.mark.service


@pytest.fixture(scope="module")
def home(tmp_path_factory, households):
    """Household A (65 training days) with a day and two hours observed, and B with its map only."""
    db = tmp_path_factory.mktemp("dashboard") / "globe.sqlite3"
    admin, member = tokens(db, "A", "B")
    with app_client(db, admin) as c:
        create(c, "A", households["A"])
        create(c, "B", households["B"])
        payload = household_payload(households["C"])
        body = {"name": "C", "timezone": "Europe/Paris", "nodes": payload["nodes"]}
        assert c.post("/households", json=body).status_code == 201
        observe_days(c, "A", households["A"], households["A"].test[:2], steps=13)  # to 08:00, before breakfast
    return db, admin, member


@pytest.fixture()
def browser(home):
    db = home[0]
    with app_client(db) as c:  # no Authorization header: a browser
        yield c


def test_login_exchanges_the_token_for_a_hardened_session_cookie(browser, home):
    _, admin, member = home
    r = login(browser, member["A"])
    assert r.status_code == 303 and r.headers["location"] == "/dashboard"
    cookie = next(h for h in r.headers.get_list("set-cookie") if h.startswith(SESSION_COOKIE + "="))
    flags = {f.strip().split("=")[0].lower() for f in cookie.split(";")[1:]}
    assert {"httponly", "max-age", "path"} <= flags and "samesite=strict" in cookie.lower()
    assert member["A"] not in cookie and member["A"][6:] not in cookie
    assert browser.get("/dashboard").headers["location"] == "/dashboard/households/A"
    page = browser.get("/dashboard/households/A")
    assert page.status_code == 200 and "<svg" in page.text and 'id="timeline"' in page.text


def test_a_wrong_token_is_refused_and_opens_no_session(browser):
    r = login(browser, "globe_not-a-real-token")
    assert r.status_code == 401 and "Unknown or revoked token" in r.text
    assert not any(h.startswith(SESSION_COOKIE) for h in r.headers.get_list("set-cookie"))
    assert browser.get("/dashboard/households/A").headers["location"] == "/dashboard/login"


def test_a_login_post_without_its_csrf_token_or_from_another_origin_is_refused(browser, home):
    browser.get("/dashboard/login")
    r = browser.post("/dashboard/login", data={"token": home[2]["A"], "csrf": "forged"})
    assert r.status_code == 403 and SESSION_COOKIE not in r.headers.get("set-cookie", "")
    form = browser.get("/dashboard/login")
    r = browser.post("/dashboard/login", data={"token": home[2]["A"], "csrf": csrf_of(form.text)},
                     headers={"Origin": "http://evil.example"})
    assert r.status_code == 403 and SESSION_COOKIE not in r.headers.get("set-cookie", "")


def test_pages_carry_security_headers_and_never_a_token(browser, home):
    _, admin, member = home
    assert login(browser, admin).status_code == 303
    pages = ["/dashboard/households", "/dashboard/households/A", "/dashboard/households/A/live",
             "/dashboard/households/A/routine", "/dashboard/households/A/settings", "/dashboard/households/B"]
    for path in pages:
        r = browser.get(path)
        assert r.status_code == 200, (path, r.text[:500])
        csp = r.headers["content-security-policy"]
        assert "script-src 'self'" in csp and "unsafe-eval" not in csp and "unsafe-inline" not in csp
        assert r.headers["x-frame-options"] == "DENY" and r.headers["cache-control"] == "no-store"
        for token in (admin, *member.values()):
            assert token not in r.text and token[6:] not in r.text
        assert "<script>" not in r.text and " style=" not in r.text  # no inline script or style (the CSP forbids them)
        assert "http://" not in r.text and "https://" not in r.text  # nothing fetched from elsewhere
    listed = browser.get("/dashboard/households").text
    assert 'href="/dashboard/households/A"' in listed and 'href="/dashboard/households/B"' in listed


def test_the_today_page_shows_the_timeline_the_next_hour_and_the_scores(browser, home):
    assert login(browser, home[2]["A"]).status_code == 303
    html = browser.get("/dashboard/households/A").text
    assert "ready" in html and re.search(r'id="days-learned">66<', html)  # 65 training days + the first test day
    # every step of today's 13 but the first, in the chart for a desktop and in the one for a phone
    assert len(re.findall(r"<title>\d\d:\d\d predicted ", html)) == 2 * 12
    assert html.count('<g class="now">') == 2
    assert "Robot takes it to" in html and "fetch now" in html  # a forecast for the coming hour
    assert 'id="recent-steps"' in html and "shadow" in html  # a new household is in shadow mode
    assert "Activity accuracy, 1 step ahead" in html and re.search(r"\d+%", html)
    routine = browser.get("/dashboard/households/A/routine").text
    assert "The last 28 days" in routine and routine.count("<rect") > 28
    settings = browser.get("/dashboard/households/A/settings").text
    assert "Activity model" in settings and "kind" in settings and 'id="shadow-toggle"' not in settings  # not an admin


def test_a_household_still_learning_has_every_page(browser, home):
    """A cold start (a map, no day learned yet): no prediction, no forecast, nothing to score."""
    assert login(browser, home[1]).status_code == 303
    html = browser.get("/dashboard/households/C").text
    assert "learning" in html and "No observation yet today" in html and "still learning this home" in html
    for page in ("routine", "settings"):
        assert browser.get(f"/dashboard/households/C/{page}").status_code == 200


def test_a_household_token_sees_only_its_household(browser, home):
    assert login(browser, home[2]["A"]).status_code == 303
    for path in ("/dashboard/households/B", "/dashboard/households/B/live", "/dashboard/households/B/routine",
                 "/dashboard/households/B/settings"):
        r = browser.get(path)
        assert r.status_code == 403 and "does not give access to household" in r.text
        assert 'id="timeline"' not in r.text and 'id="actogram"' not in r.text
    assert browser.get("/dashboard/households").headers["location"] == "/dashboard/households/A"


def test_the_api_bearer_header_does_not_open_the_dashboard_and_the_host_list_applies(home):
    db, admin, _ = home
    with app_client(db, admin) as c:
        assert c.get("/dashboard/households/A").headers["location"] == "/dashboard/login"
        assert c.get("/dashboard/login", headers={"Host": "evil.example"}).status_code == 400


def test_shadow_switches_from_the_dashboard_with_csrf_and_admin_only(browser, home):
    db, admin, member = home
    assert login(browser, member["A"]).status_code == 303
    csrf = csrf_of(browser.get("/dashboard/households/A/settings").text)
    refused = browser.post("/dashboard/households/A/shadow", data={"csrf": csrf, "shadow": "off"})
    assert refused.status_code == 403 and "admin" in refused.text
    browser.cookies.clear()
    assert login(browser, admin).status_code == 303
    settings = browser.get("/dashboard/households/A/settings").text
    assert 'id="shadow-toggle"' in settings
    assert browser.post("/dashboard/households/A/shadow", data={"csrf": "forged", "shadow": "off"}).status_code == 403
    unconfirmed = browser.post("/dashboard/households/A/shadow", data={"csrf": csrf_of(settings), "shadow": "off"})
    assert unconfirmed.status_code == 422 and "tick the box" in unconfirmed.text
    with app_client(db, admin) as api:
        assert api.get("/households/A/stats").json()["shadow"] is True
    confirmed = {"csrf": csrf_of(settings), "shadow": "off", "confirm": "yes"}
    r = browser.post("/dashboard/households/A/shadow", data=confirmed)
    assert r.status_code == 303
    with app_client(db, admin) as api:
        assert api.get("/households/A/stats").json()["shadow"] is False
        assert api.put("/households/A/shadow", json={"shadow": True}).json() == {"household": "A", "shadow": True}


def test_logout_ends_the_session_and_needs_the_csrf_token(browser, home):
    assert login(browser, home[1]).status_code == 303
    copied = browser.cookies.get(SESSION_COOKIE)  # a copy of the cookie, kept elsewhere
    csrf = csrf_of(browser.get("/dashboard/households").text)
    assert browser.post("/dashboard/logout", data={"csrf": "forged"}).status_code == 403
    r = browser.post("/dashboard/logout", data={"csrf": csrf})
    assert r.status_code == 303 and r.headers["location"] == "/dashboard/login"
    cookies = r.headers.get_list("set-cookie")
    assert any(h.startswith(SESSION_COOKIE + '=""') and "max-age=0" in h.lower() for h in cookies)
    assert browser.get("/dashboard/households").headers["location"] == "/dashboard/login"
    # the copy ends with the session (it stayed valid for the session's 8 hours)
    browser.cookies.set(SESSION_COOKIE, copied)
    again = browser.get("/dashboard/households")
    assert again.status_code == 303 and again.headers["location"] == "/dashboard/login"


def test_sessions_are_signed_expire_and_end_with_their_token(tmp_path):
    from globe.service.auth import issue, revoke
    from globe.service.store import Store

    store = Store(tmp_path / "s.sqlite3")
    token, token_id = issue(store, household="A")
    signer = Sessions(b"k" * 32, 60)
    value = signer.open(Caller(token_id, "A", False), now=1000.0)
    assert signer.read(value, now=1010.0) is not None
    assert signer.read(value, now=1061.0) is None  # expired
    assert Sessions(b"x" * 32, 60).read(value, now=1010.0) is None  # another server's secret
    body, mac = value.split(".")
    assert signer.read(body[:-2] + "AA." + mac, now=1010.0) is None  # tampered
    session = signer.read(value, now=1010.0)
    assert signer.caller(store, session) == Caller(token_id, "A", False)
    assert signer.check_csrf(session, signer.csrf(session)) and not signer.check_csrf(session, "x")
    revoke(store, token)
    assert signer.caller(store, session) is None  # a revoked token ends its sessions
    store.close()


def test_the_static_files_are_served_from_the_package(browser):
    js = browser.get("/dashboard/static/dashboard.js")
    assert js.status_code == 200 and js.headers["content-type"].startswith("text/javascript") and "fetch(" in js.text
    assert browser.get("/dashboard/static/dashboard.css").status_code == 200
    assert browser.get("/dashboard/static/..%2Fviews.py").status_code == 404
    assert browser.get("/dashboard/static/views.py").status_code == 404


def test_dashboard_paths_are_not_in_the_openapi_schema(browser):
    paths = browser.get("/openapi.json").json()["paths"]
    assert "/households/{name}/shadow" in paths and not any(p.startswith("/dashboard") for p in paths)


def test_hostile_forms_cookies_and_names_get_a_refusal_never_a_500(browser, home):
    """Non-ASCII CSRF values and cookies, a form with too many fields, odd static names, a large
    unauthenticated body and other methods: each is refused in its own words (found in review)."""
    form = browser.get("/dashboard/login")
    origin = {"Origin": "http://127.0.0.1"}
    refused = browser.post("/dashboard/login", data={"csrf": "é", "token": home[2]["A"]}, headers=origin)
    assert refused.status_code == 403
    many = {f"f{i}": "x" for i in range(9)} | {"csrf": csrf_of(form.text)}
    assert browser.post("/dashboard/login", data=many, headers=origin).status_code == 403
    latin = {"Cookie": SESSION_COOKIE.encode() + b"=\xe9.\xe9"}  # a byte no token or signature has
    assert browser.get("/dashboard/households/A", headers=latin).status_code == 303  # log in again
    for name in ("a%00.css", "x" * 300 + ".css", "..%2Fstore.py", "dashboard.html"):
        assert browser.get(f"/dashboard/static/{name}").status_code == 404, name
    big = browser.post("/dashboard/login", content=b"token=" + b"x" * 20_000,
                       headers=origin | {"Content-Type": "application/x-www-form-urlencoded"})
    assert big.status_code == 413  # refused by its declared length: nothing buffered
    assert browser.put("/dashboard/login", content=b"x").status_code == 405
