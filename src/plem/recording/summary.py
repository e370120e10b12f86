"""What a directory of plem bags holds: segments, message counts, dropped cycles, faults and deletions.

The directory may be the recorder's bag_dir (one directory per robot), one robot's directory or one
segment. Payloads are taken straight from the MCAP chunks through their message indexes (or from the
sqlite3 table), and only the bytes of the fields needed are gathered, so an hour of 1 kHz rt_raw is
summarised in seconds rather than deserialized message by message. A segment being recorded is read as
far as its writer has put it in the file (complete chunks, committed transactions).
"""

from __future__ import annotations

import mmap
import os
import re
import sqlite3
import struct
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from plem.errors import PlemError
from plem.launch.arguments import DEFAULTS
from plem.middleware.monitor_feed import MONITOR_TOPICS
from plem.middleware.raw_cdr import raw_field, raw_fields
from plem.recording.archive import KEEP_SUFFIX, bag_metadata, directory_size, extent_of, iso_time, read_event_log
from plem.recording.mcap_records import (
    CHUNK,
    MAGIC,
    MESSAGE_FIELDS,
    MESSAGE_INDEX,
    RECORD_HEADER,
    McapError,
    chunk_records,
    define,
    records,
)
from plem.recording.segment import bag_file, being_written, open_bag_file

#: Gaps listed one by one; the totals count every gap.
LISTED_GAPS = 20
#: RtRaw payload bytes up to the end of its cycle number.
_CYCLE_TYPE, _CYCLE_OFFSET = raw_fields(0)["cycle"]
CYCLE_END = _CYCLE_OFFSET + _CYCLE_TYPE.itemsize


class BagError(PlemError):
    """A directory holds no bags plem can read, or a bag is malformed."""


# -- finding segments --------------------------------------------------------------------------------------
def _segments(directory: Path) -> list[Path]:
    """The segment directories directly under `directory`, oldest first (their names sort in time order)."""
    return sorted(child for child in directory.iterdir()
                  if child.is_dir() and not child.name.startswith(".") and bag_file(child) is not None)


@dataclass(frozen=True)
class RobotBags:
    """One robot's segments found under the directory given; `whole`: all of them, not one segment picked."""

    robot_id: str
    directory: Path
    segments: list[Path]
    whole: bool = True


def find_bags(path: Path) -> list[RobotBags]:
    """The robots and segments under a bag_dir, a robot's directory or a single segment directory."""
    usage = f"the recorder's bag_dir (default {DEFAULTS['bag_dir']}), one robot's directory in it, or one segment"
    if not path.is_dir():
        raise BagError(f"{path} is not a bag directory", what=usage,
                       why="it does not exist" if not path.exists() else "it is a file",
                       how="pass the directory the recorder wrote (launch argument bag_dir)")
    if bag_file(path) is not None:
        return [RobotBags(path.parent.name, path.parent, [path], whole=False)]
    try:
        if segments := _segments(path):
            return [RobotBags(path.name, path, segments)]
        robots = [RobotBags(child.name, child, segments) for child in sorted(path.iterdir())
                  if child.is_dir() and (segments := _segments(child))]
    except OSError as error:
        raise BagError(f"cannot read {error.filename or path}", what=f"{usage}, readable by you",
                       why=error.strerror or str(error), how="run plem as a user who may read the bags") from None
    if not robots:
        raise BagError(f"no bags in {path}", what=f"{usage}, holding .mcap or .db3 segments",
                       why="no segment directory found in it or in its sub-directories",
                       how="pass the directory the recorder wrote (launch argument bag_dir), or record with "
                           "`plem launch ... record:=true` first")
    return robots


def pick_robot(robots: list[RobotBags], robot_id: str | None, directory: Path, doing: str,
               also: str = "") -> tuple[RobotBags, list[str]]:
    """The bags of `robot_id`, else of the robot whose last message is the latest, with a warning naming it and the
    others (`doing` it, e.g. "plotting"); BagError naming the robots there when `robot_id` is not one of them.
    `also`: the other choices --robot offers, as the messages end with them."""
    if robot_id is not None:
        for bags in robots:
            if bags.robot_id == robot_id:
                return bags, []
        raise BagError(f"no bags of robot {robot_id} in {directory}", what=f"bags of {robot_id}",
                       why=f"robots found: {', '.join(bags.robot_id for bags in robots)}",
                       how=f"pass one of them with --robot{also}")
    if len(robots) == 1:
        return robots[0], []
    ends = {bags.robot_id: last_message_time(bags) for bags in robots}
    newest = max(robots, key=lambda found: ends[found.robot_id])
    return newest, [f"{directory} holds the bags of {len(robots)} robots "
                    f"({', '.join(bags.robot_id for bags in robots)}): {doing} {newest.robot_id}, the one whose last "
                    f"message is the latest ({iso_time(ends[newest.robot_id])}); pass --robot ID for another{also}"]


