"""``/dashboard``: the household dashboard in the browser (HTML, not part of the OpenAPI schema).

Access uses the API's tokens, never in a URL or a page: the login form exchanges a token for a
session cookie (HttpOnly, SameSite=Strict, signed, expiring; Secure over HTTPS); every form post
carries a CSRF token and, when the browser sends one, an Origin of this very service. The Guard's
Host allow-list applies as to every path; a household token sees its own household only. Every
page is sent with a Content-Security-Policy that allows this service's own script and style only.
"""

from __future__ import annotations

import asyncio
from importlib import resources
from typing import Annotated, Any
from urllib.parse import parse_qs, urlsplit

from fastapi import APIRouter, Depends, Request
from fastapi.responses import HTMLResponse, RedirectResponse, Response
from starlette.exceptions import HTTPException as StarletteHTTPException

from globe.errors import GlobeError
from globe.service import answers, auth
from globe.service.dashboard import views
from globe.service.dashboard.sessions import LOGIN_COOKIE, SESSION_COOKIE, Session, Sessions
from globe.service.deps import RegistryDep
from globe.service.guard import DASHBOARD_FORM_BYTES
from globe.service.registry import Registry

router = APIRouter(include_in_schema=False)

SECURITY_HEADERS = {
    "Content-Security-Policy": "default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self'; "
                               "connect-src 'self'; form-action 'self'; frame-ancestors 'none'; base-uri 'none'",
    "X-Content-Type-Options": "nosniff",
    "X-Frame-Options": "DENY",
    "Referrer-Policy": "same-origin",  # not "no-referrer": Chromium then sends form posts with "Origin: null"
    "Cache-Control": "no-store",
    "Cross-Origin-Opener-Policy": "same-origin",
}
STATIC_TYPES = {".css": "text/css; charset=utf-8", ".js": "text/javascript; charset=utf-8", ".svg": "image/svg+xml"}
STATIC_FILES = frozenset({"dashboard.css", "dashboard.js", "favicon.svg"})  # nothing else is served


def sessions(request: Request) -> Sessions:
    """The app's session signer (made on first use from the secret in the database)."""
    found = getattr(request.app.state, "dashboard_sessions", None)
    if found is None:
        registry: Registry = request.app.state.registry
        found = Sessions.from_store(registry.store, registry.config.service.session_minutes * 60)
        request.app.state.dashboard_sessions = found
    return found


class Viewer:
    """A logged-in browser: its session and who it is."""

    def __init__(self, session: Session, caller: auth.Caller, csrf: str) -> None:
        self.session, self.caller, self.csrf = session, caller, csrf

    def context(self, registry: Registry, **more: Any) -> dict[str, Any]:
        who = "admin" if self.caller.admin else f"household {self.caller.household}"
        return {"who": who, "admin": self.caller.admin, "csrf": self.csrf,
                "refresh_s": registry.config.service.dashboard_refresh_s, **more}


def login_needed() -> StarletteHTTPException:
    """No valid session: the browser is sent to the login page."""
    return StarletteHTTPException(303, "log in first: /dashboard/login", headers={"Location": "/dashboard/login"})


async def viewer(request: Request, registry: RegistryDep) -> Viewer:
    signer = sessions(request)
    session = signer.read(request.cookies.get(SESSION_COOKIE))
    caller = None if session is None else signer.caller(registry.store, session)
    if session is None or caller is None:
        raise login_needed()
    return Viewer(session, caller, signer.csrf(session))


ViewerDep = Annotated[Viewer, Depends(viewer)]


def page(html: str, status: int = 200) -> HTMLResponse:
    return HTMLResponse(html, status_code=status, headers=SECURITY_HEADERS)


def redirect(to: str) -> RedirectResponse:
    return RedirectResponse(to, status_code=303, headers=SECURITY_HEADERS)


def failure(status: int, heading: str, message: str, **context: Any) -> HTMLResponse:
    return page(views.render("error.html", status_code=status, heading=heading, message=message, **context), status)


