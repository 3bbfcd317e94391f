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
    cli("household", "import", "--db", str(db), "--name", "home-b", "--timezone", "Europe/Paris", "--method", "ngram",
        str(homer_root / "HouseholdB"))
    robot = cli("token", "create", "--db", str(db), "--household", "home-b").stdout.strip().splitlines()[-1]
    with pytest.raises(DataError):
        cli("token", "create", "--db", str(db), "--admin", "--household", "home-b")
    with pytest.raises(DataError, match="no household 'ghost'") as err:  # a token for nobody: refused
        cli("token", "create", "--db", str(db), "--household", "ghost")
    assert err.value.field == "household" and "ghost" not in cli("token", "list", "--db", str(db)).stdout
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


@pytest.mark.parametrize("name", ["", "a/b", "../x", ".", "..", "-x", "x" * 300])
def test_the_cli_imports_only_names_clients_can_address(tmp_path, homer_root, name):
    db = tmp_path / "globe.sqlite3"
    with pytest.raises(DataError) as err:
        cli("household", "import", "--db", str(db), "--name", name, str(homer_root / "HouseholdB"))
    assert err.value.field == "name" and "household name" in str(err.value)
    with pytest.raises(DataError):
        cli("token", "create", "--db", str(db), "--household", name)
    from globe.service.store import Store

    store = Store(db)
    assert store.households() == [] and store.tokens() == []
    store.close()


def test_household_delete_and_export_from_the_command_line(tmp_path, homer_root):
    import json

    db = tmp_path / "globe.sqlite3"
    admin = cli("token", "create", "--db", str(db), "--admin").stdout.strip().splitlines()[-1]
    cli("household", "import", "--db", str(db), "--name", "home-c", "--timezone", "UTC", "--method", "ngram",
        str(homer_root / "HouseholdC"))
    robot = cli("token", "create", "--db", str(db), "--household", "home-c").stdout.strip().splitlines()[-1]
    out = tmp_path / "home-c.json"
    cli("household", "export", "--db", str(db), "--name", "home-c", "--out", str(out))
    exported = json.loads(out.read_text())
    assert exported["name"] == "home-c" and len(exported["days"]) == 65 and exported["observations"] == []
    srv = Server(db, tmp_path / "server.log")
    srv.start()
    try:
        with GlobeClient(srv.url, token=admin) as c:
            assert c._call("GET", "/households/home-c/export") == exported  # the same, over HTTP
        assert cli("household", "delete", "--db", str(db), "--name", "home-c").exit_code == 0
        with GlobeClient(srv.url, token=robot) as c:
            with pytest.raises(ServiceError) as err:
                c.stats("home-c")
            assert err.value.status == 401  # its tokens went with it
        with GlobeClient(srv.url, token=admin) as c:
            assert c.households() == []
            with pytest.raises(ServiceError) as err:
                c.observe("home-c", __import__("datetime").datetime.now(), "idle", {})
            assert err.value.status == 404
    finally:
        srv.stop()
    with pytest.raises(DataError, match="no household 'home-c'"):
        cli("household", "delete", "--db", str(db), "--name", "home-c")


def test_import_takes_each_day_files_date_from_its_name(tmp_path):
    """A folder written by ``globe data import`` names its day files by their date: the database
    keeps the dates; a folder of numbered days keeps none."""
    from globe.data.csv_logs import write_day, write_nodes
    from globe.service.store import Store
    from tests.simulated import weekly_home

    h = weekly_home(9, 1, 4)
    for name, named in (("dated", True), ("numbered", False)):
        folder = tmp_path / name
        (folder / "train").mkdir(parents=True)
        write_nodes(folder / "nodes.csv", h.nodes)
        for i, d in enumerate(h.train):
            write_day(folder / "train" / (f"{d.name}.csv" if named else f"{i:03d}.csv"), d, h.objects)
        cli("household", "import", "--db", str(tmp_path / "db.sqlite3"), "--name", name, "--timezone", "UTC",
            "--method", "ngram", str(folder))
    store = Store(tmp_path / "db.sqlite3")
    assert [d.date for d in store.training_days("dated")] == [d.name for d in h.train]
    assert h.train[0].name == "2024-01-01"
    assert [d.date for d in store.training_days("numbered")] == [None] * len(h.train)
    store.close()


def test_import_names_the_day_file_a_limit_refuses(tmp_path):
    """A 300-character activity imports and validates, but the service's label limit refuses it:
    the error named 'days[1]' (the service's name for an uploaded day), not the file on this disk."""
    from tests.corpus.homes import day_rows, day_text, write_home

    home = write_home(tmp_path / "data", train=3, test=0)
    rows = day_rows(1)
    rows[4][1] = "x" * 300
    (home / "train" / "001.csv").write_text(day_text(rows), encoding="utf-8")
    with pytest.raises(DataError) as err:
        cli("household", "import", "--db", str(tmp_path / "db.sqlite3"), "--name", "t", "--method", "ngram", str(home))
    assert (err.value.source, err.value.line) == (str(home / "train" / "001.csv"), 6)
    assert "longer than 128 characters" in err.value.message and "x" * 65 not in str(err.value)


def test_import_keeps_a_folders_sensors(tmp_path):
    from globe.service.store import Store
    from tests.simulated_sensors import sensor_home, write_home

    home, sensors = sensor_home(days=5, test=1, step=10, seed=4)
    folder = write_home(tmp_path / "Sensors", home, sensors)
    db = tmp_path / "globe.sqlite3"
    cli("household", "import", "--db", str(db), "--name", "s", "--method", "ngram", str(folder))
    store = Store(db)
    try:
        assert [s.name for s in store.sensors("s") or ()] == [s.name for s in sensors.sensors]
        stored = [d.events for d in store.training_days("s")]
        assert len(stored) == len(home.train) and all(stored)  # each training day's activations kept
    finally:
        store.close()