def last_message_time(bags: RobotBags) -> int:
    """The log time (ns) of a robot's last recorded message: the end of its newest segment that tells one (0: none)."""
    for path in reversed(bags.segments):
        info = segment_info(path)
        if info.start_ns is not None and info.duration_ns is not None:
            return info.start_ns + info.duration_ns
    return 0


# -- reading payloads --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Payloads:
    """Messages of one topic from a stretch of a bag: log times (ns) and where each payload lies in `buffer`."""

    stamps: np.ndarray
    buffer: np.ndarray
    starts: np.ndarray
    sizes: np.ndarray

    def message(self, index: int) -> bytes:
        """The payload of message `index`, copied out of the buffer."""
        start = int(self.starts[index])
        return self.buffer[start:start + int(self.sizes[index])].tobytes()


#: Log times (ns) from, to (both included): messages outside are not read where the storage allows.
Window = tuple[int, int]
EVERYTHING: Window = (0, 2**63 - 1)


def read_topic(segment: Path, topic: str, head: int | None = None, window: Window = EVERYTHING) -> Iterator[Payloads]:
    """The messages of `topic` in a segment, in the order they were written, a chunk at a time.

    `head`: only the first `head` bytes of each payload are needed (sqlite3 then reads no more).
    `window`: the log times wanted; MCAP chunks wholly outside it are skipped, so a batch may still hold
    messages just outside it.
    """
    file = bag_file(segment)
    if file is None:
        raise BagError(f"{segment} holds no bag file", what="a .mcap or .db3 file in the segment directory",
                       why="none found", how="pass a segment the recorder wrote")
    return _mcap_topic(file, topic, window) if file.suffix == ".mcap" else _sqlite3_topic(file, topic, head, window)


def _chunk_times(chunk: memoryview) -> Window:
    """The earliest and latest log time of the messages in a chunk, from its header."""
    start, end = struct.unpack_from("<QQ", chunk, 0)
    return int(start), int(end)


@dataclass(frozen=True)
class McapIndex:
    """An MCAP file as far as it reads: its channels (id → topic, type), its chunks with their message indexes,
    whether it ends whole."""

    channels: dict[int, tuple[str, str]]
    indexed: list[tuple[memoryview, memoryview]]
    whole: bool

    def counts(self) -> Counter[str]:
        """Messages per topic that the message indexes point at: what can be read."""
        counts: Counter[str] = Counter()
        for _, index in self.indexed:
            (channel_id,) = struct.unpack_from("<H", index, 0)
            counts[self.channels.get(channel_id, ("", ""))[0]] += (len(index) - 6) // 16
        return counts

    def topics(self) -> dict[str, tuple[str, int]]:
        """Every channel's topic → (type, messages that can be read), as metadata.yaml lists them."""
        counts = self.counts()
        return {topic: (msgtype, counts[topic]) for topic, msgtype in self.channels.values()}

    def extent(self) -> Window | None:
        """The earliest and latest log time of the messages that can be read; None when there are none."""
        times = [_chunk_times(chunk) for chunk, _ in self.indexed]
        return (min(start for start, _ in times), max(end for _, end in times)) if times else None


def _corrupt(path: Path, error: Exception) -> BagError:
    return BagError(f"{path} is damaged", what="MCAP records as the recorder writes them",
                    why=f"{type(error).__name__}: {error}", how="run `plem bag repair` on its segment, or delete it")


def _file_data(path: Path) -> bytes | mmap.mmap:
    """A bag file's bytes: mapped when finished; read when it may still be written to, as a writer the disk
    refuses cuts it back (a mapped page past the end would kill the reader)."""
    try:
        with os.fdopen(open_bag_file(path), "rb") as handle:
            size = os.fstat(handle.fileno()).st_size
            if not (path.parent / "metadata.yaml").exists():
                return handle.read()
            return mmap.mmap(handle.fileno(), 0, access=mmap.ACCESS_READ) if size else b""
    except PlemError as error:
        raise BagError(error.summary, what=error.what, why=error.why, how=error.how) from None
    except OSError as error:
        raise BagError(f"cannot read {path}", what="a readable bag file", why=error.strerror or str(error),
                       how="check the file's permissions") from None


