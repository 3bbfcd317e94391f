"""``globe token`` and ``globe household import`` against a real service database and process."""

import pytest
from typer.testing import CliRunner

from globe.cli.main import app
from globe.errors import DataError
from globe.service.client import GlobeClient, ServiceError
from tests.service.conftest import Server

pytestmark = pytest.mark.service


def cli(*args):
    result = CliRunner().invoke(app, list(args))
    if result.exception and not isinstance(result.exception, SystemExit):
        raise result.exception
    return result


def test_tokens_and_import_from_the_command_line(tmp_path, homer_root):
    db = tmp_path / "globe.sqlite3"
    created = cli("token", "create", "--db", str(db), "--admin")
    admin = created.stdout.strip().splitlines()[-1]
    assert created.exit_code == 0 and admin.startswith("globe_")
    assert admin not in db.read_bytes().decode("latin-1")  # only the hash is kept
    cli("household", "import", "--db", str(db), "--name", "home-b", "--timezone", "Europe/Paris", str(homer_root / "HouseholdB"))
    robot = cli("token", "create", "--db", str(db), "--household", "home-b").stdout.strip().splitlines()[-1]
    with pytest.raises(DataError):
        cli("token", "create", "--db", str(db), "--admin", "--household", "home-b")
    srv = Server(db, tmp_path / "server.log")
    srv.start()
    try:
        with GlobeClient(srv.url, token=admin) as c:
            assert c.households() == ["home-b"]
        with GlobeClient(srv.url, token=robot) as c:
            s = c.stats("home-b")
            assert s["days_learned"] == 65 and s["timezone"] == "Europe/Paris"
            listed = cli("token", "list", "--db", str(db)).stdout
            assert "household home-b" in listed and "admin" in listed and robot not in listed
            robot_id = next(line.split()[0] for line in listed.splitlines() if "household home-b" in line)
            assert cli("token", "revoke", "--db", str(db), robot_id).exit_code == 0
            with pytest.raises(ServiceError) as err:
                c.stats("home-b")
            assert err.value.status == 401
    finally:
        srv.stop()
