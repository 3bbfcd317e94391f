"""The ``globe`` application: global options and the one error boundary."""

from __future__ import annotations

import logging
import sys
from typing import Annotated

import typer
from rich.markup import escape

from globe import __version__
from globe.cli import data_cmd, evaluate_cmd, model_cmd, noise_cmd, service_cmd
from globe.cli.common import console
from globe.errors import GlobeError

app = typer.Typer(help="GLOBE: predict a person's next activity and object so a robot can help.",
                  no_args_is_help=True, pretty_exceptions_enable=False, add_completion=False)
app.add_typer(data_cmd.app, name="data")
app.command("train")(model_cmd.train)
app.command("predict")(model_cmd.predict)
app.command("evaluate")(evaluate_cmd.evaluate)
app.command("reproduce")(evaluate_cmd.reproduce)
app.command("noise")(noise_cmd.noise)
app.command("robustness")(evaluate_cmd.robustness)
app.command("serve")(service_cmd.serve)
app.command("robot")(service_cmd.robot)

_state = {"verbose": False}


def _version(value: bool) -> None:
    if value:
        print(f"globe {__version__}")
        raise typer.Exit()


@app.callback()
def _main(
    verbose: Annotated[bool, typer.Option("--verbose", "-v", help="log details and show tracebacks")] = False,
    version: Annotated[bool, typer.Option("--version", callback=_version, is_eager=True, help="print the version")] = False,
) -> None:
    _state["verbose"] = verbose
    logging.basicConfig(level=logging.INFO if verbose else logging.WARNING, format="%(levelname)s %(name)s: %(message)s")


def main() -> None:
    try:
        app(standalone_mode=False)
    except GlobeError as err:
        if _state["verbose"]:
            console.print_exception()
        console.print("[red]error:[/red]", escape(str(err)), highlight=False, soft_wrap=True)
        sys.exit(1)
    except typer.Exit as exit_:
        sys.exit(exit_.exit_code)
    except typer.Abort:
        console.print("aborted")
        sys.exit(130)
    except Exception as err:  # click usage errors arrive here in non-standalone mode
        import click

        if isinstance(err, click.ClickException):
            err.show()
            sys.exit(err.exit_code)
        raise
