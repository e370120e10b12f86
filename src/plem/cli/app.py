"""The `plem` command: the root application and the entry point that turns errors into exit codes.

Each command's module is imported when that command is looked up, so a command starts without importing the
others (`plem --help` looks them all up to list them).
"""

from __future__ import annotations

import importlib
import os
import sys
import traceback
from collections.abc import Callable, Iterator, MutableMapping, Sequence
from dataclasses import dataclass, field
from types import ModuleType
from typing import Annotated, Any

import typer
from typer._click import Command
from typer._click import exceptions as click_exceptions
from typer.core import TyperGroup

import plem
from plem.cli import coercion, flags
from plem.errors import PlemError, UsageError


def _no_settings(_module: ModuleType) -> dict[str, Any]:
    return {}


@dataclass(frozen=True)
class CommandSource:
    """Where a `plem` command is defined: `attribute` of `module` is its function, or the typer.Typer of a group
    of commands; `settings` gives, from the imported module, the keyword arguments of typer.Typer.command."""

    module: str
    attribute: str = "app"
    settings: Callable[[ModuleType], dict[str, Any]] = field(default=_no_settings)

    def register(self, name: str, parent: typer.Typer) -> None:
        """Import the module and register the command on `parent` as `name`."""
        module = importlib.import_module(self.module)
        target = getattr(module, self.attribute)
        if isinstance(target, typer.Typer):
            parent.add_typer(target, name=name)
        else:
            parent.command(name, **self.settings(module))(target)


#: Every command of `plem`, in the order `plem --help` lists them.
COMMANDS: dict[str, CommandSource] = {
    "validate": CommandSource("plem.cli.description", "validate"),
    "create-description": CommandSource("plem.cli.description", "create_description"),
    "launch": CommandSource("plem.cli.launch", "launch",
                            lambda module: {"context_settings": module.EXTRA_ARGS, "add_help_option": False}),
    "state": CommandSource("plem.cli.robot", "state"),
    "move": CommandSource("plem.cli.motion", "move"),
    "plan": CommandSource("plem.cli.motion", "plan"),
    "jog": CommandSource("plem.cli.streaming", "jog", lambda module: module.JOG_SETTINGS),
    "speed": CommandSource("plem.cli.streaming", "speed"),
    "scene": CommandSource("plem.cli.scene"),
    "mode": CommandSource("plem.cli.robot", "mode"),
    "reset": CommandSource("plem.cli.robot", "reset"),
    "doctor": CommandSource("plem.cli.doctor", "doctor"),
    "config": CommandSource("plem.cli.config"),
    "profile": CommandSource("plem.cli.profile"),
    "topic": CommandSource("plem.cli.topic"),
    "service": CommandSource("plem.cli.service"),
    "action": CommandSource("plem.cli.action"),
    "node": CommandSource("plem.cli.node"),
    "bag": CommandSource("plem.cli.bag"),
    "fleet": CommandSource("plem.cli.fleet"),
    "view": CommandSource("plem.cli.view", "view"),
    "ethercat": CommandSource("plem.cli.ethercat"),
}


class LazyCommands(MutableMapping[str, Command]):
    """A group's commands by name, in order; each of COMMANDS is built, its module imported, on first access."""

    def __init__(self, build: Callable[[str], Command]) -> None:
        self._build = build
        self._commands: dict[str, Command | None] = dict.fromkeys(COMMANDS)

    def __getitem__(self, name: str) -> Command:
        command = self._commands[name]
        if command is None:
            command = self._commands[name] = self._build(name)
        return command

    def __setitem__(self, name: str, command: Command) -> None:
        self._commands[name] = command

    def __delitem__(self, name: str) -> None:
        del self._commands[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._commands)

    def __len__(self) -> int:
        return len(self._commands)


class RootGroup(TyperGroup):
    """The `plem` group: COMMANDS, each built as typer builds a registered command, when first looked up."""

    def __init__(self, **attrs: Any) -> None:
        super().__init__(**attrs)
        self.commands = LazyCommands(self._build)

    def parse_args(self, ctx: Any, args: list[str]) -> list[str]:
        """Refuse `plem --version` with anything after it: a flag takes no value (`--version true` is not a
        way to ask for the version), and the version is all `plem --version` prints."""
        if args[:1] == ["--version"] and len(args) > 1:
            raise UsageError("--version takes no value", what="`plem --version` on its own: a flag takes no value",
                             why=f"it was followed by {' '.join(args[1:])!r}", how="run `plem --version`")
        return super().parse_args(ctx, args)

    def _build(self, name: str) -> Command:
        holder = typer.Typer(rich_markup_mode=self.rich_markup_mode, suggest_commands=self.suggest_commands)
        COMMANDS[name].register(name, holder)
        return typer.main.get_group(holder).commands[name]


app = typer.Typer(
    name="plem",
    help="Bring up, configure and run 6- and 7-axis robot arms.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    cls=RootGroup,
)
coercion.install()  # plain values converted without importing pydantic
flags.install()  # flags shown without a value type in --help


def _print_version(requested: bool) -> None:
    """`plem --version`: plem's version, then exit."""
    if requested:
        typer.echo(f"plem {plem.__version__}")  # the version the package metadata is built from
        raise typer.Exit


@app.callback()
def _root(
    _version: Annotated[bool, typer.Option("--version", callback=_print_version, is_eager=True,
                                           help="Print plem's version and exit.")] = False,
) -> None:
    """Bring up, configure and run 6- and 7-axis robot arms."""


def _print_error(error: PlemError) -> None:
    """The error's WHAT/WHY/HOW block on stderr (the console is set up only when there is an error to print)."""
    from plem.cli.output import print_error as print_block

    print_block(error)


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
        _print_error(error)
        return error.exit_code
    except click_exceptions.NoArgsIsHelpError as error:   # a group given no command: its help is the answer
        error.show()
        return 2
    except click_exceptions.UsageError as error:
        _print_error(_usage_error(error))
        return 2
    except click_exceptions.ClickException as error:
        error.show()
        return error.exit_code
    except (typer.Abort, KeyboardInterrupt):
        return 130
    except Exception as error:  # noqa: BLE001 - a bug in plem: still no traceback unless asked for
        if os.environ.get("PLEM_DEBUG"):
            traceback.print_exc()
        _print_error(PlemError(
            f"Internal error: {type(error).__name__}: {error}",
            what="the command to finish or report a WHAT/WHY/HOW error",
            why="plem hit an unexpected condition (a bug)",
            how="rerun with PLEM_DEBUG=1 to see the traceback, and report it with the command you ran",
        ))
        return 1


def main() -> None:
    """Console entry point."""
    sys.exit(run())