def mcap_index(path: Path) -> McapIndex:
    """Scan an MCAP file's records (their headers only); BagError when it is not an MCAP file or not a regular one.

    A file without its summary (being recorded, or killed) has its channels in its chunks only: those are
    read until every channel a message index names is known.
    """
    data = _file_data(path)
    if data[:len(MAGIC)] != MAGIC:
        raise BagError(f"{path} is not an MCAP file", what="a file starting with the MCAP magic",
                       why="its first bytes differ" if data else "it is empty", how="pass a segment the recorder wrote")
    schemas: dict[int, str] = {}
    channels: dict[int, tuple[str, str]] = {}
    chunks: list[memoryview] = []
    indexed: list[tuple[memoryview, memoryview]] = []
    try:
        for opcode, content in records(data, len(MAGIC)):
            if opcode == CHUNK:
                chunks.append(content)
            elif opcode == MESSAGE_INDEX and chunks:
                if len(content) < 6 or (len(content) - 6) % 16:
                    raise ValueError(f"a message index of {len(content)} bytes")
                indexed.append((chunks[-1], content))
            else:
                define(opcode, content, schemas, channels)
        named = {struct.unpack_from("<H", index, 0)[0] for _, index in indexed}
        for chunk in chunks:
            if named <= channels.keys():
                break
            for opcode, content in records(chunk_records(chunk)):
                define(opcode, content, schemas, channels)
    except (struct.error, ValueError) as error:
        raise _corrupt(path, error) from None
    except McapError as error:
        raise BagError(error.summary, what=error.what, why=error.why, how=error.how) from None
    return McapIndex(channels, indexed, len(data) > 2 * len(MAGIC) and data[-len(MAGIC):] == MAGIC)


def _mcap_topic(path: Path, topic: str, window: Window) -> Iterator[Payloads]:
    """Every chunk with messages of `topic` in `window`, found through the message index that follows each chunk."""
    index = mcap_index(path)
    for chunk, entries in index.indexed:
        (channel_id,) = struct.unpack_from("<H", entries, 0)
        start, end = _chunk_times(chunk)
        if index.channels.get(channel_id, ("", ""))[0] == topic and start <= window[1] and end >= window[0]:
            try:
                yield _indexed_payloads(chunk, entries)
            except (struct.error, IndexError, ValueError) as error:
                raise _corrupt(path, error) from None


def _indexed_payloads(chunk: memoryview, index: memoryview) -> Payloads:
    """The messages a message index points at within its chunk."""
    inner = np.frombuffer(chunk_records(chunk), np.uint8)
    entries = np.frombuffer(index, dtype=[("time", "<u8"), ("offset", "<u8")], offset=2 + 4)
    offsets = entries["offset"].astype(np.int64)
    lengths = inner[offsets[:, None] + 1 + np.arange(8)].view("<u8").ravel().astype(np.int64)
    return Payloads(entries["time"].astype(np.int64), inner, offsets + RECORD_HEADER + MESSAGE_FIELDS,
                    lengths - MESSAGE_FIELDS)


def _sqlite3_topic(path: Path, topic: str, head: int | None, window: Window,
                   batch: int = 100_000) -> Iterator[Payloads]:
    """The messages of `topic` in `window` in a rosbag2 sqlite3 file (their first `head` bytes), `batch` rows at a
    time."""
    data = "m.data" if head is None else f"substr(m.data, 1, {int(head)})"
    connection = _sqlite3_open(path)
    try:
        cursor = connection.execute(f"SELECT m.timestamp, {data} FROM messages m JOIN topics t ON m.topic_id = t.id "
                                    "WHERE t.name = ? AND m.timestamp BETWEEN ? AND ? ORDER BY m.id",
                                    (topic, *window))
        while rows := cursor.fetchmany(batch):
            stamps, blobs = zip(*rows, strict=True)
            sizes = np.fromiter(map(len, blobs), np.int64, len(blobs))
            yield Payloads(np.array(stamps, np.int64), np.frombuffer(b"".join(blobs), np.uint8),
                           np.cumsum(sizes) - sizes, sizes)
    except sqlite3.DatabaseError as error:
        raise BagError(f"{path} cannot be read", what="a rosbag2 sqlite3 database", why=str(error),
                       how="pass a segment the recorder wrote") from error
    finally:
        connection.close()


