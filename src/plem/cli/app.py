"""The `plem` command: the root application and the entry point that turns errors into exit codes."""

from __future__ import annotations

import os
import sys
import traceback
from collections.abc import Sequence
from typing import Annotated

import typer
from typer._click import exceptions as click_exceptions

from plem.cli import bag as bag_commands
from plem.cli import config as config_commands
from plem.cli import description as description_commands
from plem.cli import doctor as doctor_command
from plem.cli import ethercat as ethercat_commands
from plem.cli import launch as launch_command
from plem.cli import profile as profile_commands
from plem.cli import robot as robot_commands
from plem.cli import topic as topic_commands
from plem.cli.output import print_error
from plem.errors import PlemError, UsageError

app = typer.Typer(
    name="plem",
    help="Bring up, configure and run 6- and 7-axis robot arms.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


def _print_version(requested: bool) -> None:
    """`plem --version`: the installed version, then exit."""
    if requested:
        from importlib.metadata import version  # deferred: costs 0.1 s, only --version needs it

        typer.echo(f"plem {version('plem')}")
        raise typer.Exit


@app.callback()
def _root(
    _version: Annotated[bool, typer.Option("--version", callback=_print_version, is_eager=True,
                                           help="Print plem's version and exit.")] = False,
) -> None:
    """Bring up, configure and run 6- and 7-axis robot arms."""


app.add_typer(config_commands.app, name="config")
app.add_typer(profile_commands.app, name="profile")
app.add_typer(topic_commands.app, name="topic")
app.add_typer(bag_commands.app, name="bag")
app.add_typer(ethercat_commands.app, name="ethercat")
app.command("validate")(description_commands.validate)
app.command("create-description")(description_commands.create_description)
app.command("launch", context_settings=launch_command.EXTRA_ARGS, add_help_option=False)(launch_command.launch)
app.command("state")(robot_commands.state)
app.command("move")(robot_commands.move)
app.command("mode")(robot_commands.mode)
app.command("reset")(robot_commands.reset)
app.command("doctor")(doctor_command.doctor)


def _usage_error(error: click_exceptions.UsageError) -> UsageError:
    command = error.ctx.command_path if error.ctx else "plem"
    return UsageError(
        error.format_message(),
        what=f"a valid command line for `{command}`",
        why=error.format_message(),
        how=f"run `{command} --help` for the arguments",
    )


def run(argv: Sequence[str] | None = None) -> int:
    """Run the CLI and return its exit code: 0 ok, 1 error, 2 usage error; never lets a traceback out."""
    command = typer.main.get_command(app)
    try:
        result = command.main(args=list(argv) if argv is not None else None, prog_name="plem", standalone_mode=False)
        return result if isinstance(result, int) else 0
    except PlemError as error:
        print_error(error)
        return error.exit_code
    except click_exceptions.NoArgsIsHelpError as error:   # a group given no command: its help is the answer
        error.show()
        return 2
    except click_exceptions.UsageError as error:
        print_error(_usage_error(error))
        return 2
    except click_exceptions.ClickException as error:
        error.show()
        return error.exit_code
    except (typer.Abort, KeyboardInterrupt):
        return 130
    except Exception as error:  # noqa: BLE001 - a bug in plem: still no traceback unless asked for
        if os.environ.get("PLEM_DEBUG"):
            traceback.print_exc()
        print_error(PlemError(
            f"Internal error: {type(error).__name__}: {error}",
            what="the command to finish or report a WHAT/WHY/HOW error",
            why="plem hit an unexpected condition (a bug)",
            how="rerun with PLEM_DEBUG=1 to see the traceback, and report it with the command you ran",
        ))
        return 1


def main() -> None:
    """Console entry point."""
    sys.exit(run())
