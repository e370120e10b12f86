"""Synthetic fleet datasets in the exported layout, whose report answers are known by construction.

The tests and the fleet benchmark write them; every file is what an export writes (`plem.fleet.schema`'s tables,
Hive partitions `robot_id=…/date=…/`, one file per segment). A run is one recording session of one robot:

- every joint moves as `AMPLITUDE[j] · sin(2π t / PERIOD_S)` from t = 0, so a whole number of periods travels
  `4 · AMPLITUDE[j]` per period and reverses twice per period; its effort is `EFFORT[j] · cos(2π t / PERIOD_S)`
  (RMS `EFFORT[j] / √2` over whole periods), and the command leads the position by `FOLLOWING[j]`;
- wake-up latency repeats a shuffled pattern every 1000 cycles: `latency_base_us` µs plus 0, 100, …, 99 900 ns,
  so over whole seconds the whole-microsecond percentiles are base + 49 (p50), base + 98 (p99), base + 99 (p99.9);
- the cumulative counters (overruns, missed periods, lost frames) climb evenly from 0 to the run's totals;
- a fault is an rt_events row (kind `fault`), with the mode changes into and out of operation around the run;
- a segment's rows are split by their UTC date, as the export writes them (the `date` partition is that date).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from plem.fleet import schema

PERIOD_S = 4.0
#: Per joint (index j): motion amplitude (rad), effort amplitude (N·m) and the command's lead (rad).
AMPLITUDE = tuple(0.1 * (j + 1) for j in range(7))
EFFORT = tuple(10.0 * (j + 1) for j in range(7))
FOLLOWING = tuple(1e-4 * (j + 1) for j in range(7))
LATENCY_PATTERN = 1000  # cycles after which the latency pattern repeats
_SPREAD_NS = np.random.default_rng(33).permutation(LATENCY_PATTERN).astype(np.uint32) * 100
STATS_RATE_HZ = 10
JOINT_STATES_EVERY = 10  # rt_raw cycles per joint_states row
_EPOCH = datetime(1970, 1, 1, tzinfo=UTC)


@dataclass(frozen=True)
class Fault:
    """A fault `at_s` seconds into its run."""

    at_s: float
    cause: str = "tracking_error"
    reason: str = "joint 1 followed its command by more than the tracking tolerance"


@dataclass(frozen=True)
class Run:
    """One robot's recording session: rows from `start` for `seconds`, its counters starting at zero."""

    robot_id: str
    dof: int
    start: datetime
    seconds: int
    latency_base_us: int = 10
    overruns: int = 0
    missed_periods: int = 0
    lost_frames: int = 0
    faults: tuple[Fault, ...] = ()
    #: [from, to) seconds of the run whose rt_raw rows are missing (cycles lost before the recorder).
    gaps: tuple[tuple[float, float], ...] = ()
    segment_seconds: int = 60
    rate_hz: int = 1000
    model: str = "indy7"
    first_cycle: int = 0   # the loop counts cycles from 0 at its start


def write_runs(dest: Path, runs: list[Run], compression: str = "zstd") -> list[Path]:
    """Write every run's segments under `dest`; returns the files written."""
    return [path for run in runs for path in write_run(dest, run, compression)]


def write_run(dest: Path, run: Run, compression: str = "zstd") -> list[Path]:
    """Write one run as segment files of `run.segment_seconds`, each table's file under its partition."""
    written: list[Path] = []
    period_ns = round(1e9 / run.rate_hz)
    start_ns = _epoch_ns(run.start)
    total = run.seconds * run.rate_hz
    per_segment = run.segment_seconds * run.rate_hz
    for first in range(0, total, per_segment):
        index = np.arange(first, min(first + per_segment, total), dtype=np.int64)
        segment_start = run.start + timedelta(seconds=first / run.rate_hz)
        name = f"{run.robot_id}_{segment_start:%Y_%m_%d-%H_%M_%S}"
        tables = _segment_tables(run, index, start_ns, period_ns, total, name)
        for table_name, table in tables.items():
            for day, rows in _by_date(table, "start" if table_name == "segments" else "time"):
                path = dest / table_name / f"robot_id={run.robot_id}" / f"date={day}" / f"{name}.parquet"
                path.parent.mkdir(parents=True, exist_ok=True)
                pq.write_table(rows, path, compression=compression)
                written.append(path)
    return written