def _sqlite3_open(path: Path) -> sqlite3.Connection:
    """A read-only connection to a regular sqlite3 file (sqlite3 would block on a FIFO)."""
    try:
        os.close(open_bag_file(path))
    except PlemError as error:
        raise BagError(error.summary, what=error.what, why=error.why, how=error.how) from None
    return sqlite3.connect(f"file:{path}?mode=ro", uri=True)


def _sqlite3_so_far(path: Path) -> tuple[dict[str, tuple[str, int]], Window | None]:
    """Topics (topic → type, messages) and the extent of what a rosbag2 sqlite3 file holds committed so far."""
    connection = _sqlite3_open(path)
    try:
        rows = connection.execute("SELECT t.name, t.type, count(m.id), min(m.timestamp), max(m.timestamp) FROM "
                                  "topics t LEFT JOIN messages m ON m.topic_id = t.id GROUP BY t.id").fetchall()
    except sqlite3.DatabaseError as error:
        raise BagError(f"{path} cannot be read", what="a rosbag2 sqlite3 database", why=str(error),
                       how="wait for the recorder to close the segment, then run `plem bag info` again") from error
    finally:
        connection.close()
    times = [(int(first), int(last)) for *_, first, last in rows if first is not None]
    extent = (min(first for first, _ in times), max(last for _, last in times)) if times else None
    return {name: (msgtype, int(count)) for name, msgtype, count, _, _ in rows}, extent


def _sqlite3_count(path: Path) -> int:
    """The messages a rosbag2 sqlite3 file holds; BagError when it does not read."""
    connection = _sqlite3_open(path)
    try:
        (count,) = connection.execute("SELECT count(*) FROM messages").fetchone()
    except sqlite3.DatabaseError as error:
        raise BagError(f"{path} cannot be read", what="a rosbag2 sqlite3 database", why=str(error),
                       how="run `plem bag repair` on its segment, or delete it") from error
    finally:
        connection.close()
    return int(count)


# -- segments ----------------------------------------------------------------------------------------------
@dataclass
class SegmentInfo:
    """One segment and its `state`.

    complete; recording (a live recorder holds it open: its topics, start and duration are what the file
    holds so far); killed (unfinished: no metadata.yaml, and no recorder writes it); damaged (metadata.yaml
    is there but the file is truncated or damaged: `problem` says how much reads); unreadable (its
    metadata.yaml or bag file cannot be read at all).
    """

    path: Path
    storage: str
    state: str
    size: int
    kept: bool
    start_ns: int | None = None
    duration_ns: int | None = None
    topics: dict[str, tuple[str, int]] = field(default_factory=dict)   # topic → (type, messages)
    problem: str = ""

    @property
    def name(self) -> str:
        """The segment's directory name, as the event log names it."""
        return self.path.name

    @property
    def readable(self) -> bool:
        """Whether its messages are read: complete, or being recorded (as far as written so far)."""
        return self.state in ("complete", "recording")

    def topic_of(self, ros_type: str) -> str | None:
        """The segment's topic carrying `ros_type`."""
        return next((topic for topic, (msgtype, _) in sorted(self.topics.items()) if msgtype == ros_type), None)

    def note(self) -> str:
        """What to tell about a segment that is not complete ('' for a complete one)."""
        recording = f"being recorded; nothing readable so far: {self.problem}" if self.problem else \
            "being recorded (so far)"
        return {"killed": "unfinished (recorder killed) — run `plem bag repair`", "recording": recording,
                "damaged": f"damaged: {self.problem} — run `plem bag repair`",
                "unreadable": f"unreadable: {self.problem}"}.get(self.state, "")

    def error(self) -> BagError | None:
        """The WHAT/WHY/HOW of a damaged or unreadable segment; None for the others."""
        if self.state == "damaged":
            return BagError(f"segment {self.name} is damaged", what="a bag file that reads back whole",
                            why=self.problem, how=f"run `plem bag repair {self.path}`: it rebuilds the segment from "
                                                   "what can be read and keeps the original if that fails")
        if self.state == "unreadable":
            return BagError(f"segment {self.name} cannot be read", what="a segment with a readable metadata.yaml and "
                            "bag file, as the recorder writes them", why=self.problem,
                            how=f"restore the files of {self.path}, or delete it")
        return None


