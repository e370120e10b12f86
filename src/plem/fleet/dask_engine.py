"""The health report's aggregates as a Dask job: dask.dataframe over the same Parquet files, on a distributed
cluster (a scheduler's address) or a local one of worker processes.

Each task reads one file with pyarrow (its partition values from its path, columns it lacks as null, as the DuckDB
views read it) on a worker; the workers need plem installed and access to DEST (the same path, or the store with
its AWS_* variables). The aggregates are those of plem.fleet.health.duckdb_aggregates, so the report is the same.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import date, datetime
from typing import TYPE_CHECKING, Any

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from plem.fleet import schema
from plem.fleet.dataset import Dataset, FleetError, current_schema, partition_values
from plem.fleet.health import COUNTERS, HISTOGRAM_COLUMNS

if TYPE_CHECKING:
    import pandas as pd
    from distributed import Client
    from fsspec import AbstractFileSystem

LOCAL_WORKERS = 2
CONNECT_TIMEOUT_S = 10


def _partition_array(path: str, name: str, rows: int) -> pa.Array:
    value = partition_values(path)[name]
    if name == "date":
        return pa.array([date.fromisoformat(value)] * rows, pa.date32())
    return pa.array([value] * rows, pa.string())


def read_file(path: str, filesystem: AbstractFileSystem, table: str, columns: list[str]) -> pa.Table:
    """One file's `columns`: partition columns from its path, columns the file lacks as null (as the views)."""
    wanted = current_schema(table)
    local = "file" in (filesystem.protocol if isinstance(filesystem.protocol, tuple) else (filesystem.protocol,))
    with (open(path, "rb") if local else filesystem.open(path, "rb")) as handle:   # pyarrow reads local files natively
        parquet = pq.ParquetFile(handle)
        present = set(parquet.schema_arrow.names)
        data = parquet.read(columns=[name for name in columns if name in present])
    arrays = []
    for name in columns:
        if name in data.column_names:
            arrays.append(data.column(name).cast(wanted.field(name).type))
        elif name in ("robot_id", "date"):
            arrays.append(_partition_array(path, name, data.num_rows))
        else:
            arrays.append(pa.nulls(data.num_rows, wanted.field(name).type))
    return pa.table(arrays, names=columns)


def file_histogram(path: str, filesystem: AbstractFileSystem, since: datetime | None) -> pd.DataFrame:
    """One rt_raw file's latency histogram (robot_id, day, us, n, max_ns), counted where it is read."""
    data = read_file(path, filesystem, "rt_raw", ["time", "latency_ns"])
    keep = pc.is_valid(data.column("latency_ns"))
    if since is not None:
        keep = pc.and_(keep, pc.greater_equal(data.column("time"), pa.scalar(since, schema.TIME)))
    latency = data.filter(keep).column("latency_ns").cast(pa.int64())
    grouped = pa.table({"us": pc.divide(latency, 1000), "latency": latency}).group_by("us") \
        .aggregate([("latency", "count"), ("latency", "max")])
    rows = grouped.num_rows
    return pa.table({"robot_id": _partition_array(path, "robot_id", rows), "day": _partition_array(path, "date", rows),
                     "us": grouped.column("us"), "n": grouped.column("latency_count"),
                     "max_ns": grouped.column("latency_max")}).to_pandas()


def _files(dataset: Dataset, table: str, since: datetime | None) -> list[str]:
    """The table's files, those of dates before `since` left out."""
    files = dataset.files[table]
    if since is None:
        return files
    first = since.date().isoformat()
    return [path for path in files if partition_values(path).get("date", first) >= first]


def _from_files(function: Any, files: list[str], meta: pd.DataFrame, **arguments: Any) -> Any:
    """A dask DataFrame of `function(file, **arguments)` for every file, one task per partition directory (a robot's
    day: a task of a few tens of files keeps the scheduler's cost per task small); just `meta` without files."""
    import dask.dataframe as dd

    if not files:
        return dd.from_pandas(meta, npartitions=1)  # type: ignore[no-untyped-call]
    directories: dict[str, list[str]] = {}
    for path in files:
        directories.setdefault(path.rsplit("/", 1)[0], []).append(path)
    return dd.from_map(each_file, list(directories.values()), function=function, meta=meta,  # type: ignore[no-untyped-call]
                       enforce_metadata=False, **arguments)


def each_file(paths: list[str], function: Any, **arguments: Any) -> pd.DataFrame:
    """`function` over the files of one task, concatenated."""
    import pandas as pd

    frames = [frame for frame in (function(path, **arguments) for path in paths) if not frame.empty]
    return pd.concat(frames, ignore_index=True) if frames else function(paths[0], **arguments).iloc[:0]


def increases(values: np.ndarray, previous: np.ndarray) -> np.ndarray:
    """Each counter value's increase over the previous one: the whole value after a restart (a decrease) or with
    no previous value (NaN); NaN where the value is null (health's definition, as DuckDB's query computes it)."""
    with np.errstate(invalid="ignore"):
        restarted = np.isnan(previous) | (values < previous)
        return np.where(restarted, values, values - previous)


def _total(values: np.ndarray) -> float:
    """The sum of the known values; NaN when none is known (SQL's sum)."""
    known = values[~np.isnan(values)]
    return float(known.sum()) if len(known) else float("nan")