def _by_date(table: pa.Table, column: str) -> list[tuple[str, pa.Table]]:
    """The table's rows split by the UTC date of `column` (a segment across midnight is a file in each date)."""
    days = table.column(column).cast(pa.int64()).to_numpy() // (86_400 * 1_000_000_000)
    return [((_EPOCH + timedelta(days=int(day))).date().isoformat(), table.filter(pa.array(days == day)))
            for day in np.unique(days)]


def _epoch_ns(moment: datetime) -> int:
    return (moment - _EPOCH) // timedelta(microseconds=1) * 1000


def _segment_tables(run: Run, index: np.ndarray, start_ns: int, period_ns: int, total: int,
                    name: str) -> dict[str, pa.Table]:
    """The five tables' rows of the cycles `index` of `run` (segments last, as an export writes them)."""
    kept = np.ones(len(index), dtype=bool)
    for begin, end in run.gaps:
        kept &= ~((index >= begin * run.rate_hz) & (index < end * run.rate_hz))
    raw = _rt_raw(run, index[kept], start_ns, period_ns)
    events = _rt_events(run, index, start_ns, period_ns, total)
    stats = _rt_monitor_stats(run, index, start_ns, period_ns, total)
    states = _joint_states(run, index, start_ns, period_ns)
    segment = pa.Table.from_pylist([{
        "segment": name, "serial": f"SN-{run.robot_id}", "model": run.model, "host": f"{run.robot_id}-host",
        "plem_version": "0.1.0", "dof": run.dof, "joint_names": [f"joint{j + 1}" for j in range(run.dof)],
        "start": start_ns + int(index[0]) * period_ns, "end": start_ns + int(index[-1]) * period_ns,
        "rt_raw_rows": raw.num_rows, "rt_events_rows": events.num_rows, "rt_monitor_stats_rows": stats.num_rows,
        "joint_states_rows": states.num_rows, "dropped": len(index) - raw.num_rows,
        "schema_version": schema.SCHEMA_VERSION}], schema=schema.segments())
    return {"rt_raw": raw, "rt_events": events, "rt_monitor_stats": stats, "joint_states": states,
            "segments": segment}


def _motion(run: Run, index: np.ndarray) -> dict[str, np.ndarray]:
    """The joints' columns: the phase from the cycle within its period, so every period repeats exactly."""
    per_period = round(PERIOD_S * run.rate_hz)
    phase = 2 * math.pi * (index % per_period) / per_period
    sine, cosine = np.sin(phase), np.cos(phase)
    omega = 2 * math.pi / PERIOD_S
    columns: dict[str, np.ndarray] = {}
    for j in range(run.dof):
        columns[f"position_{j}"] = AMPLITUDE[j] * sine
        columns[f"velocity_{j}"] = AMPLITUDE[j] * omega * cosine
        columns[f"effort_{j}"] = EFFORT[j] * cosine
    for j in range(run.dof):
        columns[f"command_position_{j}"] = columns[f"position_{j}"] + FOLLOWING[j]
        columns[f"command_velocity_{j}"] = columns[f"velocity_{j}"]
        columns[f"command_acceleration_{j}"] = -AMPLITUDE[j] * omega * omega * sine
    return columns


def _fault_cycles(run: Run) -> list[int]:
    return [round(fault.at_s * run.rate_hz) for fault in run.faults]


