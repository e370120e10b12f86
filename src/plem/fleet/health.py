"""The health report: per robot per day, the loop's overruns, missed periods, lost frames and wake-up latency
percentiles, and each robot's trend over the days.

An engine (DuckDB here, Dask in plem.fleet.dask_engine) computes two aggregates, and this module turns them into the
report, so both engines answer alike by construction:

- the latency histogram: per robot, UTC day and whole microsecond of wake-up latency (`latency_ns // 1000`), the
  cycles and their largest latency in ns;
- the counters: per robot and UTC day, the sum of the increases of rt_monitor_stats' cumulative counters
  (overruns, missed_periods, bus_lost_frames) in time order; a counter that goes down restarted with a new run, so
  its value then is all increase (as is a robot's first value).

A percentile is the nearest-rank one over the day's cycles, in whole microseconds: the smallest whole microsecond
at or below which at least that share of the cycles woke (exact, from the histogram, in integer arithmetic).
"""

from __future__ import annotations

from datetime import datetime, timedelta
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    import pandas as pd

    from plem.fleet.dataset import Dataset

#: Percentiles reported, as (column, numerator, denominator) of the share.
PERCENTILES = (("latency_p50_us", 50, 100), ("latency_p99_us", 99, 100), ("latency_p999_us", 999, 1000))
COUNTERS = (("overruns", "overruns"), ("missed_periods", "missed_periods"), ("lost_frames", "bus_lost_frames"))
HISTOGRAM_COLUMNS = ("robot_id", "day", "us", "n", "max_ns")
DAY_COLUMNS = ("robot_id", "day", "cycles", *(name for name, _ in COUNTERS), *(name for name, _, _ in PERCENTILES),
               "latency_max_us")
#: The figures whose trend is reported, and their units per day.
TREND_FIGURES = (("latency_p99_us", "µs"), ("overruns", "overruns"), ("missed_periods", "missed periods"),
                 ("lost_frames", "lost frames"))


def nearest_rank(us: np.ndarray, counts: np.ndarray, numerator: int, denominator: int) -> int:
    """The nearest-rank percentile numerator/denominator of a histogram (bins `us` ascending, `counts` cycles)."""
    cumulative = np.cumsum(counts)
    rank = -(-int(cumulative[-1]) * numerator // denominator)   # ceil(N · share) in integers
    return int(us[int(np.searchsorted(cumulative, max(rank, 1)))])


def percentiles(histogram: pd.DataFrame, keys: list[str]) -> pd.DataFrame:
    """Per group of `keys`: cycles, the PERCENTILES and the largest latency (µs) from a latency histogram."""
    import pandas as pd

    rows: list[dict[str, Any]] = []
    for key, group in histogram.sort_values([*keys, "us"]).groupby(keys, sort=True):
        us, counts = group["us"].to_numpy(dtype=np.int64), group["n"].to_numpy(dtype=np.int64)
        row = dict(zip(keys, key if isinstance(key, tuple) else (key,), strict=True))
        row["cycles"] = int(counts.sum())
        row.update({name: nearest_rank(us, counts, numerator, denominator)
                    for name, numerator, denominator in PERCENTILES})
        row["latency_max_us"] = float(group["max_ns"].max()) / 1000
        rows.append(row)
    columns = [*keys, "cycles", *(name for name, _, _ in PERCENTILES), "latency_max_us"]
    return pd.DataFrame(rows, columns=columns)


def days(histogram: pd.DataFrame, counters: pd.DataFrame) -> pd.DataFrame:
    """The report's rows, one per robot and day with data in either aggregate, sorted by robot and day."""
    import pandas as pd

    latency = percentiles(histogram, ["robot_id", "day"])
    counters = counters.assign(day=pd.to_datetime(counters["day"]).dt.date)
    latency = latency.assign(day=pd.to_datetime(latency["day"]).dt.date)
    merged = latency.merge(counters, on=["robot_id", "day"], how="outer")
    merged = merged.reindex(columns=list(DAY_COLUMNS)).sort_values(["robot_id", "day"]).reset_index(drop=True)
    for column in DAY_COLUMNS[2:-1]:
        merged[column] = merged[column].astype("Int64")
    merged["latency_max_us"] = merged["latency_max_us"].astype("float64")
    merged["robot_id"] = merged["robot_id"].astype(str)
    return merged


def trend(report: pd.DataFrame) -> pd.DataFrame:
    """Per robot: the least-squares change per week of each TREND_FIGURE over its days, and which ones grow."""
    import pandas as pd

    rows: list[dict[str, Any]] = []
    for robot, group in report.groupby("robot_id", sort=True):
        day_numbers = np.array([(day - group["day"].iloc[0]).days for day in group["day"]], dtype=float)
        row: dict[str, Any] = {"robot_id": robot, "days": len(group)}
        growing = []
        for figure, _unit in TREND_FIGURES:
            values = group[figure].to_numpy(dtype=float, na_value=np.nan)
            known = ~np.isnan(values)
            slope = float("nan")
            if known.sum() >= 2 and np.ptp(day_numbers[known]) > 0:
                slope = float(np.polyfit(day_numbers[known], values[known], 1)[0]) * 7
                if slope > 1e-9:
                    growing.append(figure)
            row[f"{figure}_per_week"] = round(slope, 6) + 0.0   # + 0.0: no "-0" for a flat line
        row["grows"] = ", ".join(growing)
        rows.append(row)
    columns = ["robot_id", "days", *(f"{figure}_per_week" for figure, _ in TREND_FIGURES), "grows"]
    return pd.DataFrame(rows, columns=columns)


def duckdb_aggregates(dataset: Dataset, since: datetime | None) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The latency histogram and the counters' daily increases, computed by DuckDB over the views."""
    where, parameters = since_filter(since)
    histogram = dataset.frame(
        "SELECT robot_id, date AS day, CAST(latency_ns // 1000 AS BIGINT) AS us, count(*) AS n, "
        f"CAST(max(latency_ns) AS BIGINT) AS max_ns FROM rt_raw WHERE latency_ns IS NOT NULL {where} GROUP BY ALL",
        parameters)
    lags = ", ".join(f"lag({source}) OVER w AS previous_{name}" for name, source in COUNTERS)
    sums = ", ".join(f"CAST(sum(CASE WHEN previous_{name} IS NULL OR {source} < previous_{name} THEN {source} "
                     f"ELSE {source} - previous_{name} END) AS BIGINT) AS {name}" for name, source in COUNTERS)
    sources = ", ".join(source for _, source in COUNTERS)
    counters = dataset.frame(
        f"WITH ordered AS (SELECT robot_id, date, time, {sources}, {lags} FROM rt_monitor_stats "
        "WINDOW w AS (PARTITION BY robot_id ORDER BY time)) "
        f"SELECT robot_id, date AS day, {sums} FROM ordered WHERE true {where} GROUP BY ALL",
        parameters)
    return histogram, counters


def since_filter(since: datetime | None) -> tuple[str, list[Any]]:
    """An `AND …` clause keeping rows from `since` (pruning date partitions that end before it)."""
    if since is None:
        return "", []
    return "AND date >= ? AND time >= ?", [(since - timedelta(days=1)).date(), since]
