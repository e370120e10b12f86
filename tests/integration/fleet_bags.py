"""Bags for the fleet export's tests and benchmark, recorded through the recorder's own code paths: rt_raw and
joint_states as the recorder's batch serialiser writes them (numpy, 100 cycles a batch, as it pumps every 100 ms),
rt_events and rt_monitor_stats as single messages, with who recorded it in each segment's metadata."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from plem.control.events import Event, EventKind
from plem.control.modes import Mode
from plem.ipc.records import raw_override_column, raw_record_length
from plem.middleware.monitor_feed import MONITOR_TOPICS
from plem.middleware.raw_cdr import raw_sizes
from plem.middleware.types import library
from plem.recording.bulk_cdr import JointStateEncoder, raw_payloads
from plem.recording.identity import identity
from plem.recording.recorder import Messages, Recorder
from plem.recording.segment import SegmentWriter
from plem.recording.settings import RecordingSettings

S = 1_000_000_000
MS = 1_000_000
LIBRARY = library()
STORE = LIBRARY.store
URDF = '<?xml version="1.0"?>\n<robot name="arm">\n  <link name="base_link"/>\n</robot>\n'
BATCH = 100


def joints(dof: int) -> list[str]:
    return [f"joint{index + 1}" for index in range(dof)]


def ring_records(first: int, count: int, dof: int, rng: np.random.Generator, lost_after: int | None = None
                 ) -> np.ndarray:
    """rt_raw ring records of cycles `first`.. (3 cycles lost after cycle `lost_after`), random joint rows."""
    records = rng.normal(size=(count, raw_record_length(dof)))
    cycles = np.arange(first, first + count)
    if lost_after is not None:
        cycles = np.where(cycles > lost_after, cycles + 3, cycles)
    records[:, 0] = cycles
    records[:, 1] = 10**12 + cycles * MS
    records[:, 2] = cycles // 700 % 3
    records[:, 3] = (cycles // 900) % 2
    records[:, 4] = 1
    records[:, 5] = rng.integers(1_000, 90_000, count)
    records[:, 6] = rng.integers(1_000, 400_000, count)
    records[:, raw_override_column(dof)] = rng.uniform(0, 1, count)
    return records


def recorder_for(robot_dir: Path, clock: list[int], dof: int, segment_s: float = 1.0) -> Recorder:
    """The recorder as a launch starts it, on the clock `clock`, writing who records into every segment."""
    settings = RecordingSettings(robot_dir, segment_s=segment_s)
    return Recorder(settings, robot_dir.name, MONITOR_TOPICS, STORE, clock=lambda: clock[0],
                    disk_usage=lambda _: (100, 10, 90), description=URDF,
                    identity=identity(robot_dir.name, "PE07I7E0E001", "Indy7V2", joints(dof)))


def record_robot(robot_dir: Path, start_ns: int, cycles: int, dof: int = 6, seed: int = 0,
                 segment_s: float = 1.0, lost_after: int | None = None) -> None:
    """`cycles` cycles at 1 kHz from `start_ns` of one robot into 1 s segments, a fault at cycle 1200."""
    rng = np.random.default_rng(seed)
    clock = [start_ns]
    recorder = recorder_for(robot_dir, clock, dof, segment_s)
    encoder = JointStateEncoder(joints(dof))
    for first in range(0, cycles, BATCH):
        count = min(BATCH, cycles - first)
        records = ring_records(first, count, dof, rng, lost_after)
        stamps = start_ns + np.arange(first, first + count, dtype=np.int64) * MS
        clock[0] = int(stamps[-1])
        every = np.flatnonzero(np.arange(first, first + count) % 10 == 0)
        recorder.record([Messages("rt_raw", stamps, raw_payloads(records, stamps, dof)),
                         Messages("joint_states", stamps[every], encoder.payloads(records[every], stamps[every]))])
        stats = LIBRARY.new(MONITOR_TOPICS["rt_monitor_stats"], cycles=first + count, overruns=first // 1000,
                            period_ns=MS, mode="hold", latency=LIBRARY.new("plem_msgs/msg/TimingStats", samples=first,
                                                                           p999_us=float(rng.uniform(20, 90))),
                            queues=[LIBRARY.new("plem_msgs/msg/QueueStats", name="rt_raw", capacity=4096,
                                                written=first + count, dropped=3)])
        recorder.rt_monitor_stats(stats, int(stamps[-1]))
        if first <= 1200 < first + count:
            stamp = start_ns + 1200 * MS
            event = Event(EventKind.FAULT, "drive_fault", "joint2: drive fault 0x7121 (following error)", Mode.FAULT,
                          1200, stamp, 0.0, Mode.TRAJECTORY)
            recorder.rt_event(LIBRARY.new(MONITOR_TOPICS["rt_events"], header=LIBRARY.new(
                "std_msgs/msg/Header", stamp=LIBRARY.stamp(stamp)), cycle=1200, monotonic_ns=10**12 + 1200 * MS,
                kind="fault", cause="drive_fault", reason=event.reason, mode="fault", previous_mode="trajectory"),
                event, stamp)
    recorder.close()


def record_old_raw(robot_dir: Path, start_ns: int, cycles: int, dof: int = 6) -> None:
    """One segment with RtRaw as plem recorded it before speed_override (its old definition in the bag), and no
    identity in its metadata, as an older plem wrote it."""
    text = (Path(__file__).parents[2] / "src/plem/middleware/interfaces/plem_msgs/msg/RtRaw.msg").read_text()
    store = get_typestore(Stores.ROS2_JAZZY)
    store.register(get_types_from_msg(text[:text.index("# The speed override")], MONITOR_TOPICS["rt_raw"]))
    robot_dir.mkdir(parents=True, exist_ok=True)
    writer = SegmentWriter(robot_dir / f"{robot_dir.name}_2020_01_01-00_00_00", [(f"/{robot_dir.name}/rt_raw",
                                                                  MONITOR_TOPICS["rt_raw"])], store)
    stamps = start_ns + np.arange(cycles, dtype=np.int64) * MS
    payloads = raw_payloads(ring_records(0, cycles, dof, np.random.default_rng(7)), stamps, dof)
    old = np.ascontiguousarray(payloads[:, :raw_sizes(dof)[1]])
    writer.append_groups([(f"/{robot_dir.name}/rt_raw", stamps, old)])
    writer.close()
