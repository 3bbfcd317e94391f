"""Access tokens: an admin token manages households; a household token reaches one household.

A token is shown once, when created; the database keeps only its SHA-256 (tokens are 256
random bits, so a plain hash is enough: there is nothing to brute-force). Every request looks
the hash up, so a token created or revoked with the CLI takes effect at once in a running service.
"""

from __future__ import annotations

import hashlib
import hmac
import secrets
from dataclasses import dataclass
from pathlib import Path

from globe.errors import AuthenticationError, DataError, PermissionDeniedError
from globe.service.schema import TokenRow
from globe.service.store import Store

PREFIX = "globe_"


def digest(token: str) -> str:
    return hashlib.sha256(token.encode("utf-8")).hexdigest()


@dataclass(frozen=True, slots=True)
class Caller:
    token_id: str
    household: str | None
    admin: bool

    def require_admin(self) -> None:
        if not self.admin:
            raise PermissionDeniedError("this endpoint needs an admin token")

    def require_household(self, name: str) -> None:
        if not self.admin and self.household != name:
            raise PermissionDeniedError(f"this token does not give access to household {name!r}")


def issue(store: Store, *, household: str | None = None, admin: bool = False) -> tuple[str, str]:
    """Create a token; returns (token, id). Exactly one of ``household`` and ``admin``."""
    if admin == (household is not None):
        raise DataError("a token is either --admin or for one --household", field="household")
    token = PREFIX + secrets.token_urlsafe(32)
    h = digest(token)
    token_id = h[:12]
    store.add_token(token_id, h, household, admin)
    return token, token_id


def create_token(db_path: Path, *, household: str | None = None, admin: bool = False) -> str:
    """Create a token in the database at ``db_path`` (created if needed); returns the token."""
    store = Store(Path(db_path))
    try:
        return issue(store, household=household, admin=admin)[0]
    finally:
        store.close()


def revoke(store: Store, token_or_id: str) -> int:
    """Revoke a token given itself or its id; returns how many were revoked."""
    if token_or_id.startswith(PREFIX):
        return store.revoke_token(digest=digest(token_or_id))
    return store.revoke_token(token_id=token_or_id)


def authenticate(store: Store, authorization: str | None) -> Caller:
    """The caller of a request from its ``Authorization`` header (401 if missing or unknown)."""
    if not authorization:
        raise AuthenticationError("missing 'Authorization: Bearer <token>' header")
    scheme, _, token = authorization.partition(" ")
    token = token.strip()
    if scheme.lower() != "bearer" or not token:
        raise AuthenticationError("the Authorization header must be 'Bearer <token>'")
    h = digest(token)
    row: TokenRow | None = store.token(h)
    if row is None or row.revoked_at is not None or not hmac.compare_digest(row.id, h[:12]):
        raise AuthenticationError("unknown or revoked token")
    return Caller(row.id, row.household, row.admin)
