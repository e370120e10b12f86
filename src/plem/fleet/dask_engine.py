"""The health report's aggregates as a Dask job: dask.dataframe over the same Parquet files, on a distributed
cluster (a scheduler's address) or a local one of worker processes.

Each task reads one file with pyarrow (its partition values from its path, columns it lacks as null, as the DuckDB
views read it) on a worker; the workers need plem installed and access to DEST (the same path, or the store with
its AWS_* variables). The aggregates are those of plem.fleet.health.duckdb_aggregates, so the report is the same.
"""

from __future__ import annotations

import logging
from datetime import datetime, timedelta
from typing import TYPE_CHECKING, Any

import pyarrow as pa
import pyarrow.parquet as pq

from plem.fleet.dataset import Dataset, FleetError, current_schema
from plem.fleet.health import COUNTERS, HISTOGRAM_COLUMNS

if TYPE_CHECKING:
    import pandas as pd
    from distributed import Client
    from fsspec import AbstractFileSystem

LOCAL_WORKERS = 2
CONNECT_TIMEOUT_S = 10


def read_file(path: str, filesystem: AbstractFileSystem, table: str, columns: list[str]) -> pd.DataFrame:
    """One file's `columns` as pandas: partition columns from its path, columns the file lacks as null."""
    wanted = current_schema(table)
    present = set(pq.read_schema(path, filesystem=filesystem).names)
    data = pq.read_table(path, filesystem=filesystem, columns=[name for name in columns if name in present])
    partitions = dict(part.split("=", 1) for part in path.split("/") if "=" in part)
    arrays = []
    for name in columns:
        if name in data.column_names:
            arrays.append(data.column(name).cast(wanted.field(name).type))
        elif name == "robot_id":
            arrays.append(pa.array([partitions["robot_id"]] * data.num_rows, pa.string()))
        else:
            arrays.append(pa.nulls(data.num_rows, wanted.field(name).type))
    return pa.table(arrays, names=columns).to_pandas()


def _frame(dataset: Dataset, table: str, columns: list[str], since: datetime | None) -> Any:
    """The table's files (those of dates before `since` left out) as one dask DataFrame of `columns`."""
    import dask.dataframe as dd

    files = dataset.files[table]
    if since is not None:
        first = (since.date() - timedelta(days=1)).isoformat()
        files = [path for path in files if _date_of(path) >= first]
    meta = current_schema(table).empty_table().select(columns).to_pandas()
    if not files:
        return dd.from_pandas(meta, npartitions=1)  # type: ignore[no-untyped-call]
    return dd.from_map(read_file, files, filesystem=dataset.filesystem, table=table, columns=columns, meta=meta,  # type: ignore[no-untyped-call]
                       enforce_metadata=False)


def _date_of(path: str) -> str:
    return next((part.removeprefix("date=") for part in path.split("/") if part.startswith("date=")), "")


def _increases(group: pd.DataFrame) -> pd.DataFrame:
    """A robot's counters as increases in time order (a counter going down restarted: its value is all increase)."""
    ordered = group.sort_values("time", kind="stable")
    result = ordered[["time"]].copy()
    result.insert(0, "robot_id", group.name)   # the group's key (pandas leaves it out of the group's columns)
    for name, source in COUNTERS:
        values = ordered[source].astype("float64")
        previous = values.shift()
        result[name] = values.where(previous.isna() | (values < previous), values - previous)
    return result


def aggregates(dataset: Dataset, since: datetime | None, client: Client) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The latency histogram and the counters' daily increases (as health.duckdb_aggregates), computed by Dask."""
    import pandas as pd

    raw = _frame(dataset, "rt_raw", ["robot_id", "time", "latency_ns"], since)
    raw = raw[raw["latency_ns"].notnull()]
    if since is not None:
        raw = raw[raw["time"] >= pd.Timestamp(since)]
    raw = raw.assign(day=raw["time"].dt.floor("D"), us=(raw["latency_ns"].astype("int64") // 1000),
                     max_ns=raw["latency_ns"].astype("int64"))
    histogram = raw.groupby(["robot_id", "day", "us"]).agg(n=("max_ns", "count"), max_ns=("max_ns", "max"))

    sources = [source for _, source in COUNTERS]
    stats = _frame(dataset, "rt_monitor_stats", ["robot_id", "time", *sources], since=None)
    meta = pd.DataFrame({"robot_id": pd.Series(dtype=str), "time": pd.Series(dtype="datetime64[ns, UTC]"),
                         **{name: pd.Series(dtype="float64") for name, _ in COUNTERS}})
    increases = stats.groupby("robot_id", group_keys=False).apply(_increases, meta=meta)
    if since is not None:
        increases = increases[increases["time"] >= pd.Timestamp(since)]
    increases = increases.assign(day=increases["time"].dt.floor("D"))
    counters = increases.groupby(["robot_id", "day"])[[name for name, _ in COUNTERS]].sum(min_count=1)

    histogram_frame, counters_frame = client.compute([histogram, counters], sync=True)  # type: ignore[no-untyped-call]
    histogram_frame = histogram_frame.reset_index().reindex(columns=list(HISTOGRAM_COLUMNS))
    return _dated(histogram_frame), _dated(counters_frame.reset_index())


def _dated(frame: pd.DataFrame) -> pd.DataFrame:
    """`day` as a date (a UTC midnight from Dask; a date from DuckDB)."""
    frame["day"] = frame["day"].dt.date
    return frame


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

