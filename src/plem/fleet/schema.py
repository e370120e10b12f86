"""The fleet dataset's tables: their Parquet schemas, layout and versions, shared by the export and every reader.

A dataset is a directory (or an object-store prefix) with one Hive-partitioned table per topic:

    DEST/rt_raw/robot_id=indy/date=2026-11-29/indy_2026_11_29-10_15_00.parquet
    DEST/rt_events/..., DEST/rt_monitor_stats/..., DEST/joint_states/..., DEST/segments/...

Joint rows are flat typed columns, one per joint (`position_0` … `position_{n-1}`): per-joint aggregates are plain
column expressions for every engine, and a 6-axis and a 7-axis robot share a table (a reader unions the files by
column name; the 7th joint's columns are null for the 6-axis one). The joints' names are in `segments`.
"""

from __future__ import annotations

import pyarrow as pa

#: The version of the tables written now; every file carries it, and readers accept every older one.
SCHEMA_VERSION = 1
#: Metadata key of a Parquet file's schema version.
VERSION_KEY = b"plem.schema_version"
#: The tables, in the order an export writes them (`segments` last: its row says the segment is whole).
TABLES = ("rt_raw", "rt_events", "rt_monitor_stats", "joint_states", "segments")
#: Partition columns of every table, in path order.
PARTITIONS = ("robot_id", "date")

TIME = pa.timestamp("ns", tz="UTC")
#: rt_raw's per-joint rows, in RtRaw's order.
RAW_JOINT_FIELDS = ("position", "velocity", "effort", "command_position", "command_velocity", "command_acceleration")
#: joint_states' per-joint rows.
STATE_JOINT_FIELDS = ("position", "velocity", "effort")
#: The timing figures of RtMonitorStats (each a TimingStats) and what each holds.
TIMING_SERIES = ("latency", "compute", "latency_interval", "compute_interval")
TIMING_FIGURES = ("samples", "min_us", "mean_us", "p50_us", "p99_us", "p999_us", "max_us")


def joint_columns(fields: tuple[str, ...], dof: int) -> list[pa.Field]:
    """One float64 column per joint and field: `position_0`, `position_1`, …, then `velocity_0`, …"""
    return [pa.field(f"{name}_{joint}", pa.float64()) for name in fields for joint in range(dof)]


def rt_raw(dof: int) -> pa.Schema:
    """One row per cycle."""
    return _versioned([
        pa.field("time", TIME, nullable=False), pa.field("cycle", pa.int64(), nullable=False),
        pa.field("monotonic_ns", pa.int64()), pa.field("mode", pa.uint8()), pa.field("faulted", pa.bool_()),
        pa.field("drives_enabled", pa.bool_()), pa.field("latency_ns", pa.uint32()),
        pa.field("compute_ns", pa.uint32()),
        *joint_columns(RAW_JOINT_FIELDS, dof),
        pa.field("speed_override", pa.float64()),   # null in bags recorded before RtRaw carried it
    ])


def rt_events() -> pa.Schema:
    """One row per event, its fault text decoded."""
    return _versioned([
        pa.field("time", TIME, nullable=False), pa.field("cycle", pa.int64()), pa.field("monotonic_ns", pa.int64()),
        pa.field("kind", pa.string()), pa.field("cause", pa.string()), pa.field("reason", pa.string()),
        pa.field("mode", pa.string()), pa.field("previous_mode", pa.string()),
    ])


def rt_monitor_stats() -> pa.Schema:
    """One row per statistics message (10 Hz): counters, and each timing series' figures as flat columns."""
    counters = ("cycles", "overruns", "missed_periods", "period_ns", "commands_received", "commands_accepted",
                "commands_rejected", "bus_lost_frames", "bus_working_counter_errors")
    return _versioned([
        pa.field("time", TIME, nullable=False), *(pa.field(name, pa.int64()) for name in counters),
        pa.field("mode", pa.string()), pa.field("fault_reason", pa.string()),
        *(pa.field(f"{series}_{figure}", pa.int64() if figure == "samples" else pa.float64())
          for series in TIMING_SERIES for figure in TIMING_FIGURES),
        pa.field("queues", pa.list_(pa.struct([("name", pa.string()), ("capacity", pa.int64()), ("fill", pa.int64()),
                                               ("written", pa.int64()), ("dropped", pa.int64())]))),
    ])


def joint_states(dof: int) -> pa.Schema:
    """One row per joint_states message."""
    return _versioned([pa.field("time", TIME, nullable=False), *joint_columns(STATE_JOINT_FIELDS, dof)])


def segments() -> pa.Schema:
    """One row per exported segment: whose it is, what it covers, and what it lost."""
    return _versioned([
        pa.field("segment", pa.string(), nullable=False), pa.field("serial", pa.string()),
        pa.field("model", pa.string()), pa.field("host", pa.string()), pa.field("plem_version", pa.string()),
        pa.field("dof", pa.int32()), pa.field("joint_names", pa.list_(pa.string())),
        pa.field("start", TIME), pa.field("end", TIME),
        pa.field("rt_raw_rows", pa.int64()), pa.field("rt_events_rows", pa.int64()),
        pa.field("rt_monitor_stats_rows", pa.int64()), pa.field("joint_states_rows", pa.int64()),
        pa.field("dropped", pa.int64()), pa.field("schema_version", pa.int32()),
    ])


def _versioned(fields: list[pa.Field]) -> pa.Schema:
    return pa.schema(fields, metadata={VERSION_KEY: str(SCHEMA_VERSION).encode()})
