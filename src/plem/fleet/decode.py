"""A closed bag segment's topics as Arrow tables of the fleet dataset (plem.fleet.schema), decoded from ROS 2 CDR.

The bag's own embedded message definitions decide how it is read: they are parsed into a type store, and
rt_raw's definition must be RtRaw as plem records it now or as it was before `speed_override` (then that
column is null). rt_raw and joint_states have a fixed layout per robot, so their payloads are read with
numpy, a batch of thousands at a time (the layout of `plem.middleware.raw_cdr` and
`plem.recording.bulk_cdr`, which the recorder writes with); the rare others (rt_events, rt_monitor_stats, and
a joint_states message of another shape) are deserialized one by one through the type store. A row's `time`
is its message's bag time, which the recorder sets to the message's header stamp.
"""

from __future__ import annotations

import json
import struct
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from plem.errors import PlemError
from plem.fleet import schema
from plem.middleware.monitor_feed import MONITOR_TOPICS
from plem.middleware.raw_cdr import raw_dof, raw_dtype, raw_sizes
from plem.recording.archive import bag_metadata
from plem.recording.bulk_cdr import JointStateEncoder
from plem.recording.identity import IDENTITY_PREFIX
from plem.recording.mcap_records import CHUNK, MAGIC, SCHEMA, chunk_records, records, string
from plem.recording.segment import bag_file
from plem.recording.summary import BagError, Payloads, SegmentInfo, read_topic

RAW_TYPE = MONITOR_TOPICS["rt_raw"]


@dataclass
class SegmentTables:
    """One segment decoded: a table per topic (rows in time order), and what its `segments` row tells."""

    tables: dict[str, pa.Table]
    dof: int | None
    joint_names: list[str] | None
    dropped: int
    identity: dict[str, str] = field(default_factory=dict)


# -- the bag's own definitions --------------------------------------------------------------------------------
@cache
def _types_of(definitions: tuple[tuple[str, str], ...]) -> Typestore:
    """A type store of the definitions a bag embeds ((type, ros2msg text) pairs); segments of one recorder share
    them, so each set is parsed once."""
    store = get_typestore(Stores.EMPTY)
    types: dict[str, Any] = {}
    for msgtype, text in definitions:
        types.update(get_types_from_msg(text, msgtype))
    store.register(types)
    return store


def embedded_definitions(file: Path) -> tuple[tuple[str, str], ...]:
    """(type, ros2msg text) of every schema an MCAP file embeds: its first records and first chunk hold them all
    (the recorder writes its connections before any message)."""
    with open(file, "rb") as handle:
        data = handle.read(HEAD_BYTES)
    found: dict[str, str] = {}

    def take(opcode: int, content: memoryview) -> None:
        if opcode == SCHEMA:
            name, offset = string(content, 2)
            encoding, offset = string(content, offset)
            (length,) = struct.unpack_from("<I", content, offset)
            if encoding == "ros2msg":
                found[name] = bytes(content[offset + 4:offset + 4 + length]).decode()

    for opcode, content in records(data, len(MAGIC)):
        take(opcode, content)
        if opcode == CHUNK:
            for inner, inner_content in records(chunk_records(content)):
                take(inner, inner_content)
            break
    return tuple(sorted(found.items()))


#: How much of an MCAP file is read for its definitions: the recorder's first chunk holds only its connections.
HEAD_BYTES = 1024 * 1024


def _bag_types(info: SegmentInfo) -> tuple[Typestore, dict[str, str]]:
    """The type store of a segment's embedded definitions (plem's own interfaces for a bag without them, as sqlite3
    bags are), and its metadata's custom_data."""
    file = bag_file(info.path)
    try:
        definitions = embedded_definitions(file) if file is not None and file.suffix == ".mcap" else ()
        custom = (bag_metadata(info.path) or {}).get("custom_data") or {}
    except (OSError, ValueError, struct.error, PlemError) as error:
        raise BagError(f"segment {info.name} cannot be read", what="a complete rosbag2 segment",
                       why=f"{type(error).__name__}: {error}", how=f"run `plem bag repair {info.path}`") from None
    custom = {str(key): str(value) for key, value in custom.items()} if isinstance(custom, dict) else {}
    if definitions:
        return _types_of(definitions), custom
    from plem.middleware.types import library

    return library().store, custom


