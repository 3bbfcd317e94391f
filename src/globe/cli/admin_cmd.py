"""Administration of a service database on the server's own machine: ``globe token create|revoke|list``
and ``globe household import|delete|export`` (import reads a folder on this disk: never offered over HTTP)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from globe.cli.common import console, count, out
from globe.errors import DataError

if TYPE_CHECKING:
    from globe.data.records import Household
    from globe.data.sensors import SensorData

DbOption = Annotated[Path, typer.Option("--db", help="the service's SQLite file (created if missing)")]

token_app = typer.Typer(help="Access tokens of the assistance service.", no_args_is_help=True)
household_app = typer.Typer(help="Households of the assistance service's database.", no_args_is_help=True)


def register(app: typer.Typer) -> None:
    """Add ``globe token`` and ``globe household`` to the main application."""
    app.add_typer(token_app, name="token")
    app.add_typer(household_app, name="household")


@token_app.command("create")
def token_create(
    db: DbOption,
    admin: Annotated[bool, typer.Option("--admin", help="may create, list and delete households")] = False,
    household: Annotated[str | None, typer.Option("--household", help="reaches this household only")] = None,
) -> None:
    """Print a new token once (the database keeps only its hash)."""
    from globe.service.auth import issue
    from globe.service.schemas import check_household_name
    from globe.service.store import Store

    if admin == (household is not None):
        raise DataError("give exactly one of --admin and --household NAME", field="household")
    if household is not None:
        check_household_name(household, field="household")
    store = Store(db)
    try:
        if household is not None and store.household(household) is None:
            raise DataError(f"no household {household!r} in {db} (create it first; 'globe household import' or "
                            "POST /households)", field="household")
        token, token_id = issue(store, household=household, admin=admin)
    finally:
        store.close()
    console.print(f"token {token_id} ({'admin' if admin else 'household ' + str(household)}); it is shown only now:")
    out.print(token, highlight=False, soft_wrap=True)


@token_app.command("revoke")
def token_revoke(db: DbOption,
                 token: Annotated[str, typer.Argument(help="the token, or its id from 'globe token list'")]) -> None:
    """Revoke a token (effective at once, also in a running service)."""
    from globe.service.auth import revoke
    from globe.service.store import Store

    store = Store(db)
    try:
        n = revoke(store, token)
    finally:
        store.close()
    if not n:
        raise DataError("no such active token", field="token")
    console.print("revoked")


@token_app.command("list")
def token_list(db: DbOption) -> None:
    """Tokens by id (never the tokens themselves)."""
    from globe.service.store import Store

    store = Store(db)
    try:
        rows = store.tokens()
    finally:
        store.close()
    for r in rows:
        scope = "admin" if r.admin else f"household {r.household}"
        revoked = f"  revoked {r.revoked_at}" if r.revoked_at else ""
        out.print(f"{r.id}  {scope:30s}  created {r.created_at}{revoked}")


@household_app.command("import")
def household_import(
    db: DbOption,
    name: Annotated[str, typer.Option("--name", help="household id in the service")],
    folder: Annotated[Path, typer.Argument(help="folder with nodes.csv and optional train/*.csv")],
    timezone: Annotated[str | None, typer.Option("--timezone", help="IANA zone (default: the server's)")] = None,
    method: Annotated[str | None, typer.Option(
        "--method", help="how its models are chosen: routine (default: by cross-validation on its training days), "
                         "ngram_smoothed, ngram (the paper's) or persistence")] = None,
    include_test: Annotated[bool, typer.Option(
        "--include-test", help="learn its test/*.csv days too (after the training days)")] = False,
    config: Annotated[Path | None, typer.Option("--config", help="TOML configuration file")] = None,
) -> None:
    """Import a household folder from this machine's disk into the database, with the models chosen for it."""
    from globe.cli.common import resolve
    from globe.cli.model_cmd import _method
    from globe.data.csv_logs import day_files, read_nodes
    from globe.data.records import named_date
    from globe.evaluation.deploy import choose_deployment
    from globe.service.schemas import check_household_name
    from globe.service.store import Store
    from globe.service.timepolicy import check_timezone
    from globe.service.upload import household_from
    from globe.session import deployment_summary, session_grid
    from globe.session.build import new_activities_rule

    cfg = resolve(config)
    chosen_by = _method(method) or cfg.selection.deploy
    check_household_name(name)
    nodes = read_nodes(folder / "nodes.csv")
    files = [f for split in ("train", "test") if split == "train" or include_test
             for f in (day_files(folder / split) if (folder / split).is_dir() else [])]
    texts = [f.read_text(encoding="utf-8-sig") for f in files]
    named = [named_date(f.name) for f in files]  # imported days are named by their date
    try:
        household = household_from(name, nodes, texts, dates=named if None not in named else None)
    except DataError as err:  # days[i] is a file on this disk: named as such
        index = err.source[5:-1] if err.source and err.source.startswith("days[") else ""
        if not index.isdigit():
            raise
        raise type(err)(err.message, source=str(files[int(index)]), line=err.line, field=err.field) from None
    objects, days = household.objects, household.train
    tz = check_timezone(timezone)
    store = Store(db)
    try:
        if store.household(name) is not None:
            raise DataError(f"household {name!r} exists already", field="name")
        deployment = choose_deployment(household, cfg, method=chosen_by, progress=console.print)
        settings = {"grid": session_grid(household, cfg).as_dict(), "method": chosen_by,
                    "new_activities": new_activities_rule(cfg, bool(days)),
                    "deployment": deployment.model_dump(mode="json")}
        store.add_household(household, tz, texts, settings=settings, sensors=_sensors_of(folder, files, household))
    finally:
        store.close()
    which = "training and test" if include_test else "training; --include-test adds test/"
    learned = f"{count(len(days), 'day')} ({which})"
    console.print(f"imported household {name!r}: {len(objects)} objects, {learned}, time zone {tz}; it runs "
                  f"{deployment_summary(deployment)}", soft_wrap=True)


