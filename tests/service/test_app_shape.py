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


def test_the_openapi_schema_says_what_the_server_enforces():
    """Configured limits (not the models' hard ceilings), the label and class#id rules, and the
    400/408/431 answers the guard sends."""
    config = GlobeConfig().with_overrides({"service.max_label_length": 40, "service.max_locations": 3})
    schema = create_app(config).openapi()
    parts = schema["components"]["schemas"]
    observation = parts["ObservationIn"]["properties"]
    assert [b for b in observation["id"]["anyOf"] if b["type"] == "string"][0]["maxLength"] == 40
    activity = [b for b in observation["activity"]["anyOf"] if b["type"] == "string"][0]
    assert activity == {"type": "string", "maxLength": 40, "minLength": 1}
    assert observation["locations"]["maxProperties"] == 3
    assert parts["NodeIn"]["properties"]["node"]["maxLength"] == 40
    for path, operations in schema["paths"].items():
        for method, operation in operations.items():
            assert {"400", "408", "431"} <= set(operation["responses"]), (method, path)


@pytest.mark.parametrize(("label", "ok"), [
    ("cooking", True), (" cooking\t", True), ("café", True), ("", False), (" \t", False), ("idle\x07", False),
    ("a\x85b", False), ("evil\u202etxt", False), ("x\u2066", False), ("in\tside", False), ("\ufeffidle", False),
    ("id\u200ble", False), ("persian\u200cword", True),
])
def test_the_documented_label_pattern_is_the_servers_rule(label, ok):
    import re

    from globe.data.csv_logs import activity_label
    from globe.service.schemas import LABEL_PATTERN

    try:
        activity_label(label)
        accepted = True
    except DataError:
        accepted = False
    assert accepted == ok and bool(re.match(LABEL_PATTERN[:-1] + r"\Z", label)) == ok


@pytest.mark.parametrize(("label", "ok"), [
    ("kitchen#1", True), ("a#b#c", True), ("##1", True), (" a#1 ", True), ("a #1", True), ("#1", False), ("a#", False),
    ("a# ", False), (" #1", False), ("a1", False), ("a#1\x00", False), ("a#1#", False),
])
def test_the_documented_node_pattern_is_the_servers_class_id_rule(label, ok):
    import re

    from globe.data.csv_logs import parse_nodes_text
    from globe.service.schemas import NODE_PATTERN

    cls = label.strip(" \t").rpartition("#")[0].strip(" \t") or "x"
    try:
        parse_nodes_text(f'node,class,category,movable,start_location\n"{label}","{cls}",Rooms,0,"{label}"\n', "nodes")
        accepted = True
    except DataError as err:
        accepted = "does not start with its class" in str(err)
    assert accepted == ok and bool(re.match(NODE_PATTERN[:-1] + r"\Z", label)) == ok


def test_a_method_a_path_does_not_answer_names_every_method_it_does(token_store):
    """``OPTIONS /households`` said ``Allow: GET`` (the router named its first route's methods only)."""
    store, token = token_store
    c = client_of(UnknownHouseholdError("x"), store, token)  # no `with`: its lifespan would open a database
    for path, allowed in (("/households", "GET, POST"), ("/households/A", "DELETE"),
                          ("/households/A/observations", "POST"), ("/households/A/shadow", "PUT")):
        r = c.options(path)
        assert (r.status_code, r.headers["allow"]) == (405, allowed), (path, r.headers)
