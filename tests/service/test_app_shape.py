"""The app's shape without a server: each error class answers with its own status, and the
dependencies in :mod:`globe.service.deps` can be overridden (unit tests with a stand-in registry
over a real token store)."""

import pytest
from fastapi.testclient import TestClient

from globe.config import GlobeConfig
from globe.errors import (
    AuthenticationError,
    ConfigError,
    DataError,
    DuplicateHouseholdError,
    GlobeError,
    LimitError,
    LLMCacheError,
    PermissionDeniedError,
    StoreError,
    StoreUnavailableError,
    UnknownHouseholdError,
)
from globe.service import deps
from globe.service.app import create_app
from globe.service.auth import issue
from globe.service.store import Store

STATUS = [  # what the service answered for each before the classes carried it (the old isinstance ladder)
    (AuthenticationError("no token"), 401), (PermissionDeniedError("not yours"), 403),
    (UnknownHouseholdError("x"), 404), (DuplicateHouseholdError("exists"), 409),
    (DataError("bad", field="time"), 422), (LimitError("too long", field="id"), 422), (ConfigError("bad"), 422),
    (StoreError("disk"), 503), (StoreUnavailableError("gone"), 503), (LLMCacheError("locked"), 503),
]


class RaisingRegistry:
    """Stands in for the registry (its tokens in a real store): every household request raises ``error``."""

    def __init__(self, error: Exception, store: Store) -> None:
        self.error, self.store = error, store

    def stats(self, name: str):
        raise self.error


@pytest.fixture()
def token_store(tmp_path):
    store = Store(tmp_path / "tokens.sqlite3")
    token, _ = issue(store, admin=True)
    yield store, token
    store.close()


def client_of(error: Exception, store: Store, token: str) -> TestClient:
    """The app with its registry dependency overridden (no lifespan runs: no database is opened)."""
    app = create_app(GlobeConfig())
    app.state.registry = RaisingRegistry(error, store)  # the guard authenticates against its store
    app.dependency_overrides[deps.get_registry] = lambda: app.state.registry
    return TestClient(app, base_url="http://127.0.0.1", raise_server_exceptions=False,
                      headers={"Authorization": f"Bearer {token}"})


@pytest.mark.parametrize(("error", "status"), STATUS, ids=[type(e).__name__ for e, _ in STATUS])
def test_each_error_class_answers_with_its_own_status(error, status, token_store):
    assert error.http_status == status
    r = client_of(error, *token_store).get("/households/A/stats")
    assert r.status_code == status
    assert r.json() == {"detail": str(error) if not isinstance(error, DataError) else error.message,
                        "field": getattr(error, "field", None)}
    assert ("www-authenticate" in r.headers) == (status == 401)


def test_an_unexpected_globe_error_is_a_500(token_store):
    assert GlobeError.http_status == 500
    assert client_of(GlobeError("a bug"), *token_store).get("/households/A/stats").status_code == 500
