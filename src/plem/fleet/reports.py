"""The faults and usage reports, computed by DuckDB over a dataset's views.

faults: every rt_events row of kind `fault`, with what rt_raw holds of the seconds before it (the window): the peak
|velocity|, the peak following error |command_position − position| and the peak |effort| over the arm's joints
(with the joint), the wake-up latency p99 (nearest rank, whole µs, as in the health report) and max, the largest
compute time, and the cycles present against those expected: the window's length at the robot's period
(rt_monitor_stats' period_ns), or fewer when the loop had run fewer (its cycle number, counted from 0 at its start).

usage: per robot and joint, the travel Σ|Δposition| between consecutive cycles in time order, the reversals (the
velocity's sign changing between samples beyond ±deadband; samples inside it are skipped) and the RMS effort.
"""

from __future__ import annotations

from datetime import datetime, timedelta
from typing import TYPE_CHECKING, Any

from plem.fleet.health import percentiles, since_filter

if TYPE_CHECKING:
    import pandas as pd

    from plem.fleet.dataset import Dataset

DEFAULT_PERIOD_NS = 1_000_000
FAULT_COLUMNS = ("robot_id", "time", "cycle", "cause", "reason", "mode", "previous_mode", "cycles", "expected", "lost",
                 "peak_velocity", "velocity_joint", "peak_following_error", "following_joint", "peak_effort",
                 "effort_joint", "latency_p99_us", "latency_max_us", "compute_max_us")
USAGE_COLUMNS = ("robot_id", "joint", "joint_name", "travel", "reversals", "rms_effort", "samples")
#: The peaks of the fault window: (column, SQL of one joint j, the joint's column).
_PEAKS = (("peak_velocity", "abs(velocity_{j})", "velocity_joint"),
          ("peak_following_error", "abs(command_position_{j} - position_{j})", "following_joint"),
          ("peak_effort", "abs(effort_{j})", "effort_joint"))


def joint_count(dataset: Dataset) -> int:
    """The most joints any robot of the dataset has (rt_raw's position_N columns)."""
    names = [row[0] for row in dataset.rows("DESCRIBE rt_raw")[1]]
    return sum(1 for name in names if name.startswith("position_"))


def joint_names(dataset: Dataset) -> dict[str, list[str]]:
    """Each robot's joint names, from its latest segment."""
    frame = dataset.frame("SELECT robot_id, arg_max(joint_names, start) AS names FROM segments GROUP BY robot_id")
    return {str(robot): list(names) if names is not None else [] for robot, names in
            zip(frame["robot_id"], frame["names"], strict=True)}


def _joint_label(names: dict[str, list[str]], robot: str, joint: Any) -> str | None:
    if joint is None or joint != joint:
        return None
    robot_names = names.get(robot, [])
    return robot_names[int(joint)] if int(joint) < len(robot_names) else f"joint {int(joint)}"