async def form(request: Request) -> dict[str, str]:
    """The posted urlencoded form (one value per field), after the same-origin check."""
    origin = request.headers.get("origin")
    if origin is not None and urlsplit(origin).netloc.lower() != request.headers.get("host", "").lower():
        raise PermissionError("cross-origin form post refused")
    body = await request.body()
    if len(body) > DASHBOARD_FORM_BYTES:
        raise PermissionError("form too large")
    try:
        return {k: v[0] for k, v in parse_qs(body.decode("utf-8", "replace"), max_num_fields=8).items()}
    except ValueError:  # more fields than any of the dashboard's forms has
        raise PermissionError("malformed form") from None


def _cookie(response: Response, request: Request, name: str, value: str, max_age: int,
            path: str = "/dashboard") -> None:
    response.set_cookie(name, value, max_age=max_age, path=path, httponly=True, samesite="strict",
                        secure=request.url.scheme == "https")


async def _in_thread(fn: Any, *args: Any) -> Any:
    """Pages read under a household's lock: off the event loop."""
    return await asyncio.to_thread(fn, *args)


# -- login and logout --------------------------------------------------------------------------
def _login_page(request: Request, error: str | None = None, status: int = 200) -> HTMLResponse:
    cookie, token = sessions(request).login_pair()
    response = page(views.render("login.html", csrf=token, error=error), status)
    _cookie(response, request, LOGIN_COOKIE, cookie, 600, "/dashboard/login")
    return response


@router.get("/dashboard/login")
async def login_form(request: Request) -> HTMLResponse:
    return _login_page(request)


@router.post("/dashboard/login")
async def login(request: Request, registry: RegistryDep) -> Response:
    signer = sessions(request)
    try:
        fields = await form(request)
    except PermissionError as err:
        return failure(403, "Refused", str(err))
    if not signer.check_login(request.cookies.get(LOGIN_COOKIE), fields.get("csrf")):
        return _login_page(request, "The form expired or did not come from this page: try again.", 403)
    try:
        caller = auth.authenticate(registry.store, f"Bearer {fields.get('token', '').strip()}")
    except GlobeError:
        return _login_page(request, "Unknown or revoked token.", 401)
    response = redirect("/dashboard")
    _cookie(response, request, SESSION_COOKIE, signer.open(caller), signer.lifetime_s)
    response.delete_cookie(LOGIN_COOKIE, path="/dashboard/login")
    return response


@router.post("/dashboard/logout")
async def logout(request: Request, registry: RegistryDep) -> Response:
    signer = sessions(request)
    session = signer.read(request.cookies.get(SESSION_COOKIE))
    try:
        fields = await form(request)
    except PermissionError as err:
        return failure(403, "Refused", str(err))
    if session is not None and not signer.check_csrf(session, fields.get("csrf")):
        return failure(403, "Refused", "the form did not come from this dashboard (CSRF token missing or wrong)")
    if session is not None:
        registry.store.end_session(session.nonce, session.expires)
    response = redirect("/dashboard/login")
    response.delete_cookie(SESSION_COOKIE, path="/dashboard", httponly=True, samesite="strict")
    return response


# -- pages ------------------------------------------------------------------------------------
@router.get("/dashboard")
async def home(request: Request, registry: RegistryDep) -> Response:
    try:
        v = await viewer(request, registry)
    except StarletteHTTPException:
        return redirect("/dashboard/login")
    return redirect("/dashboard/households" if v.caller.admin else f"/dashboard/households/{v.caller.household}")


@router.get("/dashboard/households")
async def households(v: ViewerDep, registry: RegistryDep) -> Response:
    if not v.caller.admin:
        return redirect(f"/dashboard/households/{v.caller.household}")
    lines = await _in_thread(views.household_lines, registry, registry.names())
    return page(views.render("households.html", lines=lines, **v.context(registry)))


def _not_theirs(v: Viewer, registry: Registry, name: str) -> Response | None:
    """The refusal for a login that does not give access to household ``name`` (None: it does)."""
    if v.caller.admin or v.caller.household == name:
        return None
    return failure(403, "Not yours", f"this login does not give access to household {name!r}", **v.context(registry))


async def _household_page(v: Viewer, registry: Registry, name: str, template: str, read: Any,
                          page_name: str) -> Response:
    if (refused := _not_theirs(v, registry, name)) is not None:
        return refused
    try:
        data = await _in_thread(read, registry, name)
    except GlobeError as err:
        return failure(err.http_status, "Unavailable", str(err), **v.context(registry))
    return page(views.render(template, page=page_name, **data, **v.context(registry)))


