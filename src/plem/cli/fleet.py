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


def _open(dest: str, *tables: str) -> Dataset:
    """DEST opened with the views of `tables` (every table when none is named)."""
    from plem.fleet.dataset import open_dataset

    return open_dataset(dest, tables) if tables else open_dataset(dest)


def _since(text: str | None) -> datetime | None:
    from plem.fleet.dataset import parse_since

    return None if text is None else parse_since(text, datetime.now(UTC))


def _cell(value: Any) -> Any:
    """A value as JSON/CSV shows it: NaN and NA as null, numpy scalars as Python ones, times as ISO text."""
    if value is None or type(value).__name__ in {"NAType", "NaTType"}:
        return None
    if hasattr(value, "isoformat"):
        return value.isoformat()
    if hasattr(value, "item") and not isinstance(value, list | tuple | dict):
        value = value.item()
    if isinstance(value, float) and math.isnan(value):
        return None
    if hasattr(value, "tolist"):
        return value.tolist()
    return value


def _text(value: Any) -> str:
    """A value as a table cell: times to the millisecond in UTC, floats to 6 significant digits (CSV and JSON keep
    every digit)."""
    if isinstance(value, datetime) and _cell(value) is not None:
        return value.astimezone(UTC).strftime("%Y-%m-%d %H:%M:%S.%f")[:-3]
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
        writer.writerows([["" if cell is None else str(cell) for cell in map(_cell, row)] for row in rows])
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
    columns, rows = dataset.rows(sql)
    if columns:
        print_rows("Query", columns, rows, output, "The query returned no rows.")


def _print_frame(title: str, frame: Any, output: TableFormat, empty: str) -> None:
    columns, rows = _frame_rows(frame)
    print_rows(title, columns, rows, output, empty)


def _window(since: datetime | None) -> str:
    return f" since {since.isoformat()}" if since is not None else ""


@app.command()
def faults(
    dest: Dest,
    since: Since = None,
    window: Annotated[float, typer.Option("--window", min=0.001, metavar="SECONDS",
                                          help="Seconds of rt_raw before each fault to summarise.")] = 1.0,
    output: FormatOption = TableFormat.table,
) -> None:
    """Every fault across the robots, with the motion and timing of the seconds before it."""
    from plem.fleet import reports

    start = _since(since)
    dataset = _open(dest, "rt_raw", "rt_events", "rt_monitor_stats", "segments")
    report = reports.faults(dataset, start, window)
    _print_frame(f"Faults ({window:g} s before each)", report, output, f"No faults in {dest}{_window(start)}.")
    if output is TableFormat.table and not report.empty:
        counts = report["robot_id"].value_counts()
        stdout.print("Faults per robot: " + ", ".join(f"{robot} {count}" for robot, count in counts.items()),
                     markup=False, highlight=False)


@app.command()
def health(
    dest: Dest,
    since: Since = None,
    engine: Annotated[Engine, typer.Option("--engine", help="DuckDB on this machine, or a Dask cluster.")]
    = Engine.duckdb,
    scheduler: Annotated[str | None, typer.Option("--scheduler", metavar="tcp://HOST:8786", show_default=False,
                                                  help="With --engine dask: the cluster's scheduler "
                                                       "(default: a local cluster of 2 worker processes).")] = None,
    output: FormatOption = TableFormat.table,
    plot: Plot = None,
) -> None:
    """Overruns, missed periods, lost frames and wake-up latency percentiles per robot per day, and the trend."""
    from plem.fleet import health as report

    start = _since(since)
    if scheduler is not None and engine is not Engine.dask:
        from plem.errors import UsageError

        raise UsageError("--scheduler needs --engine dask", what="--scheduler with --engine dask",
                         why=f"--engine is {engine.value}", how="add --engine dask, or leave --scheduler out")
    dataset = _open(dest, "rt_raw", "rt_monitor_stats")
    if engine is Engine.dask:
        from plem.fleet import dask_engine

        with dask_engine.connect(scheduler) as client:
            aggregates = dask_engine.aggregates(dataset, start, client)
    else:
        aggregates = report.duckdb_aggregates(dataset, start)
    days = report.days(*aggregates)
    trend = report.trend(days)
    empty = f"No rt_raw or rt_monitor_stats rows in {dest}{_window(start)}."
    if output is TableFormat.json:
        print_json({"days": [_record(row) for row in days.to_dict("records")],
                    "trend": [_record(row) for row in trend.to_dict("records")]})
    else:
        _print_frame("Health per robot and day (latency in µs)", days, output, empty)
        if output is TableFormat.table and not trend.empty:
            _print_frame("Trend (least-squares change per week over the days)", trend, output, "")
            growing = [f"{robot} ({grows})" for robot, grows in zip(trend["robot_id"], trend["grows"], strict=True)
                       if grows]
            stdout.print("Growing week on week: " + ("; ".join(growing) if growing else "none"), markup=False,
                         highlight=False)
    if plot is not None and not days.empty:
        from plem.fleet import plots

        plots.health(days, plot)


def _record(row: dict[str, Any]) -> dict[str, Any]:
    return {key: _cell(value) for key, value in row.items()}


@app.command()
def usage(
    dest: Dest,
    since: Since = None,
    deadband: Annotated[float, typer.Option("--deadband", min=0.0, metavar="RAD/S",
                                            help="Velocities within ±this are no direction (for reversals).")]
    = 0.01,
    output: FormatOption = TableFormat.table,
    plot: Plot = None,
) -> None:
    """Travel, reversals and RMS effort per robot and joint, the most travelled first: what to service first."""
    from plem.fleet import reports

    start = _since(since)
    dataset = _open(dest, "rt_raw", "segments")
    report = reports.usage(dataset, start, deadband)
    _print_frame("Usage per joint (most travelled first)", report, output, f"No rt_raw rows in {dest}{_window(start)}.")
    if plot is not None and not report.empty:
        from plem.fleet import plots

        plots.usage(report, plot)