def raw_layout(store: Typestore, segment: str) -> bool:
    """Whether the bag's RtRaw has a speed_override (False: RtRaw as recorded before it had one); BagError for a
    definition this plem does not know."""
    from plem.middleware.types import library

    current = [name for name, _ in library().store.fielddefs[RAW_TYPE][1]]
    found = [name for name, _ in store.fielddefs[RAW_TYPE][1]] if RAW_TYPE in store.fielddefs else current
    if found == current:
        return True
    if found == current[:-1] and current[-1] == "speed_override":
        return False
    raise BagError(f"rt_raw of {segment} has a layout this plem does not know",
                   what=f"{RAW_TYPE} with the fields {', '.join(current)} (or without speed_override, as older plem "
                        "recorded it)", why=f"the bag's definition has {', '.join(found)}",
                   how="export it with the plem version that recorded it (pip install plem==VERSION), or upgrade "
                       "plem if it is newer")


# -- rt_raw -----------------------------------------------------------------------------------------------------
def _gather(payloads: Payloads, rows: np.ndarray, size: int, begin: int = 0) -> np.ndarray:
    """Bytes `begin` to `size` of the payloads at `rows`, one row of bytes each: whole rows copied out of a
    sliding-window view of the buffer (no index per byte)."""
    width = size - begin
    windows = np.lib.stride_tricks.sliding_window_view(payloads.buffer, width)
    out: np.ndarray = windows[payloads.starts[rows].astype(np.int64) + begin]
    return out


def raw_records(payloads: Payloads, dof: int) -> tuple[np.ndarray, np.ndarray]:
    """RtRaw payloads as numpy records of `raw_dtype(dof)`, and which of them carry a speed_override; BagError when
    one has neither size RtRaw of `dof` joints has."""
    full, old = raw_sizes(dof)
    has = payloads.sizes == full
    if not np.all(has | (payloads.sizes == old)):
        raise BagError(f"rt_raw messages of another arm among those of {dof} joints",
                       what=f"RtRaw messages of one arm ({dof} joints, as the first one)",
                       why=f"payloads of {sorted(set(payloads.sizes.tolist()) - {full, old})} bytes",
                       how="export the segments of each arm from their own robot directory")
    everything = np.arange(len(has))
    data = np.zeros((len(has), full), np.uint8)
    data[:, :old] = _gather(payloads, everything, old)
    if np.any(has):
        data[has, old:] = _gather(payloads, everything[has], full, old)
    return data.view(raw_dtype(dof)).reshape(len(has)), has


def _raw_columns(batches: Iterable[Payloads], override: bool) -> tuple[dict[str, Any], int]:
    """rt_raw's columns (numpy, or Arrow for the nullable speed_override) and its DOF (0: no messages)."""
    parts: dict[str, list[np.ndarray]] = {}
    dof = 0
    for payloads in batches:
        if not len(payloads.starts):
            continue
        dof = dof or raw_dof(payloads.message(0))
        records, has = raw_records(payloads, dof)
        columns = {"time": payloads.stamps, "cycle": records["cycle"].astype(np.int64),
                   "monotonic_ns": records["monotonic_ns"], "mode": records["mode"],
                   "faulted": records["faulted"] != 0, "drives_enabled": records["drives_enabled"] != 0,
                   "latency_ns": records["latency_ns"], "compute_ns": records["compute_ns"],
                   "speed_override": records["speed_override"], "has_override": has & override}
        for row in schema.RAW_JOINT_FIELDS:
            columns[row] = records[row]
        for name, values in columns.items():
            parts.setdefault(name, []).append(values)
    joined = {name: np.concatenate(values) for name, values in parts.items()}
    return joined, dof