def _rt_raw(run: Run, index: np.ndarray, start_ns: int, period_ns: int) -> pa.Table:
    faults = _fault_cycles(run)
    faulted = np.zeros(len(index), dtype=bool)
    for cycle in faults:
        faulted |= index >= cycle
    columns: dict[str, object] = {
        "time": pa.array(start_ns + index * period_ns, schema.TIME),
        "cycle": run.first_cycle + index,
        "monotonic_ns": 10**12 + index * period_ns,
        "mode": np.where(faulted, 3, 1).astype(np.uint8),
        "faulted": faulted,
        "drives_enabled": ~faulted,
        "latency_ns": (run.latency_base_us * 1000 + _SPREAD_NS[index % LATENCY_PATTERN]).astype(np.uint32),
        "compute_ns": (5000 + (index % 10) * 100).astype(np.uint32),
        **_motion(run, index),
        "speed_override": np.ones(len(index)),
    }
    return pa.Table.from_pydict(columns, schema=schema.rt_raw(run.dof))


def _rt_events(run: Run, index: np.ndarray, start_ns: int, period_ns: int, total: int) -> pa.Table:
    rows = [(0, "mode_changed", "", "", "position", "hold")]
    rows += [(round(fault.at_s * run.rate_hz), "fault", fault.cause, fault.reason, "fault", "position")
             for fault in run.faults]
    rows.append((total - 1, "mode_changed", "", "", "hold", "position"))
    inside = [row for row in rows if index[0] <= row[0] <= index[-1]]
    return pa.Table.from_pylist([{
        "time": start_ns + cycle * period_ns, "cycle": run.first_cycle + cycle,
        "monotonic_ns": 10**12 + cycle * period_ns,
        "kind": kind, "cause": cause, "reason": reason, "mode": mode, "previous_mode": previous}
        for cycle, kind, cause, reason, mode, previous in inside], schema=schema.rt_events())


def _rt_monitor_stats(run: Run, index: np.ndarray, start_ns: int, period_ns: int, total: int) -> pa.Table:
    every = run.rate_hz // STATS_RATE_HZ
    samples = total // every
    last = np.arange(index[0] + every - 1, index[-1] + 1, every)   # the cycle closing each statistics window
    k = (last + 1) // every   # windows done, 1 … samples
    rows = len(k)

    def climb(value: int) -> np.ndarray:
        return (value * k) // samples

    base_us = float(run.latency_base_us)
    columns: dict[str, object] = {
        "time": pa.array(start_ns + last * period_ns, schema.TIME), "cycles": last + 1,
        "overruns": climb(run.overruns), "missed_periods": climb(run.missed_periods),
        "period_ns": np.full(rows, period_ns), "commands_received": np.zeros(rows, dtype=np.int64),
        "commands_accepted": np.zeros(rows, dtype=np.int64), "commands_rejected": np.zeros(rows, dtype=np.int64),
        "bus_lost_frames": climb(run.lost_frames), "bus_working_counter_errors": np.zeros(rows, dtype=np.int64),
        "mode": ["position"] * rows, "fault_reason": [""] * rows,
    }
    figures = {"latency": (base_us, base_us + 50, base_us + 49, base_us + 98, base_us + 99, base_us + 99.9),
               "compute": (5.0, 5.45, 5.4, 5.9, 5.9, 5.9)}
    for series in schema.TIMING_SERIES:
        values = figures.get(series, (0.0,) * 6)
        columns[f"{series}_samples"] = np.full(rows, every)
        for figure, value in zip(schema.TIMING_FIGURES[1:], values, strict=True):
            columns[f"{series}_{figure}"] = np.full(rows, value)
    columns["queues"] = [[{"name": "rt_raw", "capacity": 4096, "fill": 0, "written": int(c) * every, "dropped": 0}]
                         for c in k]
    return pa.Table.from_pydict(columns, schema=schema.rt_monitor_stats())


def _joint_states(run: Run, index: np.ndarray, start_ns: int, period_ns: int) -> pa.Table:
    picked = index[index % JOINT_STATES_EVERY == 0]
    motion = _motion(run, picked)
    columns: dict[str, object] = {"time": pa.array(start_ns + picked * period_ns, schema.TIME)}
    columns.update({f"{name}_{j}": motion[f"{name}_{j}"] for name in schema.STATE_JOINT_FIELDS for j in range(run.dof)})
    return pa.Table.from_pydict(columns, schema=schema.joint_states(run.dof))