def file_counters(path: str, filesystem: AbstractFileSystem, since: datetime | None) -> pd.DataFrame:
    """One rt_monitor_stats file in a row: its first and last time and counter values, and the sum of the counters'
    increases within it (rows from `since`); the first row's increase needs the robot's previous file."""
    import pandas as pd

    sources = [source for _, source in COUNTERS]
    data = read_file(path, filesystem, "rt_monitor_stats", ["time", *sources]).sort_by("time")
    if data.num_rows == 0:
        return pd.DataFrame(columns=_COUNTER_PARTS)
    times = data.column("time").cast(pa.int64()).to_numpy()
    since_ns = -(2**63) if since is None else int(pa.scalar(since, schema.TIME).cast(pa.int64()).as_py())
    partitions = partition_values(path)
    row: dict[str, Any] = {"robot_id": partitions["robot_id"], "day": date.fromisoformat(partitions["date"]),
                           "first_ns": int(times[0]), "first_counted": bool(times[0] >= since_ns),
                           "in_range": bool(times[-1] >= since_ns)}
    for name, source in COUNTERS:
        values = data.column(source).cast(pa.float64()).to_numpy(zero_copy_only=False)
        row[f"{name}_first"], row[f"{name}_last"] = values[0], values[-1]
        row[f"{name}_inner"] = _total(increases(values[1:], values[:-1])[times[1:] >= since_ns])
    return pd.DataFrame([row], columns=_COUNTER_PARTS)


_COUNTER_PARTS = ["robot_id", "day", "first_ns", "first_counted", "in_range",
                  *(f"{name}_{part}" for name, _ in COUNTERS for part in ("first", "last", "inner"))]


def combine_counters(parts: pd.DataFrame) -> pd.DataFrame:
    """The counters' daily increases from the files' rows: each robot's files in time order (a robot's segments
    do not overlap), each file's first increase over the previous file's last value."""
    import pandas as pd

    rows = []
    for robot, files in parts.sort_values(["robot_id", "first_ns"], kind="stable").groupby("robot_id", sort=True):
        previous = {name: float("nan") for name, _ in COUNTERS}
        for file in files.to_dict("records"):
            row: dict[str, Any] = {"robot_id": robot, "day": file["day"]}
            for name, _ in COUNTERS:
                first = increases(np.array([file[f"{name}_first"]]), np.array([previous[name]]))
                counted = first if file["first_counted"] else np.array([float("nan")])
                row[name] = _total(np.array([counted[0], file[f"{name}_inner"]]))
                previous[name] = file[f"{name}_last"]
            if file["in_range"]:   # a file before `since` only gives the next one its last values
                rows.append(row)
    frame = pd.DataFrame(rows, columns=["robot_id", "day", *(name for name, _ in COUNTERS)])
    return frame.groupby(["robot_id", "day"], as_index=False).sum(min_count=1)


def aggregates(dataset: Dataset, since: datetime | None, client: Client) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The latency histogram and the counters' daily increases (as health.duckdb_aggregates), computed by Dask.

    A day is the file's `date` partition, the UTC date of its rows (as DuckDB's). Each file is reduced where it is
    read (its latency histogram; its counters' first and last values and inner increases), so only small frames
    travel; the counters' increases across files are joined in time order here."""
    import pandas as pd

    histogram_meta = pd.DataFrame({"robot_id": pd.Series(dtype=str), "day": pd.Series(dtype=object),
                                   "us": pd.Series(dtype="int64"), "n": pd.Series(dtype="int64"),
                                   "max_ns": pd.Series(dtype="int64")})
    parts = _from_files(file_histogram, _files(dataset, "rt_raw", since), histogram_meta,
                        filesystem=dataset.filesystem, since=since)
    histogram = parts.groupby(["robot_id", "day", "us"]).agg(n=("n", "sum"), max_ns=("max_ns", "max"), split_out=1)
    counter_meta = pd.DataFrame({column: pd.Series(dtype=object if column in ("robot_id", "day") else
                                                   bool if column in ("first_counted", "in_range") else
                                                   "int64" if column == "first_ns" else "float64")
                                 for column in _COUNTER_PARTS})
    counter_parts = _from_files(file_counters, dataset.files["rt_monitor_stats"], counter_meta,
                                filesystem=dataset.filesystem, since=since)
    histogram_frame, counter_frame = client.compute([histogram, counter_parts], sync=True)  # type: ignore[no-untyped-call]
    return (histogram_frame.reset_index().reindex(columns=list(HISTOGRAM_COLUMNS)),
            combine_counters(counter_frame))


@contextmanager
def connect(scheduler: str | None) -> Iterator[Client]:
    """A client of the cluster at `scheduler` (tcp://host:8786), or of a local cluster of worker processes started
    for the job and stopped after it."""
    from distributed import Client, LocalCluster

    if scheduler is None:
        with LocalCluster(n_workers=LOCAL_WORKERS, threads_per_worker=1, processes=True,  # type: ignore[no-untyped-call]
                          dashboard_address=":0", silence_logs=logging.ERROR) as cluster, \
                Client(cluster) as client:  # type: ignore[no-untyped-call]
            yield client
        return
    try:
        client = Client(scheduler, timeout=CONNECT_TIMEOUT_S)  # type: ignore[no-untyped-call]
    except (OSError, TimeoutError, ValueError) as error:
        raise FleetError(f"Cannot reach the Dask scheduler at {scheduler}", what="a running Dask scheduler at "
                         "--scheduler, with workers that have plem installed and can read DEST",
                         why=f"{type(error).__name__}: {error}",
                         how="start it (`dask scheduler` on the host, `dask worker tcp://HOST:8786` on each worker) "
                             "and pass --scheduler tcp://HOST:8786, or leave --scheduler out for a local "
                             "cluster") from None
    with client:
        yield client