def raw_table(batches: Iterable[Payloads], override: bool = True) -> tuple[pa.Table, np.ndarray]:
    """rt_raw's table of a segment's RtRaw payloads, and its cycle numbers (for the drops)."""
    columns, dof = _raw_columns(batches, override)
    table_schema = schema.rt_raw(dof)
    if not dof:
        return table_schema.empty_table(), np.zeros(0, np.int64)
    arrays: list[pa.Array] = [pa.array(columns["time"], schema.TIME)]
    for name in ("cycle", "monotonic_ns", "mode", "faulted", "drives_enabled", "latency_ns", "compute_ns"):
        arrays.append(pa.array(columns[name], table_schema.field(name).type))
    for row in schema.RAW_JOINT_FIELDS:
        arrays.extend(pa.array(np.ascontiguousarray(columns[row][:, joint])) for joint in range(dof))
    arrays.append(pa.array(columns["speed_override"], pa.float64(), mask=~columns["has_override"]))
    return pa.Table.from_arrays(arrays, schema=table_schema), columns["cycle"]


def missing_cycles(cycles: np.ndarray) -> int:
    """Cycles lost between consecutive recorded ones (a new driver run, where cycles restart, loses none)."""
    steps = np.diff(cycles)
    return int((steps[steps > 1] - 1).sum())


# -- joint_states -------------------------------------------------------------------------------------------------
def _joint_state_rows(batches: Iterable[Payloads], store: Typestore) -> tuple[list[str] | None, dict[str, Any]]:
    """joint_states' columns (time, then position/velocity/effort as messages × joints, NaN where a message has
    no value) and the joints' names of the first message."""
    ros_type = MONITOR_TOPICS["joint_states"]
    names: list[str] | None = None
    encoder: JointStateEncoder | None = None
    fixed = np.zeros(0, bool)
    times: list[np.ndarray] = []
    rows: dict[str, list[np.ndarray]] = {row: [] for row in schema.STATE_JOINT_FIELDS}
    for payloads in batches:
        if not len(payloads.starts):
            continue
        if encoder is None:
            first: Any = store.deserialize_cdr(payloads.message(0), ros_type)   # a generated message
            names = [str(name) for name in first.name]
            encoder = JointStateEncoder(names)
            fixed = _fixed_bytes(encoder)
        times.append(payloads.stamps)
        size = encoder.template.size
        if np.all(payloads.sizes == size):
            data = _gather(payloads, np.arange(len(payloads.starts)), size)
            if np.all(data[:, fixed] == encoder.template[fixed]):
                view = data.view(encoder.dtype).reshape(len(data))
                for index, row in enumerate(schema.STATE_JOINT_FIELDS):
                    rows[row].append(view[f"row{index}"])
                continue
        decoded = [store.deserialize_cdr(payloads.message(index), ros_type) for index in range(len(payloads.starts))]
        for row in schema.STATE_JOINT_FIELDS:
            rows[row].append(np.array([_padded(getattr(message, row), encoder.dof) for message in decoded]))
    if not times:
        return names, {}
    return names, {"time": np.concatenate(times), **{row: np.concatenate(parts) for row, parts in rows.items()}}


def _fixed_bytes(encoder: JointStateEncoder) -> np.ndarray:
    """Which bytes of a JointState payload are the same in every message of the robot (all but stamp and values)."""
    fixed = np.ones(encoder.template.size, bool)
    for field_type, offset, *_ in (encoder.dtype.fields or {}).values():
        fixed[offset:offset + field_type.itemsize] = False
    return fixed


def _padded(values: Any, dof: int) -> np.ndarray:
    """A message's row as `dof` values, NaN (null in the table) where it has none."""
    out = np.full(dof, np.nan)
    given = np.asarray(values, float)[:dof]
    out[:len(given)] = given
    return out


def joint_states_table(batches: Iterable[Payloads], store: Typestore) -> tuple[pa.Table, list[str] | None]:
    """joint_states' table of a segment's JointState payloads, and the joints' names."""
    names, columns = _joint_state_rows(batches, store)
    if not columns:
        return schema.joint_states(len(names or ())).empty_table(), names
    dof = len(names or ())
    arrays: list[pa.Array] = [pa.array(columns["time"], schema.TIME)]
    for row in schema.STATE_JOINT_FIELDS:
        for joint in range(dof):
            values = np.ascontiguousarray(columns[row][:, joint])
            arrays.append(pa.array(values, pa.float64(), mask=np.isnan(values)))
    return pa.Table.from_arrays(arrays, schema=schema.joint_states(dof)), names