def segment_info(path: Path) -> SegmentInfo:
    """What a segment holds, and whether it is complete, being recorded, unfinished or damaged."""
    file = bag_file(path)
    storage = "mcap" if file is not None and file.suffix == ".mcap" else "sqlite3"
    info = SegmentInfo(path, storage, "complete", directory_size(path),
                       path.with_name(path.name + KEEP_SUFFIX).exists())
    try:
        metadata = bag_metadata(path)
        if metadata is None:
            info.state = "recording" if being_written(path) else "killed"
            if info.state == "recording" and file is not None:
                _read_so_far(info, file)
            return info
        extent = extent_of(metadata)
        info.topics = {entry["topic_metadata"]["name"]: (entry["topic_metadata"]["type"], int(entry["message_count"]))
                       for entry in metadata["topics_with_message_count"]}
    except PlemError as error:
        info.state, info.problem = "unreadable", f"{error.summary}: {error.why}"
        return info
    except (KeyError, TypeError, ValueError) as error:
        info.state, info.problem = "unreadable", f"metadata.yaml: {type(error).__name__}: {error}"
        return info
    info.start_ns, info.duration_ns = extent[0], extent[1] - extent[0]
    if file is not None:
        _check_readable(info, file)
    return info


def _read_so_far(info: SegmentInfo, file: Path) -> None:
    """The topics, message counts, start and duration of a segment being recorded, from what its file holds."""
    try:
        if info.storage == "mcap":
            index = mcap_index(file)
            topics, extent = index.topics(), index.extent()
        else:
            topics, extent = _sqlite3_so_far(file)
    except PlemError as error:
        info.problem = f"{error.summary}: {error.why}"
        return
    info.topics = topics
    if extent is not None:
        info.start_ns, info.duration_ns = extent[0], extent[1] - extent[0]


def _check_readable(info: SegmentInfo, file: Path) -> None:
    """Mark a segment whose file holds less than its metadata.yaml says (truncated, damaged) damaged or unreadable."""
    expected = sum(count for _, count in info.topics.values())
    try:
        if info.storage == "mcap":
            index = mcap_index(file)
            readable, whole = index.counts().total(), index.whole
        else:
            readable, whole = _sqlite3_count(file), True
    except BagError as error:
        info.state, info.problem = "unreadable", f"{error.summary}: {error.why}"
        return
    if readable < expected or not whole:
        ending = "" if whole else "ends before its summary (truncated); "
        info.state = "damaged"
        info.problem = f"{file.name} {ending}{readable} of {expected} messages can be read"


# -- one robot ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Gap:
    """Cycles missing between two consecutive recorded rt_raw samples."""

    segment: str
    offset_s: float
    after_cycle: int
    missing: int


@dataclass
class CycleDrops:
    """rt_raw cycle continuity over a robot's segments in time order."""

    samples: int = 0
    gap_count: int = 0
    missing: int = 0
    new_runs: int = 0
    gaps: list[Gap] = field(default_factory=list)
    not_compared: list[str] = field(default_factory=list)   # segment boundaries continuity is not checked across

    def add(self, segment: SegmentInfo, payloads: Payloads, previous: int | None) -> int:
        """Count the gaps in one batch of cycles following `previous` (None: a fresh start); its last cycle."""
        cycles = raw_field(payloads.buffer, payloads.starts, "cycle").astype(np.int64)
        steps = np.diff(cycles, prepend=cycles[0] if previous is None else previous)
        jumps = np.flatnonzero(steps > 1)
        self.samples += len(cycles)
        self.gap_count += len(jumps)
        self.missing += int(steps[jumps].sum() - len(jumps))
        self.new_runs += int(np.count_nonzero(steps < 0))
        for at in jumps[:max(0, LISTED_GAPS - len(self.gaps))]:
            self.gaps.append(Gap(segment.name, round((int(payloads.stamps[at]) - (segment.start_ns or 0)) / 1e9, 3),
                                 int(cycles[at] - steps[at]), int(steps[at] - 1)))
        return int(cycles[-1])


