"""The ``globe`` application: global options and the one error boundary."""

from __future__ import annotations

import logging
import sys
import traceback
from typing import Annotated, Any

import typer
from rich.text import Text

from globe import __version__
from globe.cli import admin_cmd, data_cmd, docs_cmd, evaluate_cmd, model_cmd, noise_cmd, recognise_cmd, service_cmd
from globe.cli.common import console, out
from globe.errors import GlobeError

app = typer.Typer(help="GLOBE: predict a person's next activity and object so a robot can help.",
                  no_args_is_help=True, pretty_exceptions_enable=False, add_completion=False)
app.add_typer(data_cmd.app, name="data")
app.add_typer(docs_cmd.app, name="docs")
app.command("train")(model_cmd.train)
app.command("predict")(model_cmd.predict)
app.command("evaluate")(evaluate_cmd.evaluate)
app.command("reproduce")(evaluate_cmd.reproduce)
app.command("noise")(noise_cmd.noise)
app.command("robustness")(evaluate_cmd.robustness)
app.command("recognise")(recognise_cmd.recognise)
app.command("serve")(service_cmd.serve)
app.command("robot")(service_cmd.robot)
admin_cmd.register(app)

_state = {"verbose": False}


def _version(value: bool) -> None:
    if value:
        print(f"globe {__version__}")
        raise typer.Exit()


@app.callback()
def _main(
    verbose: Annotated[bool, typer.Option("--verbose", "-v", help="log details and show tracebacks")] = False,
    version: Annotated[bool, typer.Option(
        "--version", callback=_version, is_eager=True, help="print the version")] = False,
) -> None:
    _state["verbose"] = verbose
    logging.basicConfig(level=logging.INFO if verbose else logging.WARNING,
                        format="%(levelname)s %(name)s: %(message)s")


def _usage_errors() -> tuple[type[BaseException], ...]:
    """Typer raises the click exceptions it bundles; a standalone click, if installed, is caught too."""
    import typer.exceptions

    kinds: list[type[BaseException]] = []
    bundled = getattr(typer.exceptions, "TyperException", None)  # typer >= 0.2x bundles click
    if bundled is not None:
        kinds.append(bundled)
    try:
        from click.exceptions import ClickException
    except ImportError:  # the core install: typer needs no separate click
        pass
    else:
        kinds.append(ClickException)
    return tuple(kinds)


def one_line(message: str) -> str:
    """A message as one line: continuation lines are joined, indentation dropped."""
    parts = [p.strip() for p in str(message).splitlines() if p.strip()]
    text = ""
    for part in parts:
        text += part if not text else (" " if text.endswith(":") else "; ") + part
    return text


def _say(label: str, message: str) -> None:
    """Printed as plain text: a label like root:x:0 or [red] stays literal."""
    line = Text(f"{label}:", style="red")
    line.append(" " + one_line(message))
    console.print(line, soft_wrap=True)


def _verbose(argv: list[str]) -> bool:
    if _state["verbose"]:
        return True
    for arg in argv:  # global options come before the command
        if not arg.startswith("-"):
            return False
        if arg in ("-v", "--verbose"):
            return True
    return False


def _usage(err: BaseException) -> int:
    ctx = getattr(err, "ctx", None)
    if type(err).__name__ == "NoArgsIsHelpError" and ctx is not None:
        out.print(ctx.get_help(), markup=False, highlight=False)
        return 2
    message = err.format_message() if hasattr(err, "format_message") else str(err)
    where = f" (see '{ctx.command_path} --help')" if ctx is not None else ""
    _say("usage error" if getattr(err, "exit_code", 2) == 2 else "error", one_line(message) + where)
    return int(getattr(err, "exit_code", 2))


def _command() -> Any:
    """The click command of :data:`app`, its flags shown without a value (typer labels a flag
    ``<bool>``, as if it took one). Duck-typed: typer may bundle its own click."""
    command = typer.main.get_command(app)

    def walk(cmd: Any) -> None:
        help_option = cmd.get_help_option(cmd.context_class(cmd))
        for param in [*cmd.params, help_option]:
            if getattr(param, "is_flag", False):
                param.metavar = ""
        for sub in getattr(cmd, "commands", {}).values():
            walk(sub)

    walk(command)
    return command


def main(argv: list[str] | None = None) -> None:
    """The one error boundary: a result, or one line on stderr. Exit 1 for bad data (a GlobeError or
    a file the system refuses), 2 for bad usage, 70 for a bug (``-v`` shows the traceback)."""
    args = list(sys.argv[1:] if argv is None else argv)
    _state["verbose"] = False
    code = 0
    try:
        rv = _command().main(args=args, prog_name="globe", standalone_mode=False)
        code = rv if isinstance(rv, int) else 0
    except GlobeError as err:
        if _verbose(args):
            traceback.print_exc()
        _say("error", str(err))
        code = 1
    except _usage_errors() as err:
        if _verbose(args):
            traceback.print_exc()
        code = _usage(err)
    except typer.Exit as exit_:
        code = exit_.exit_code
    except (typer.Abort, KeyboardInterrupt):
        _say("error", "aborted")
        code = 130
    except OSError as err:
        if _verbose(args):
            traceback.print_exc()
        where = f": {err.filename}" if err.filename else ""
        _say("error", f"{err.strerror or err}{where}")
        code = 1
    except Exception as err:  # a bug: still one line unless -v
        if _verbose(args):
            traceback.print_exc()
        _say("internal error", f"{type(err).__name__}: {err} (a bug in GLOBE; run with -v for the traceback)")
        code = 70
    sys.exit(code)