def faults(dataset: Dataset, since: datetime | None, window_s: float) -> pd.DataFrame:
    """The faults report's rows, oldest first (an empty frame of FAULT_COLUMNS when there is none)."""
    import pandas as pd

    where, parameters = since_filter(since)
    found = dataset.frame("SELECT robot_id, time, cycle, cause, reason, mode, previous_mode FROM rt_events "
                          f"WHERE kind = 'fault' {where} ORDER BY time, robot_id", parameters)
    if found.empty:
        return pd.DataFrame(columns=list(FAULT_COLUMNS))
    found["id"] = range(len(found))
    found["start"] = found["time"] - timedelta(seconds=window_s)
    dataset.connection.register("_faults", found[["id", "robot_id", "start", "time"]])
    joints = joint_count(dataset)
    peaks = ", ".join(f"{sql.format(j=j)} AS {column}_{j}" for column, sql, _ in _PEAKS for j in range(joints))
    window = ("FROM _faults f JOIN rt_raw r ON r.robot_id = f.robot_id AND r.time >= f.start AND r.time < f.time "
              "WHERE r.time >= ? AND r.time < ? AND r.date >= ? AND r.date <= ?")
    first, last = found["start"].min().to_pydatetime(), found["time"].max().to_pydatetime()
    bounds = [first, last, first.date() - timedelta(days=1), last.date()]   # a segment's date is where it started
    stats = dataset.frame(
        f"WITH w AS (SELECT f.id, r.latency_ns, r.compute_ns, {peaks} {window}) "
        "SELECT id, count(*) AS cycles, max(compute_ns) / 1000.0 AS compute_max_us, "
        + ", ".join(f"max({column}_{j}) AS {column}_{j}" for column, _, _ in _PEAKS for j in range(joints))
        + " FROM w GROUP BY id", bounds)
    histogram = dataset.frame(
        f"SELECT f.id, CAST(r.latency_ns // 1000 AS BIGINT) AS us, count(*) AS n, CAST(max(r.latency_ns) AS BIGINT) "
        f"AS max_ns {window} AND r.latency_ns IS NOT NULL GROUP BY ALL", bounds)
    latency = percentiles(histogram, ["id"])[["id", "latency_p99_us", "latency_max_us"]] if not histogram.empty \
        else pd.DataFrame(columns=["id", "latency_p99_us", "latency_max_us"])
    period = dataset.frame("SELECT robot_id, median(period_ns) AS period_ns FROM rt_monitor_stats GROUP BY robot_id")
    report = found.merge(stats, on="id", how="left").merge(latency, on="id", how="left") \
        .merge(period, on="robot_id", how="left")
    report["cycles"] = report["cycles"].fillna(0).astype("int64")
    periods = report["period_ns"].fillna(DEFAULT_PERIOD_NS).astype(float)
    in_window = (window_s * 1e9 / periods).round()
    run_so_far = report["cycle"].astype("float64").fillna(in_window)   # the loop counts cycles from 0 at its start
    report["expected"] = in_window.where(in_window <= run_so_far, run_so_far).astype("int64")
    report["lost"] = (report["expected"] - report["cycles"]).clip(lower=0)
    names = joint_names(dataset)
    for column, _, joint_column in _PEAKS:
        values = report[[f"{column}_{j}" for j in range(joints)]].astype(float)
        report[column] = values.max(axis=1, skipna=True)
        best = values.fillna(-1.0).to_numpy().argmax(axis=1)
        report[joint_column] = [_joint_label(names, robot, joint if peak == peak else None)
                                for robot, joint, peak in zip(report["robot_id"], best, report[column], strict=True)]
    return report.reindex(columns=list(FAULT_COLUMNS))


def usage(dataset: Dataset, since: datetime | None, deadband: float) -> pd.DataFrame:
    """The usage report's rows, the most travelled joint first."""
    import pandas as pd

    where, parameters = since_filter(since)
    joints = joint_count(dataset)
    window = "OVER (PARTITION BY robot_id ORDER BY time)"
    inner = ", ".join(
        f"abs(position_{j} - lag(position_{j}) {window}) AS step_{j}, "
        f"CASE WHEN abs(velocity_{j}) > {deadband!r} THEN sign(velocity_{j}) END AS sign_{j}, "
        f"lag(CASE WHEN abs(velocity_{j}) > {deadband!r} THEN sign(velocity_{j}) END IGNORE NULLS) {window} "
        f"AS previous_sign_{j}, effort_{j}, position_{j}" for j in range(joints))
    outer = ", ".join(
        f"sum(step_{j}) AS travel_{j}, count(*) FILTER (WHERE sign_{j} <> previous_sign_{j}) AS reversals_{j}, "
        f"sqrt(avg(effort_{j} * effort_{j})) AS rms_effort_{j}, count(position_{j}) AS samples_{j}"
        for j in range(joints))
    frame = dataset.frame(f"WITH d AS (SELECT robot_id, {inner} FROM rt_raw WHERE true {where}) "
                          f"SELECT robot_id, {outer} FROM d GROUP BY robot_id", parameters)
    names = joint_names(dataset)
    rows = [{"robot_id": robot, "joint": j, "joint_name": _joint_label(names, robot, j),
             "travel": float(row[f"travel_{j}"]) if row[f"travel_{j}"] == row[f"travel_{j}"] else 0.0,
             "reversals": int(row[f"reversals_{j}"]), "rms_effort": row[f"rms_effort_{j}"],
             "samples": int(row[f"samples_{j}"])}
            for robot, row in zip(frame["robot_id"], frame.to_dict("records"), strict=True) for j in range(joints)
            if row[f"samples_{j}"] > 0]
    result = pd.DataFrame(rows, columns=list(USAGE_COLUMNS))
    return result.sort_values(["travel", "reversals", "robot_id", "joint"], ascending=[False, False, True, True]) \
        .reset_index(drop=True)
