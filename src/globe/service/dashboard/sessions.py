"""Dashboard sessions and CSRF tokens, signed with a server secret (HMAC-SHA256, stdlib only).

A session cookie names the token it was opened with by its id (never the token itself) and
expires; every request looks the token up again, so revoking a token ends its sessions at once,
and a logged-out session is noted in the database until it would have expired.
A form carries a CSRF token: for the login form, the signature of a random value also sent as a
cookie (double submit); once logged in, the signature of the session's own random nonce.
"""

from __future__ import annotations

import base64
import hashlib
import hmac
import secrets
import time
from dataclasses import dataclass

from globe.service import auth
from globe.service.store import Store

SESSION_COOKIE = "globe_session"
LOGIN_COOKIE = "globe_login"
SECRET_KEY = "dashboard_session_secret"


def _b64(data: bytes) -> str:
    return base64.urlsafe_b64encode(data).decode("ascii").rstrip("=")


def _unb64(text: str) -> bytes:
    return base64.urlsafe_b64decode(text + "=" * (-len(text) % 4))


@dataclass(frozen=True, slots=True)
class Session:
    token_id: str
    expires: int  # Unix time
    nonce: str


class Sessions:
    """Signs and reads session cookies and CSRF tokens with the service's secret (kept in its
    database, so sessions outlive a restart, and made once per database)."""

    def __init__(self, secret: bytes, lifetime_s: int) -> None:
        self._secret = secret
        self.lifetime_s = lifetime_s

    @classmethod
    def from_store(cls, store: Store, lifetime_s: int) -> "Sessions":
        return cls(bytes.fromhex(store.secret(SECRET_KEY, lambda: secrets.token_hex(32))), lifetime_s)

    def _sign(self, purpose: str, text: str) -> str:
        return _b64(hmac.new(self._secret, f"{purpose}|{text}".encode(), hashlib.sha256).digest())

    # -- sessions --------------------------------------------------------------------------------
    def open(self, caller: auth.Caller, now: float | None = None) -> str:
        """The cookie value of a new session for ``caller``."""
        expires = int((time.time() if now is None else now) + self.lifetime_s)
        body = _b64(f"{caller.token_id}|{expires}|{secrets.token_urlsafe(16)}".encode())
        return f"{body}.{self._sign('session', body)}"

    def read(self, value: str | None, now: float | None = None) -> Session | None:
        """The session a cookie value carries, or None (missing, forged, malformed or expired)."""
        if not value or value.count(".") != 1 or len(value) > 512:
            return None
        body, mac = value.split(".")
        if not _same(mac, self._sign("session", body)):
            return None
        try:
            token_id, expires, nonce = _unb64(body).decode().split("|")
            expiry = int(expires)
        except (ValueError, UnicodeDecodeError):
            return None
        if expiry < (time.time() if now is None else now):
            return None
        return Session(token_id, expiry, nonce)

    def caller(self, store: Store, session: Session) -> auth.Caller | None:
        """Who the session is for, if its token still exists and is not revoked, and the session
        was not logged out (a copy of its cookie ends with it)."""
        if store.session_ended(session.nonce):
            return None
        row = store.token_by_id(session.token_id)
        if row is None or row.revoked_at is not None:
            return None
        return auth.Caller(row.id, row.household, row.admin)

    # -- CSRF ------------------------------------------------------------------------------------
    def csrf(self, session: Session) -> str:
        """The CSRF token of the forms a session posts."""
        return self._sign("csrf", session.nonce)

    def check_csrf(self, session: Session, sent: str | None) -> bool:
        return bool(sent) and _same(str(sent), self.csrf(session))

    def login_pair(self) -> tuple[str, str]:
        """(cookie value, form value) of the login form's double-submit CSRF token."""
        nonce = secrets.token_urlsafe(16)
        return nonce, self._sign("login", nonce)

    def check_login(self, cookie: str | None, sent: str | None) -> bool:
        return bool(cookie) and bool(sent) and _same(str(sent), self._sign("login", str(cookie)))


def _same(sent: str, expected: str) -> bool:
    """A constant-time comparison of what a client sent (any text: non-ASCII is simply unequal,
    never an error) with what the server expects."""
    return hmac.compare_digest(sent.encode("utf-8", "surrogatepass"), expected.encode("utf-8"))


__all__ = ["LOGIN_COOKIE", "SESSION_COOKIE", "Session", "Sessions"]