@router.get("/dashboard/households/{name}")
async def today(name: str, v: ViewerDep, registry: RegistryDep) -> Response:
    return await _household_page(v, registry, name, "today.html", views.today, "today")


@router.get("/dashboard/households/{name}/live")
async def today_live(name: str, v: ViewerDep, registry: RegistryDep) -> Response:
    """The live part of the today page, swapped in by the page's script."""
    return await _household_page(v, registry, name, "_today_live.html", views.today, "today")


@router.get("/dashboard/households/{name}/routine")
async def routine(name: str, v: ViewerDep, registry: RegistryDep) -> Response:
    return await _household_page(v, registry, name, "routine.html", views.routine, "routine")


@router.get("/dashboard/households/{name}/settings")
async def settings(name: str, v: ViewerDep, registry: RegistryDep) -> Response:
    return await _household_page(v, registry, name, "settings.html", views.settings, "settings")


async def _form_of_this_dashboard(request: Request, v: Viewer, registry: Registry) -> dict[str, str] | Response:
    """A logged-in page's form fields, or the refusal of a form too big or not from this dashboard
    (its CSRF token missing or wrong)."""
    try:
        fields = await form(request)
    except PermissionError as err:
        return failure(403, "Refused", str(err), **v.context(registry))
    if not sessions(request).check_csrf(v.session, fields.get("csrf")):
        return failure(403, "Refused", "the form did not come from this dashboard (CSRF token missing or wrong)",
                       **v.context(registry))
    return fields


@router.post("/dashboard/households/{name}/shadow")
async def shadow(name: str, request: Request, v: ViewerDep, registry: RegistryDep) -> Response:
    fields = await _form_of_this_dashboard(request, v, registry)
    if isinstance(fields, Response):
        return fields
    if not v.caller.admin:
        return failure(403, "Admins only", "only an admin token switches shadow mode", **v.context(registry))
    if fields.get("shadow") not in ("on", "off"):
        return failure(422, "Bad form", "shadow must be 'on' or 'off'", **v.context(registry))
    if fields["shadow"] == "off" and fields.get("confirm") != "yes":  # letting the robot act is never one stray click
        return failure(422, "Not confirmed", "tick the box saying the scores were looked at, then switch shadow mode "
                       "off", **v.context(registry))
    try:
        await _in_thread(registry.set_shadow, name, fields["shadow"] == "on")
    except GlobeError as err:
        return failure(err.http_status, "Unavailable", str(err), **v.context(registry))
    return redirect(f"/dashboard/households/{name}/settings")


@router.post("/dashboard/households/{name}/answer")
async def answer(name: str, request: Request, v: ViewerDep, registry: RegistryDep) -> Response:
    """The person's answer to "what are you doing?" from the Today page: the label of the step
    the page showed, while it is still under way (:func:`globe.service.answers.answer`)."""
    fields = await _form_of_this_dashboard(request, v, registry)
    if isinstance(fields, Response):
        return fields
    if (refused := _not_theirs(v, registry, name)) is not None:
        return refused
    activity = fields.get("activity") or fields.get("other") or ""
    try:
        step = (fields["day"], int(fields["step"]))
    except (KeyError, ValueError):
        return failure(422, "Bad form", "the answer names no step (day and step)", **v.context(registry))
    if not activity.strip():
        return failure(422, "Bad form", "choose an activity", **v.context(registry))
    try:
        await _in_thread(lambda: answers.answer(registry, name, activity, step=step))
    except GlobeError as err:
        return failure(err.http_status, "Not taken", str(err), **v.context(registry))
    return redirect(f"/dashboard/households/{name}")


@router.get("/dashboard/static/{file}")
async def static(file: str) -> Response:
    """The dashboard's own script, style sheet and icon (shipped in the package)."""
    if file not in STATIC_FILES:  # a fixed list: no name from the request reaches the file system
        return Response("not found", status_code=404, media_type="text/plain")
    suffix = file[file.rfind("."):]
    body = resources.files("globe.service.dashboard").joinpath("static", file).read_bytes()
    return Response(body, media_type=STATIC_TYPES[suffix],
                    headers={"Cache-Control": "max-age=300", "X-Content-Type-Options": "nosniff"})
