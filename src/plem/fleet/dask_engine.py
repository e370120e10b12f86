"""The health report's aggregates as a Dask job: dask.dataframe over the same Parquet files, on a distributed
cluster (a scheduler's address) or a local one of worker processes.

Each task reads one file with pyarrow (its partition values from its path, columns it lacks as null, as the DuckDB
views read it) on a worker; the workers need plem installed and access to DEST (the same path, or the store with
its AWS_* variables). The aggregates are those of plem.fleet.health.duckdb_aggregates, so the report is the same.
"""

from __future__ import annotations

import logging
from datetime import date, datetime
from typing import TYPE_CHECKING, Any

import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from plem.fleet import schema
from plem.fleet.dataset import Dataset, FleetError, current_schema
from plem.fleet.health import COUNTERS, HISTOGRAM_COLUMNS

if TYPE_CHECKING:
    import pandas as pd
    from distributed import Client
    from fsspec import AbstractFileSystem

LOCAL_WORKERS = 2
CONNECT_TIMEOUT_S = 10


def _partitions(path: str) -> dict[str, str]:
    """A file's Hive partition values from its path (`robot_id=…/date=…/`)."""
    return dict(part.split("=", 1) for part in path.split("/") if "=" in part)


def _partition_array(path: str, name: str, rows: int) -> pa.Array:
    value = _partitions(path)[name]
    if name == "date":
        return pa.array([date.fromisoformat(value)] * rows, pa.date32())
    return pa.array([value] * rows, pa.string())


def read_file(path: str, filesystem: AbstractFileSystem, table: str, columns: list[str]) -> pa.Table:
    """One file's `columns`: partition columns from its path, columns the file lacks as null (as the views)."""
    wanted = current_schema(table)
    present = set(pq.read_schema(path, filesystem=filesystem).names)
    data = pq.read_table(path, filesystem=filesystem, columns=[name for name in columns if name in present])
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


def file_frame(path: str, filesystem: AbstractFileSystem, table: str, columns: list[str]) -> pd.DataFrame:
    """One file's `columns` as pandas (read_file's table)."""
    return read_file(path, filesystem, table, columns).to_pandas()


def _files(dataset: Dataset, table: str, since: datetime | None) -> list[str]:
    """The table's files, those of dates before `since` left out."""
    files = dataset.files[table]
    if since is None:
        return files
    first = since.date().isoformat()
    return [path for path in files if _partitions(path).get("date", first) >= first]


def _from_files(function: Any, files: list[str], meta: pd.DataFrame, **arguments: Any) -> Any:
    """A dask DataFrame of `function(file, **arguments)` for every file (just `meta` without files)."""
    import dask.dataframe as dd

    if not files:
        return dd.from_pandas(meta, npartitions=1)  # type: ignore[no-untyped-call]
    return dd.from_map(function, files, meta=meta, enforce_metadata=False,  # type: ignore[no-untyped-call]
                       **arguments)


def _increases(group: pd.DataFrame) -> pd.DataFrame:
    """A robot's counters as increases in time order (a counter going down restarted: its value is all increase)."""
    ordered = group.sort_values("time", kind="stable")
    result = ordered[["time", "date"]].copy()
    result.insert(0, "robot_id", group.name)   # the group's key (pandas leaves it out of the group's columns)
    for name, source in COUNTERS:
        values = ordered[source].astype("float64")
        previous = values.shift()
        result[name] = values.where(previous.isna() | (values < previous), values - previous)
    return result


def aggregates(dataset: Dataset, since: datetime | None, client: Client) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The latency histogram and the counters' daily increases (as health.duckdb_aggregates), computed by Dask.

    A day is the file's `date` partition, the UTC date of its rows (as DuckDB's), so each file's histogram is
    counted where the file is read and only the small histograms travel."""
    import pandas as pd

    histogram_meta = pd.DataFrame({"robot_id": pd.Series(dtype=str), "day": pd.Series(dtype=object),
                                   "us": pd.Series(dtype="int64"), "n": pd.Series(dtype="int64"),
                                   "max_ns": pd.Series(dtype="int64")})
    parts = _from_files(file_histogram, _files(dataset, "rt_raw", since), histogram_meta,
                        filesystem=dataset.filesystem, since=since)
    histogram = parts.groupby(["robot_id", "day", "us"]).agg(n=("n", "sum"), max_ns=("max_ns", "max"))

    columns = ["robot_id", "date", "time", *(source for _, source in COUNTERS)]
    stats_meta = current_schema("rt_monitor_stats").empty_table().select(columns).to_pandas()
    stats = _from_files(file_frame, dataset.files["rt_monitor_stats"], stats_meta, filesystem=dataset.filesystem,
                        table="rt_monitor_stats", columns=columns)
    meta = pd.DataFrame({"robot_id": pd.Series(dtype=str), "time": pd.Series(dtype="datetime64[ns, UTC]"),
                         "date": pd.Series(dtype=object), **{name: pd.Series(dtype="float64") for name, _ in COUNTERS}})
    increases = stats.groupby("robot_id", group_keys=False).apply(_increases, meta=meta)
    if since is not None:
        increases = increases[increases["time"] >= pd.Timestamp(since)]
    counters = increases.rename(columns={"date": "day"}).groupby(["robot_id", "day"])[
        [name for name, _ in COUNTERS]].sum(min_count=1)

    histogram_frame, counters_frame = client.compute([histogram, counters], sync=True)  # type: ignore[no-untyped-call]
    return histogram_frame.reset_index().reindex(columns=list(HISTOGRAM_COLUMNS)), counters_frame.reset_index()


def connect(scheduler: str | None) -> Client:
    """A client of the cluster at `scheduler` (tcp://host:8786), or of a new local cluster of worker processes."""
    from distributed import Client, LocalCluster

    if scheduler is None:
        cluster = LocalCluster(n_workers=LOCAL_WORKERS, threads_per_worker=1, processes=True,  # type: ignore[no-untyped-call]
                               dashboard_address=None, silence_logs=logging.ERROR)
        return Client(cluster)  # type: ignore[no-untyped-call]
    try:
        return Client(scheduler, timeout=CONNECT_TIMEOUT_S)  # type: ignore[no-untyped-call]
    except (OSError, TimeoutError, ValueError) as error:
        raise FleetError(f"Cannot reach the Dask scheduler at {scheduler}", what="a running Dask scheduler at "
                         "--scheduler, with workers that have plem installed and can read DEST",
                         why=f"{type(error).__name__}: {error}",
                         how="start it (`dask scheduler` on the host, `dask worker tcp://HOST:8786` on each worker) "
                             "and pass --scheduler tcp://HOST:8786, or leave --scheduler out for a local "
                             "cluster") from None

