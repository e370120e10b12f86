"""Closed bag segments into the fleet dataset: incremental, idempotent, and safe to kill at any moment.

Each complete segment becomes, per table, one Parquet file per UTC date its rows fall on:
`DEST/<table>/robot_id=<id>/date=<YYYY-MM-DD>/<segment>.parquet`. Its `segments` row is written last: once
it is there the segment is whole, and later runs skip it. File names depend only on the segment, and the
same segment gives the same bytes, so a run killed part way is simply run again: it rewrites the files it
had written with the same content and never duplicates a row. Each file reaches the dataset whole
(`plem.fleet.destination`). A segment being recorded is left for a later run; an unfinished (killed) or
damaged one is reported with the fix and the others are exported.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
from rosbags.serde import SerdeError

from plem.errors import PlemError
from plem.fleet import schema
from plem.fleet.decode import SegmentTables, decode_segment
from plem.fleet.destination import Destination, DestinationError
from plem.recording.segment import RESERVE_NAME, being_written
from plem.recording.summary import BagError, SegmentInfo, find_bags, segment_info

_DAY_NS = 86_400 * 1_000_000_000
#: Parquet's compression: zstd at its default level (3) compresses the 1 kHz rows well and decodes fast.
COMPRESSION = "zstd"


class ExportError(PlemError):
    """A segment that could not be exported."""


@dataclass
class ExportReport:
    """What one export run did."""

    exported: list[str] = field(default_factory=list)         # robot/segment, now in the dataset
    already: list[str] = field(default_factory=list)          # exported by an earlier run
    recording: list[str] = field(default_factory=list)        # being recorded: a later run exports them
    problems: list[PlemError] = field(default_factory=list)   # skipped with the fix (killed, damaged, gone)
    files: int = 0
    rt_raw_rows: int = 0
    bytes: int = 0
    removed_temporaries: list[str] = field(default_factory=list)


def file_path(table: str, robot_id: str, date: str, segment: str) -> str:
    """Where one file of a table lies in the dataset, relative to its root."""
    return f"{table}/robot_id={robot_id}/date={date}/{segment}.parquet"


def _utc_date(days: int) -> str:
    return str(np.datetime64(days, "D"))


def by_date(table: pa.Table) -> list[tuple[str, pa.Table]]:
    """A table's rows split by the UTC date of their `time` (a segment spanning midnight gives two parts)."""
    if not table.num_rows:
        return []
    days = table.column("time").cast(pa.int64()).to_numpy() // _DAY_NS
    if np.all(days == days[0]):
        return [(_utc_date(int(days[0])), table)]
    return [(_utc_date(int(day)), table.filter(pa.array(days == day))) for day in np.unique(days)]


def parquet_bytes(table: pa.Table) -> bytes:
    """One Parquet file of a table: zstd; floats byte-stream-split (their exponent bytes compress well), strings
    dictionary-encoded, numbers plain; the schema version in its metadata."""
    floats = [item.name for item in table.schema if pa.types.is_floating(item.type)]
    strings = [item.name for item in table.schema if pa.types.is_string(item.type)]
    sink = pa.BufferOutputStream()
    pq.write_table(table, sink, compression=COMPRESSION, use_dictionary=strings or False,
                   use_byte_stream_split=floats or False)
    return bytes(sink.getvalue())


def segment_row(info: SegmentInfo, decoded: SegmentTables) -> pa.Table:
    """The `segments` row of one decoded segment."""
    identity = decoded.identity
    start = info.start_ns
    end = None if start is None or info.duration_ns is None else start + info.duration_ns
    row = {"segment": info.name, "serial": identity.get("serial") or None, "model": identity.get("model") or None,
           "host": identity.get("host") or None, "plem_version": identity.get("plem_version") or None,
           "dof": decoded.dof, "joint_names": decoded.joint_names, "start": start, "end": end,
           **{f"{name}_rows": decoded.tables[name].num_rows for name in schema.TABLES[:-1]},
           "dropped": decoded.dropped, "schema_version": schema.SCHEMA_VERSION}
    return pa.Table.from_pylist([row], schema=schema.segments())


