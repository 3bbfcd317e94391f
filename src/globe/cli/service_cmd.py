"""``globe serve`` (the HTTP service) and ``globe robot`` (a simulated robot against it)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer
from rich.text import Text

from globe.cli.common import (
    ConfigOption,
    DataOption,
    console,
    households_from,
    out,
    progress_bar,
    resolve,
)
from globe.errors import MissingExtraError


def serve(
    database: Annotated[Path | None, typer.Option(
        "--db", help="SQLite file (default: globe.sqlite3 in the current folder; created if missing)")] = None,
    host: Annotated[str | None, typer.Option(
        "--host", help="bind address (keep loopback; put a TLS reverse proxy in front)")] = None,
    port: Annotated[int | None, typer.Option("--port", help="TCP port")] = None,
    backend: Annotated[str | None, typer.Option("--backend", help="embedded, remote or none")] = None,
    new_db: Annotated[bool, typer.Option("--new-db", help="if the --db file is empty or truncated, keep it as "
                                                          "FILE.damaged-TIME and start a new, empty database")] = False,
    config: ConfigOption = None,
) -> None:
    """Start the GLOBE assistance service (OpenAPI at /docs). Requests need a token: globe token create."""
    cfg = resolve(config, service__database=database, service__host=host, service__port=port, llm__backend=backend)
    cfg.mqtt.check_files()  # what the MQTT bridge reads: here, not from inside the running app
    try:
        import uvicorn  # noqa: F401 - checked here: the service extra
    except ImportError as err:
        raise MissingExtraError("uvicorn", "service") from err
    from globe.errors import DamagedDatabaseError
    from globe.service import server
    from globe.service.app import create_app
    from globe.service.dbfile import set_aside_database
    from globe.service.store import Store

    new = not cfg.service.database.exists()
    try:
        Store(cfg.service.database).close()  # refuse a foreign, newer or damaged database here, with a clear message
    except DamagedDatabaseError:
        if not new_db:
            raise
        kept = set_aside_database(cfg.service.database)
        console.print(f"the damaged database was kept as {kept}; starting a new one in {cfg.service.database}")
        Store(cfg.service.database).close()
    sock = server.bind(cfg.service.host, cfg.service.port)  # a busy port or an unknown host: one line, before anything
    if cfg.service.host not in ("127.0.0.1", "localhost", "::1"):
        warning = Text("warning:", style="yellow")
        warning.append(f" listening on {cfg.service.host}: tokens travel in clear text over plain HTTP; keep the "
                       "service on 127.0.0.1 behind a TLS reverse proxy (see the README)")
        console.print(warning, soft_wrap=True)
    where = cfg.service.database.resolve()
    if new:  # e.g. no --db: the default file in the current folder
        console.print(f"created a new, empty database {where} (--db names another); globe token create --db {where} "
                      "gives the first token", soft_wrap=True)
    console.print(f"GLOBE service on http://{cfg.service.host}:{cfg.service.port} (database {where})", soft_wrap=True)
    server.run(create_app(cfg), cfg.service, sock)


def robot(
    url: Annotated[str, typer.Option("--url", help="service base URL")] = "http://127.0.0.1:8765",
    household: Annotated[str, typer.Option("--household", help="HOMER+ household to replay, e.g. A")] = "A",
    name: Annotated[str | None, typer.Option(
        "--name", help="household id in the service (default: the household)")] = None,
    days: Annotated[int, typer.Option("--days", min=1, help="how many test days to replay")] = 10,
    data: DataOption = None,
    config: ConfigOption = None,
    report_file: Annotated[Path | None, typer.Option("--report", help="also write the metrics as JSON")] = None,
    token: Annotated[str | None, typer.Option(
        "--token", envvar="GLOBE_TOKEN", help="admin token (or $GLOBE_TOKEN)")] = None,
) -> None:
    """Replay HOMER+ test days through the service as a simulated robot; print assistance metrics."""
    from globe import assembly
    from globe.service.client import GlobeClient, ServiceError, household_payload
    from globe.service.robot import SimulatedRobot, replay_days

    cfg = resolve(config)
    (h,) = households_from(cfg, data, household)
    ident = name or h.name
    with GlobeClient(url, token=token) as client:
        try:
            client.create_household(ident, **household_payload(h))
        except ServiceError as err:
            if err.status != 409:
                raise
            console.print(f"household {ident!r} exists in the service: continuing with its state")
        client.set_shadow(ident, False)  # a simulated robot: it acts when told to (new households start in shadow)
        test_days = h.test[:days]
        lead, window = assembly.lead_steps(cfg.policy, assembly.step_minutes(h, cfg))
        with progress_bar(len(test_days), "replaying days") as advance:
            report = replay_days(client, ident, h, test_days, SimulatedRobot(), min_lead_steps=lead,
                                 window_steps=window, progress=advance)
        summary = report.summary()
    for key, value in summary.items():
        out.print(f"{key:20s} {value}")
    if report_file:
        report_file.write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
