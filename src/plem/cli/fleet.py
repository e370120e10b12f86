"""`plem fleet query|faults|health|usage`: SQL and ready-made reports over a fleet's exported dataset.

DEST is the directory or `s3://bucket/prefix` that `plem bag export --to` (or the recorder's `export_dir:=`) writes.
The dataset modules (DuckDB, pyarrow, Dask) are imported inside the commands so other commands start fast.
"""

from __future__ import annotations

import csv
import math
import sys
from datetime import UTC, datetime
from enum import StrEnum
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from plem.cli.output import new_table, print_json, stdout

if TYPE_CHECKING:
    from plem.fleet.dataset import Dataset

app = typer.Typer(help="Query a fleet's exported recordings (SQL and ready-made reports).", no_args_is_help=True)


class TableFormat(StrEnum):
    """`--format` of the fleet commands."""

    table = "table"
    csv = "csv"
    json = "json"


class Engine(StrEnum):
    """Where `plem fleet health` runs: DuckDB in this process, or a Dask cluster."""

    duckdb = "duckdb"
    dask = "dask"


Dest = Annotated[str, typer.Argument(metavar="DEST", show_default=False,
                                     help="The dataset: a directory or s3://bucket/prefix (AWS_* variables).")]
FormatOption = Annotated[TableFormat, typer.Option("--format", help="Output as a table, CSV or JSON.")]
Since = Annotated[str | None, typer.Option("--since", metavar="DATE|DURATION", show_default=False,
                                           help="Only data from this UTC date/time (2026-11-01) or this long ago "
                                                "(7d, 12h, 30m).")]
Plot = Annotated[Path | None, typer.Option("--plot", metavar="PNG", show_default=False,
                                           help="Also draw the report into this PNG file.")]


def _open(dest: str) -> Dataset:
    from plem.fleet.dataset import open_dataset

    return open_dataset(dest)


def _since(text: str | None) -> datetime | None:
    from plem.fleet.dataset import parse_since

    return None if text is None else parse_since(text, datetime.now(UTC))


def _cell(value: Any) -> Any:
    """A value as JSON/CSV shows it: NaN and NA as null, numpy scalars as Python ones, times as ISO text."""
    if value is None:
        return None
    if hasattr(value, "isoformat"):
        return value.isoformat()
    if hasattr(value, "item") and not isinstance(value, list | tuple | dict):
        value = value.item()
    if isinstance(value, float) and math.isnan(value):
        return None
    if type(value).__name__ in {"NAType", "NaTType"}:
        return None
    if hasattr(value, "tolist"):
        return value.tolist()
    return value


def _text(value: Any) -> str:
    cell = _cell(value)
    if cell is None:
        return ""
    if isinstance(cell, float):
        return f"{cell:.6g}"
    return str(cell)


def print_rows(title: str, columns: list[str], rows: list[tuple[Any, ...]], output: TableFormat,
               empty: str) -> None:
    """Rows as a rich table (saying `empty` when there are none), CSV with a header, or a JSON list of objects."""
    if output is TableFormat.json:
        print_json([{column: _cell(value) for column, value in zip(columns, row, strict=True)} for row in rows])
    elif output is TableFormat.csv:
        writer = csv.writer(sys.stdout, lineterminator="\n")
        writer.writerow(columns)
        writer.writerows([[_text(value) for value in row] for row in rows])
    elif not rows:
        stdout.print(empty, markup=False, highlight=False)
    else:
        table = new_table(title, *columns)
        for row in rows:
            table.add_row(*(_text(value) for value in row))
        stdout.print(table)


def _frame_rows(frame: Any) -> tuple[list[str], list[tuple[Any, ...]]]:
    return [str(column) for column in frame.columns], list(frame.itertuples(index=False, name=None))


@app.command()
def query(
    dest: Dest,
    sql: Annotated[str, typer.Argument(metavar="SQL", show_default=False,
                                       help="A DuckDB query over the views rt_raw, rt_events, rt_monitor_stats, "
                                            "joint_states and segments.")],
    output: FormatOption = TableFormat.table,
) -> None:
    """Run SQL over the dataset with DuckDB (each table is a view: robot_id and date are columns)."""
    dataset = _open(dest)
    relation = dataset.sql(sql)
    if relation is None:
        return
    print_rows("Query", list(relation.columns), relation.fetchall(), output, "The query returned no rows.")