def _sensors_of(folder: Path, files: list[Path], household: Household) -> SensorData | None:
    """The folder's sensors (``sensors.csv``, ``events/``), each day's activations keyed by the name
    the household gives the day read from that file (the service recognises activities from them)."""
    from globe.data.sensors import SensorData, day_stem, load_sensor_data  # noqa: F811

    found = load_sensor_data(folder.parent, folder.name)
    if found is None:
        return None
    days = {day_stem(day.name): found.days[path.stem] for path, day in zip(files, household.train)
            if path.stem in found.days}
    return SensorData(found.sensors, days)


@household_app.command("delete")
def household_delete(
    db: DbOption,
    name: Annotated[str, typer.Option("--name", help="household id in the service")],
) -> None:
    """Delete a household and everything stored about it (its observations, feedback and tokens).

    Prefer DELETE /households/NAME on a running service; done here, a running service forgets the
    household at its next write or rebuild (its tokens stop working at once)."""
    from globe.service.store import Store

    store = Store(db)
    try:
        if store.household(name) is None:
            raise DataError(f"no household {name!r} in {db}", field="name")
        store.delete_household(name)
    finally:
        store.close()
    console.print(f"deleted household {name!r} and everything stored about it")


@household_app.command("shadow")
def household_shadow(
    db: DbOption,
    name: Annotated[str, typer.Option("--name", help="household id in the service")],
    on: Annotated[bool, typer.Option("--on/--off", help="--on: predict and score, never act; --off: the robot acts")],
) -> None:
    """Switch a household's shadow mode (new households start in it); a running service follows
    within a second. Switch it off once the online scores (globe serve's dashboard, /stats) are good enough."""
    from globe.service.store import Store

    store = Store(db)
    try:
        if store.household(name) is None:
            raise DataError(f"no household {name!r} in {db}", field="name")
        store.set_shadow(name, on)
    finally:
        store.close()
    state = ("on (GLOBE predicts and scores, the robot is never told to act)" if on
             else "off (the robot acts on predictions)")
    console.print(f"household {name!r}: shadow mode {state}")


@household_app.command("export")
def household_export(
    db: DbOption,
    name: Annotated[str, typer.Option("--name", help="household id in the service")],
    out_file: Annotated[Path, typer.Option("--out", help="JSON file to write (what GET /households/NAME/export "
                                                         "answers)")],
) -> None:
    """Write everything stored about a household, as stored (also one the service cannot build)."""
    import json

    from globe.service.store import Store

    store = Store(db)
    try:
        found = store.export_household(name)
    finally:
        store.close()
    if found is None:
        raise DataError(f"no household {name!r} in {db}", field="name")
    out_file.write_text(json.dumps(found, indent=1) + "\n", encoding="utf-8")
    console.print(f"exported household {name!r} ({len(found['days'])} training days, {len(found['observations'])} "
                  f"observations) to {out_file}")
