"""How the CLI talks to people: errors and warnings on stderr, tables and JSON on stdout."""

from __future__ import annotations

import json
import sys
from enum import StrEnum
from typing import TYPE_CHECKING, Any

from rich.console import Console

from plem.errors import PlemError

if TYPE_CHECKING:
    from rich.table import Table


class OutputFormat(StrEnum):
    """`--format` choices shared by every command that can print JSON."""

    text = "text"
    json = "json"


PIPE_WIDTH = 200  # when output goes to a file or pipe, do not squeeze tables to 80 columns

stdout = Console(width=None if sys.stdout.isatty() else PIPE_WIDTH)
stderr = Console(stderr=True, soft_wrap=True, highlight=False)


def print_error(error: PlemError) -> None:
    """The WHAT/WHY/HOW block, without markup interpretation (paths may contain brackets)."""
    stderr.print(error.render(), markup=False)


def new_table(title: str, *columns: str) -> Table:
    """A table whose cells fold rather than truncate, so no value is ever cut off."""
    from rich.table import Table  # only the commands that print a table need it

    table = Table(title=title)
    for column in columns:
        table.add_column(column, overflow="fold")
    return table


def print_warnings(warnings: list[str]) -> None:
    """Each warning as a WARNING: line on stderr, so it never mixes with the output on stdout."""
    for warning in warnings:
        stderr.print(f"WARNING: {warning}", markup=False)


def print_json(data: Any) -> None:
    """Machine-readable output: plain JSON on stdout, no colour codes."""
    sys.stdout.write(json.dumps(data, indent=2, default=str) + "\n")