@dataclass
class RobotSummary:
    """What `plem bag info` reports for one robot."""

    robot_id: str
    directory: Path
    segments: list[SegmentInfo]
    drops: CycleDrops
    recorder: dict[str, Any] | None
    faults: list[dict[str, Any]]
    deletions: list[tuple[str, int]]    # (latest reason of a kind, how many)
    stops: list[dict[str, Any]] = field(default_factory=list)    # recording stops that ended, with what was lost
    problems: list[PlemError] = field(default_factory=list)      # damaged segments, an unreadable event log


def _cycle_drops(segments: list[SegmentInfo], deleted: list[str]) -> CycleDrops:
    """Cycle gaps within and across segments (one being recorded as far as written); not across a segment that was
    deleted, or is killed or unreadable."""
    drops = CycleDrops()
    previous: int | None = None
    last_name = ""
    breaks: list[str] = []
    for segment in segments:
        if not segment.readable:
            breaks.append(f"{segment.name} ({segment.state})")
            continue
        topic = segment.topic_of(MONITOR_TOPICS["rt_raw"])
        if topic is None:
            continue
        breaks += [f"{name} (deleted)" for name in deleted if last_name < name < segment.name]
        if breaks and previous is not None:
            drops.not_compared += breaks
            previous = None
        breaks = []
        for payloads in read_topic(segment.path, topic, head=CYCLE_END):
            previous = drops.add(segment, payloads, previous)
        last_name = segment.name
    return drops


def last_message(segments: list[SegmentInfo], ros_type: str) -> tuple[int, bytes] | None:
    """(log time, payload) of the newest message of `ros_type` in the segments that read."""
    for segment in reversed(segments):
        topic = segment.topic_of(ros_type)
        if not segment.readable or topic is None:
            continue
        last = None
        for payloads in read_topic(segment.path, topic):
            last = payloads
        if last is not None and len(last.starts):
            return int(last.stamps[-1]), last.message(len(last.starts) - 1)
    return None


def _recorder_counts(segments: list[SegmentInfo]) -> dict[str, Any] | None:
    """The recorder's own queues in the newest rt_monitor_stats: messages not recorded, ring records lost."""
    from plem.middleware.types import library

    found = last_message(segments, MONITOR_TOPICS["rt_monitor_stats"])
    if found is None:
        return None
    stamp, data = found
    stats: Any = library().store.deserialize_cdr(data, MONITOR_TOPICS["rt_monitor_stats"])  # a generated message
    queues = {queue.name: int(queue.dropped) for queue in stats.queues}
    return {"time_ns": stamp, "bag_dropped": queues.get("bag"),
            "ring_dropped": {name: queues[name] for name in ("rt_raw", "events", "stats") if name in queues}}


def _deletion_kinds(entries: list[dict[str, Any]]) -> list[tuple[str, int]]:
    """Deletion reasons grouped by their wording with the figures left out; the latest reason of each group."""
    reasons = [str(entry.get("reason", "")) for entry in entries]
    kinds = [re.sub(r"\d+(\.\d+)?", "#", reason) for reason in reasons]
    latest = dict(zip(kinds, reasons, strict=True))
    return [(latest[kind], count) for kind, count in Counter(kinds).most_common()]


def robot_segments(robot: RobotBags) -> list[SegmentInfo]:
    """The robot's segments found, each with its state."""
    return [segment_info(path) for path in robot.segments]


def summarise(robot: RobotBags) -> RobotSummary:
    """Segments, drops, the recorder's counters, faults, deletions and stops of one robot, and what cannot be read."""
    segments = robot_segments(robot)
    problems: list[PlemError] = [error for segment in segments if (error := segment.error()) is not None]
    try:
        entries = list(read_event_log(robot.directory))
    except PlemError as error:
        entries = []
        problems.append(error)
    if not robot.whole:
        entries = [entry for entry in entries if entry.get("segment") == robot.segments[0].name]
    deleted = [entry for entry in entries if entry.get("kind") == "deleted"]
    try:
        drops = _cycle_drops(segments, [str(entry.get("segment", "")) for entry in deleted])
        recorder = _recorder_counts(segments)
    except BagError as error:
        drops, recorder = CycleDrops(), None
        problems.append(error)
    return RobotSummary(robot.robot_id, robot.directory, segments, drops, recorder,
                        [entry for entry in entries if entry.get("kind") == "fault"], _deletion_kinds(deleted),
                        [entry for entry in entries if entry.get("kind") in ("recording_resumed", "recording_ended")],
                        problems)