# -- rt_events, rt_monitor_stats ---------------------------------------------------------------------------------
def _messages(batches: Iterable[Payloads], store: Typestore, ros_type: str) -> Iterator[tuple[int, Any]]:
    for payloads in batches:
        for index in range(len(payloads.starts)):
            yield int(payloads.stamps[index]), store.deserialize_cdr(payloads.message(index), ros_type)


def events_table(batches: Iterable[Payloads], store: Typestore) -> pa.Table:
    """rt_events' table: one row per event, its fault text (reason) as recorded."""
    rows = [{"time": stamp, "cycle": int(event.cycle), "monotonic_ns": int(event.monotonic_ns),
             "kind": event.kind, "cause": event.cause, "reason": event.reason, "mode": event.mode,
             "previous_mode": event.previous_mode}
            for stamp, event in _messages(batches, store, MONITOR_TOPICS["rt_events"])]
    return pa.Table.from_pylist(rows, schema=schema.rt_events())


_COUNTERS = ("cycles", "overruns", "missed_periods", "period_ns", "commands_received", "commands_accepted",
             "commands_rejected", "bus_lost_frames", "bus_working_counter_errors")


def stats_table(batches: Iterable[Payloads], store: Typestore) -> pa.Table:
    """rt_monitor_stats' table: counters, each timing series' figures as flat columns, the queues as a list."""
    rows = []
    for stamp, stats in _messages(batches, store, MONITOR_TOPICS["rt_monitor_stats"]):
        row: dict[str, Any] = {"time": stamp, "mode": stats.mode, "fault_reason": stats.fault_reason}
        row.update({name: int(getattr(stats, name)) for name in _COUNTERS})
        for series in schema.TIMING_SERIES:
            timing = getattr(stats, series)
            row.update({f"{series}_{figure}": getattr(timing, figure) for figure in schema.TIMING_FIGURES})
        row["queues"] = [{"name": queue.name, "capacity": int(queue.capacity), "fill": int(queue.fill),
                          "written": int(queue.written), "dropped": int(queue.dropped)} for queue in stats.queues]
        rows.append(row)
    return pa.Table.from_pylist(rows, schema=schema.rt_monitor_stats())


def _listed_names(text: str) -> list[str] | None:
    """The joint names the recorder wrote into a segment's metadata (a JSON list); None when absent or malformed."""
    try:
        names = json.loads(text) if text else None
    except ValueError:
        return None
    return [str(name) for name in names] if isinstance(names, list) else None


# -- a segment ------------------------------------------------------------------------------------------------------
def decode_segment(info: SegmentInfo) -> SegmentTables:
    """Every exported topic of one complete segment, decoded through the definitions it embeds."""
    store, custom = _bag_types(info)
    topics = {name: info.topic_of(ros_type) for name, ros_type in MONITOR_TOPICS.items()}

    def batches(name: str) -> Iterator[Payloads]:
        topic = topics[name]
        return read_topic(info.path, topic) if topic is not None else iter(())

    override = raw_layout(store, info.name) if topics["rt_raw"] else True
    raw, cycles = raw_table(batches("rt_raw"), override)
    states, names = joint_states_table(batches("joint_states"), store)
    tables = {"rt_raw": raw, "rt_events": events_table(batches("rt_events"), store),
              "rt_monitor_stats": stats_table(batches("rt_monitor_stats"), store), "joint_states": states}
    identity = {key.removeprefix(IDENTITY_PREFIX): value for key, value in custom.items()
                if key.startswith(IDENTITY_PREFIX)}
    names = _listed_names(identity.get("joint_names", "")) or names
    dof = (len(raw.schema) - len(schema.rt_raw(0))) // len(schema.RAW_JOINT_FIELDS) if raw.num_rows else \
        (len(names) if names is not None else None)
    return SegmentTables(tables, dof, names, missing_cycles(cycles), identity)
