"""Flags take no value: `--help` shows them without a value type, and `plem --version true` is a usage error."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
import typer
from typer.core import TyperGroup as Group

from plem.cli.app import app, run


def command_paths() -> Iterator[list[str]]:
    """Every command and subcommand of `plem`, as the words that name it."""
    def walk(group: Group, path: list[str]) -> Iterator[list[str]]:
        for name in group.list_commands(None):  # type: ignore[arg-type]  # the root group needs no context
            command = group.get_command(None, name)  # type: ignore[arg-type]
            yield [*path, name]
            if isinstance(command, Group):
                yield from walk(command, [*path, name])
    root = typer.main.get_command(app)
    assert isinstance(root, Group)
    yield []
    yield from walk(root, [])


def test_help_shows_flags_without_a_value_type(capsys: pytest.CaptureFixture[str]):
    seen = 0
    for path in command_paths():
        run([*path, "--help"])
        text = capsys.readouterr().out
        assert "<bool>" not in text, (path, text)
        seen += "--help" in text or path == ["launch"]
    assert seen > 30


@pytest.mark.parametrize("extra", [["true"], ["false"], ["state"]])
def test_version_takes_no_value(capsys: pytest.CaptureFixture[str], extra: list[str]):
    assert run(["--version", *extra]) == 2
    err = capsys.readouterr().err
    assert "ERROR: --version takes no value" in err and "WHAT:" in err and "HOW: run `plem --version`" in err, err


def test_version_alone_prints_it(capsys: pytest.CaptureFixture[str]):
    assert run(["--version"]) == 0
    assert capsys.readouterr().out.startswith("plem ")
