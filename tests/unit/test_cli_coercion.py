"""The direct conversion of command-line values gives what typer's gives: the same value or the same error."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest
import typer.main
from typer._click import Command, Context
from typer._click.exceptions import BadParameter
from typer._coercion import RuntimeParam, build_runtime_param
from typer.core import _TyperParameter

from plem.cli.app import app
from plem.cli.coercion import plain_runtime_param

TEXTS = ["", "text", "json", "JSON", " json", "0", "7", "-3", "007", "+7", "1_0", "1.5", "-0.5", "1.", ".5", " 7",
         "1e3", "nan", "inf", "9" * 40, "abc", ".", "/", "/nonexistent/x", "~", "a\x00b", "best_effort", "reliable",
         "RELIABLE", "urdf_file:=x.urdf.xacro"]


def parameters(command: Command, path: str) -> Iterator[tuple[str, Command, _TyperParameter]]:
    """Every typer parameter of `command` and of its subcommands, with the command path it belongs to."""
    for param in command.params:
        if isinstance(param, _TyperParameter):
            yield path, command, param
    for name in getattr(command, "commands", {}):
        yield from parameters(command.commands[name], f"{path} {name}")  # type: ignore[attr-defined]


PARAMETERS = list(parameters(typer.main.get_command(app), "plem"))


def outcome(runtime: RuntimeParam, value: Any, param: _TyperParameter, ctx: Context) -> tuple[str, str]:
    """The converted value's repr (NaN equals NaN) with its type, or the error message."""
    try:
        converted = runtime.coerce(value, param=param, ctx=ctx)
        return "value", f"{type(converted).__name__} {converted!r}"
    except BadParameter as error:
        return "error", error.format_message()


def test_every_command_parameter_is_covered() -> None:
    assert len(PARAMETERS) > 50
    assert {path for path, _, _ in PARAMETERS} >= {"plem validate", "plem config show", "plem topic hz"}


@pytest.mark.parametrize(("path", "command", "param"), PARAMETERS,
                         ids=[f"{path} {param.name}" for path, _, param in PARAMETERS])
def test_same_value_or_error_as_typer(path: str, command: Command, param: _TyperParameter) -> None:
    ctx = Context(command, info_name=path)
    multiple = param.multiple or param.nargs == -1
    texts = [*((text,) for text in TEXTS), tuple(TEXTS), ()] if multiple else TEXTS
    values: list[Any] = [param.default, None, *texts]
    direct, typer_own = plain_runtime_param(param.type_descriptor), build_runtime_param(param.type_descriptor)
    for value in values:
        assert outcome(direct, value, param, ctx) == outcome(typer_own, value, param, ctx), repr(value)