def segment_files(info: SegmentInfo, robot_id: str) -> tuple[list[tuple[str, bytes]], int]:
    """Every file of one segment (relative path, bytes), its `segments` row last, and its rt_raw rows."""
    decoded = decode_segment(info)
    files = [(file_path(name, robot_id, date, info.name), parquet_bytes(part))
             for name in schema.TABLES[:-1] for date, part in by_date(decoded.tables[name])]
    row = segment_row(info, decoded)
    start_date = _utc_date((info.start_ns or 0) // _DAY_NS)
    files.append((file_path("segments", robot_id, start_date, info.name), parquet_bytes(row)))
    return files, decoded.tables["rt_raw"].num_rows


#: Called with the bytes a segment is about to add, before any of them is written; raises to hold the export back.
RoomCheck = Callable[[int], None]


def _skipped(info: SegmentInfo) -> PlemError:
    """The WHAT/WHY/HOW of a segment that is neither complete nor being recorded."""
    if info.state in ("killed", "damaged"):
        return ExportError(f"segment {info.name} not exported: {info.note()}",
                           what="complete segments (closed by the recorder, with their metadata.yaml)",
                           why=f"{info.path} is {info.note()}",
                           how=f"run `plem bag repair {info.path}`, then export again; the other segments are exported")
    return ExportError(f"segment {info.name} not exported: it cannot be read",
                       what="a segment with a readable metadata.yaml and bag file", why=info.problem,
                       how=f"restore the files of {info.path}, or delete it; the other segments are exported")


def still_open(path: Path) -> bool:
    """Whether a recorder still writes the segment (its lock, or its disk reserve)."""
    return being_written(path) or (path / RESERVE_NAME).exists()


def export_segments(robot_id: str, paths: Iterable[Path], destination: Destination, report: ExportReport,
                    room: RoomCheck | None = None) -> None:
    """Export one robot's closed segments not yet in the dataset; record what happened in `report`."""
    done = destination.names(f"segments/robot_id={robot_id}")
    for path in paths:
        name = f"{robot_id}/{path.name}"
        if f"{path.name}.parquet" in done:
            report.already.append(name)
            continue
        if not path.is_dir():
            report.problems.append(ExportError(
                f"segment {path.name} not exported: it was deleted before its export",
                what="the segment's directory", why=f"{path} no longer exists (retention, the disk guard, or by hand)",
                how="nothing to do for it; keep segments until exported by raising retention_minutes:="))
            continue
        if still_open(path):
            report.recording.append(name)
            continue
        info = segment_info(path)
        if info.state == "recording":
            report.recording.append(name)
            continue
        if info.state != "complete":
            report.problems.append(_skipped(info))
            continue
        try:
            files, rows = segment_files(info, robot_id)
        except BagError as error:
            report.problems.append(error)
            continue
        except FileNotFoundError:
            report.problems.append(ExportError(
                f"segment {path.name} not exported: it was deleted while being exported",
                what="the segment's files until their export ends", why=f"{path} went away meanwhile",
                how="nothing to do for it; keep segments until exported by raising retention_minutes:="))
            continue
        except (SerdeError, ValueError, IndexError, KeyError, struct.error) as error:
            report.problems.append(ExportError(
                f"segment {path.name} not exported: a message in it cannot be decoded",
                what="messages as their definitions in the bag describe them", why=f"{type(error).__name__}: {error}",
                how=f"run `plem bag repair {path}` if it was damaged, or delete it; the other segments are exported"))
            continue
        size = sum(len(data) for _, data in files)
        if room is not None:
            room(size)
        for relative, data in files:
            destination.put(relative, data)
        report.exported.append(name)
        report.files += len(files)
        report.rt_raw_rows += rows
        report.bytes += size


def export(directories: Iterable[Path], destination: Destination, room: RoomCheck | None = None) -> ExportReport:
    """Export every closed segment under each directory (a bag_dir, a robot's directory or one segment)."""
    report = ExportReport(removed_temporaries=destination.remove_temporaries())
    for directory in directories:
        for robot in find_bags(directory):
            export_segments(robot.robot_id, robot.segments, destination, report, room)
    return report


def disk_room(destination: Destination, threshold: float) -> RoomCheck:
    """A room check keeping a local dataset's disk at or below `threshold` percent full (none on S3)."""
    def check(size: int) -> None:
        usage = destination.free_share()
        if usage is None:
            return
        total, used = usage
        if 100.0 * (used + size) / total > threshold:
            raise DestinationError(
                f"export held back: the disk holding {destination.root} would pass disk_threshold {threshold:g} %",
                what=f"room for {size} bytes below disk_threshold {threshold:g} %",
                why=f"the disk is {100.0 * used / total:.1f} % full",
                how="free space there, pass another export_dir:=, or raise disk_threshold:=; the export resumes "
                    "by itself once there is room")
    return check

