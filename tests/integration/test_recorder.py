"""The recorder on a real disk with an injected clock and disk usage: segments, retention, the disk guard,
the flight recorder's keep marks and a full disk. Bags are read back with rosbags."""

from __future__ import annotations

import contextlib
import errno
import json
import os
import subprocess
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag2 import Reader

from plem.cli.app import run
from plem.control.events import Event, EventKind
from plem.control.modes import Mode
from plem.ipc.records import raw_record_length
from plem.middleware.monitor_feed import MONITOR_TOPICS
from plem.middleware.raw_cdr import RawEncoder
from plem.middleware.types import library
from plem.recording.archive import read_event_log
from plem.recording.recorder import Recorder
from plem.recording.settings import RecordingSettings

S = 1_000_000_000
START = 1_800_000_000 * S
LIBRARY = library()
STORE = LIBRARY.store
RAW = "/arm/rt_raw"


class Disk:
    """An injected disk-usage reading: `used` bytes of `total`."""

    def __init__(self, total: int = 100 * 2**30, used: int = 10 * 2**30) -> None:
        self.total, self.used = total, used

    def __call__(self, _: Path) -> tuple[int, int, int]:
        return self.total, self.used, self.total - self.used


class Clock:
    def __init__(self) -> None:
        self.now = START

    def __call__(self) -> int:
        return self.now


def make(tmp_path: Path, clock: Clock, disk: Disk, **settings: float) -> Recorder:
    recorder = Recorder(RecordingSettings(tmp_path / "arm", **{"segment_s": 1.0, **settings}), "arm",
                        MONITOR_TOPICS, STORE, clock=clock, disk_usage=disk)
    return recorder


def feed(recorder: Recorder, clock: Clock, cycles: range, period_ns: int = 1_000_000) -> None:
    """rt_raw for `cycles`, one per period from START; the clock follows the data."""
    encoder, record = RawEncoder(6), np.zeros(raw_record_length(6))
    for cycle in cycles:
        record[0], stamp = cycle, START + cycle * period_ns
        clock.now = stamp
        recorder.rt_raw(encoder.encode(record, stamp), stamp)


def recorded(directory: Path) -> Iterator[tuple[str, int, int]]:
    """(segment, stamp, cycle) of every rt_raw message in the closed segments (with metadata), in segment order."""
    for segment in sorted(p for p in directory.iterdir() if p.is_dir() and (p / "metadata.yaml").exists()):
        with Reader(segment) as reader:
            for connection, stamp, data in reader.messages():
                if connection.topic == RAW:
                    yield segment.name, stamp, STORE.deserialize_cdr(data, connection.msgtype).cycle


def log_kinds(directory: Path) -> list[str]:
    return [entry["kind"] for entry in read_event_log(directory)]


def fault(recorder: Recorder, clock: Clock, cycle: int, kind: EventKind = EventKind.FAULT,
          reason: str = "joint2 drive fault 0x7121") -> None:
    stamp = START + cycle * 1_000_000
    clock.now = stamp
    event = Event(kind, kind.value, reason, Mode.FAULT, cycle, stamp, 0.0)
    recorder.rt_event(library().new(MONITOR_TOPICS["rt_events"], kind=kind.value, cycle=cycle), event, stamp)


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_segments_rotate_and_read_back_whole(tmp_path: Path, storage: str):
    clock, disk = Clock(), Disk()
    recorder = make(tmp_path, clock, disk, storage=storage)
    feed(recorder, clock, range(3500))
    recorder.close()
    rows = list(recorded(tmp_path / "arm"))
    assert [cycle for _, _, cycle in rows] == list(range(3500))
    assert all(b[1] > a[1] for a, b in zip(rows, rows[1:], strict=False)), "stamps strictly increase"
    assert len({segment for segment, _, _ in rows}) == 4, "1 s segments of 3.5 s of cycles"
    assert log_kinds(tmp_path / "arm").count("segment_closed") == 4


def test_retention_deletes_old_closed_segments_with_the_reason(tmp_path: Path):
    clock, disk = Clock(), Disk()
    recorder = make(tmp_path, clock, disk, retention_s=2.0)
    feed(recorder, clock, range(4500))            # segments end at 1, 2, 3, 4 s; the fifth is open
    recorder.maintain()
    kept = sorted({segment for segment, _, _ in recorded(tmp_path / "arm")} - {recorder.segment.name})
    assert len(kept) == 2, "only the segments that ended within the last 2 s stay"
    deletions = [e for e in read_event_log(tmp_path / "arm") if e["kind"] == "deleted"]
    assert len(deletions) == 2 and all("older than the retention window" in e["reason"] for e in deletions)
    assert recorder.segment.directory.exists()
    recorder.close()


def test_disk_guard_deletes_oldest_first_down_to_the_threshold_never_the_open_one(tmp_path: Path):
    clock, disk = Clock(), Disk()
    recorder = make(tmp_path, clock, disk, disk_threshold=70.0)
    feed(recorder, clock, range(4500))
    sizes = [s.size for s in recorder.closed]
    disk.used = int(0.70 * disk.total) + sizes[0] + sizes[1] // 2    # two oldest must go to get under 70 %
    recorder.maintain()
    deletions = [e for e in read_event_log(tmp_path / "arm") if e["kind"] == "deleted"]
    assert [e["segment"] for e in deletions] == sorted(e["segment"] for e in deletions) and len(deletions) == 2
    assert all("above disk_threshold 70 %" in e["reason"] for e in deletions)
    assert len(recorder.closed) == 2 and recorder.segment.directory.exists()
    disk.used = disk.total - 1                                         # nothing closed may go: recording stops
    clock.now += 2 * S
    for segment in recorder.closed:
        recorder.archive.keep(Path(segment.path), "test")
    recorder.closed = [recorder.archive.closed_segment(Path(s.path)) for s in recorder.closed]
    recorder.maintain()
    assert log_kinds(tmp_path / "arm").count("deleted") == 2 and "recording_stopped" in log_kinds(tmp_path / "arm")
    assert len(recorder.closed) == 3 and recorder.segment is None, "the open segment was finished, not deleted"
    recorder.close()


def test_a_fault_keeps_the_window_before_it_against_retention(tmp_path: Path):
    clock, disk = Clock(), Disk()
    recorder = make(tmp_path, clock, disk, retention_s=1.0, flight_window_s=1.5)
    feed(recorder, clock, range(3700))
    fault(recorder, clock, 3700)
    entry = next(e for e in read_event_log(tmp_path / "arm") if e["kind"] == "fault")
    assert entry["segment"] == recorder.segment.name and entry["offset_s"] == pytest.approx(0.7, abs=0.01)
    assert entry["cycle"] == 3700 and "0x7121" in entry["reason"]
    feed(recorder, clock, range(3701, 9000))      # much later: retention would remove the fault's segments
    recorder.maintain()
    recorder.close()
    cycles = [cycle for _, _, cycle in recorded(tmp_path / "arm")]
    window = set(range(3700 - 1500, 3700))
    assert window <= set(cycles), "the 1.5 s before the fault are still on disk"
    assert 1000 not in cycles, "unkept old segments went"
    keep_marks = sorted(p.name for p in (tmp_path / "arm").glob("*.keep"))
    assert keep_marks == sorted(f"{name}.keep" for name in entry["kept"]) and len(keep_marks) == 2


def test_a_reaction_keeps_the_window_before_it_as_a_fault_does(tmp_path: Path):
    clock, disk = Clock(), Disk()
    recorder = make(tmp_path, clock, disk, retention_s=1.0, flight_window_s=1.5)
    feed(recorder, clock, range(3700))
    fault(recorder, clock, 3700, EventKind.REACTION, "force x > 20 N (measured 23.5): stop")
    entry = next(e for e in read_event_log(tmp_path / "arm") if e["kind"] == "reaction")
    assert entry["cycle"] == 3700 and "force x > 20 N" in entry["reason"] and "reaction_time_ns" in entry
    feed(recorder, clock, range(3701, 9000))
    recorder.maintain()
    recorder.close()
    assert set(range(3700 - 1500, 3700)) <= {cycle for _, _, cycle in recorded(tmp_path / "arm")}


def test_the_fault_offset_counts_from_the_segments_earliest_message(tmp_path: Path):
    """A stats record stamped before the rotation lands in the new segment: a reader's start time is then
    earlier than the rotation, and the logged offset must count from it."""
    clock, disk = Clock(), Disk()
    recorder = make(tmp_path, clock, disk)
    feed(recorder, clock, range(1001))                      # cycle 1000 opens the second segment
    late = START + 987 * 1_000_000
    recorder.rt_monitor_stats(library().new(MONITOR_TOPICS["rt_monitor_stats"]), late)
    feed(recorder, clock, range(1001, 1400))
    fault(recorder, clock, 1400)
    recorder.close()
    entry = next(e for e in read_event_log(tmp_path / "arm") if e["kind"] == "fault")
    with Reader(tmp_path / "arm" / entry["segment"]) as reader:
        assert reader.start_time == late
        assert reader.start_time + round(entry["offset_s"] * 1e9) == entry["fault_time_ns"]


@contextlib.contextmanager
def tmpfs(parent: Path, size: str) -> Iterator[Path]:
    """A tmpfs of `size` (mount's notation, e.g. 2m) under `parent` (needs root and mount), unmounted afterwards."""
    mount = parent / f"disk_{uuid.uuid4().hex[:6]}"
    mount.mkdir()
    result = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(mount)], capture_output=True,
                            text=True)
    if result.returncode != 0:
        pytest.skip(f"cannot mount a small tmpfs here: {result.stderr.strip()}")
    try:
        yield mount
    finally:
        subprocess.run(["umount", "--lazy", str(mount)], check=True)


@pytest.fixture
def small_disk(tmp_path: Path) -> Iterator[Path]:
    """A 2 MiB tmpfs."""
    with tmpfs(tmp_path, "2m") as mount:
        yield mount


def open_files_under(directory: Path) -> list[str]:
    """Files under `directory` this process holds open, but the robot directory the recorder holds (`arm`)."""
    names = []
    for fd in Path("/proc/self/fd").iterdir():
        with contextlib.suppress(OSError):
            names.append(os.readlink(fd))
    return [name for name in names if name.startswith(str(directory)) and name != str(directory / "arm")]


class Samples:
    """rt_raw at 1 kHz from START, with an rt_monitor_stats every 100 cycles carrying the recorder's own queues as
    MonitorFeed builds them, and the guard run every 1000 cycles as the recorder process does once a second."""

    def __init__(self, recorder: Recorder, clock: Clock) -> None:
        self.recorder, self.clock, self.cycle = recorder, clock, 0
        self.encoder, self.record = RawEncoder(6), np.zeros(raw_record_length(6))

    def next(self) -> None:
        stamp = self.clock.now = START + self.cycle * 1_000_000
        self.record[0] = self.cycle
        self.recorder.rt_raw(self.encoder.encode(self.record, stamp), stamp)
        if self.cycle % 100 == 0:
            queues = [LIBRARY.new("plem_msgs/msg/QueueStats", name=q.name, written=q.written, dropped=q.dropped)
                      for q in self.recorder.queues()]
            self.recorder.rt_monitor_stats(LIBRARY.new(MONITOR_TOPICS["rt_monitor_stats"], queues=queues), stamp)
        if self.cycle % 1000 == 0:
            self.recorder.maintain()
        self.cycle += 1

    def until(self, condition: Callable[[], bool], limit: int = 100_000) -> None:
        """Feed cycles until `condition` holds (at most `limit` cycles)."""
        for _ in range(limit):
            if condition():
                return
            self.next()
        raise AssertionError("the condition never held")


def test_a_full_disk_keeps_the_segment_counts_the_loss_and_recording_resumes(small_disk: Path, caplog,
                                                                            capsys: pytest.CaptureFixture[str]):
    """The only segment is being written when the disk fills: it is finished readable, never deleted by the guard,
    no file stays open, what could not be recorded is counted and reported once, and recording resumes in a new
    segment once the space is back."""
    filler = small_disk / "filler"
    filler.write_bytes(bytes(800 * 1024))                   # about 1.2 MiB left for the recorder
    clock = Clock()
    robot = small_disk / "arm"
    recorder = Recorder(RecordingSettings(robot, segment_s=3600.0, disk_threshold=100.0), "arm", MONITOR_TOPICS,
                        STORE, clock=clock)                  # never above the threshold: the disk refuses a write
    samples = Samples(recorder, clock)
    samples.next()                                          # the first message opens the first segment
    first = recorder.segment.directory
    samples.until(lambda: recorder.stopped is not None)
    assert recorder.stopped.errno == errno.ENOSPC and recorder.stopped.interrupted == str(first)
    assert open_files_under(small_disk) == [], "every file of the stopped segment is closed"
    written = recorder.written
    samples.until(lambda: recorder.unrecorded >= 5000)      # five guard passes with the disk still full
    assert recorder.stopped is not None and recorder.segment is None
    assert first.is_dir() and (first / "metadata.yaml").is_file(), "the guard left the interrupted segment alone"
    cycles = [cycle for segment, _, cycle in recorded(robot)]
    assert cycles == list(range(len(cycles))) and len(cycles) > 1000, "the first segment reads back whole"
    with Reader(first) as reader:
        assert reader.message_count == written
    filler.unlink()                                          # the space comes back
    samples.until(lambda: recorder.stopped is None)
    lost = recorder.unrecorded
    assert lost >= 5000 and recorder.written + lost == samples.cycle + samples.cycle // 100 + 1
    resumed_at = samples.cycle
    samples.until(lambda: samples.cycle >= resumed_at + 500)
    recorder.close()

    entries = list(read_event_log(robot))
    kinds = [entry["kind"] for entry in entries]
    assert kinds.count("recording_stopped") == 1 and kinds.count("recording_resumed") == 1 and "deleted" not in kinds
    [resumed] = [entry for entry in entries if entry["kind"] == "recording_resumed"]
    assert resumed["not_recorded"] == lost and resumed["not_recorded_topics"]["rt_raw"] > 0
    stop_lines = [r.getMessage() for r in caplog.records if "recording stopped" in r.getMessage()]
    assert len(stop_lines) == 1 and "No space left on device" in stop_lines[0]
    assert f"finished with its {written} messages" in stop_lines[0] and "\nHOW: free space there" in stop_lines[0]
    assert any(f"{lost} messages not recorded" in r.getMessage() for r in caplog.records)
    after = [cycle for segment, _, cycle in recorded(robot) if segment != first.name]
    assert after[-1] == samples.cycle - 1 and after == list(range(after[0], samples.cycle)), "recorded again"

    assert run(["bag", "info", str(robot), "--format", "json"]) == 0
    (arm,) = json.loads(capsys.readouterr().out)["robots"]
    assert [s["state"] for s in arm["segments"]] == ["complete", "complete"]
    assert arm["stops"]["not_recorded"] == lost
    assert arm["drops"]["recorder"]["bag_dropped"] == lost, "the recorded rt_monitor_stats count it too"
    assert run(["bag", "info", str(robot)]) == 0
    assert f"recording stopped 1 time: {lost} messages not recorded" in capsys.readouterr().out


def test_a_full_disk_under_sqlite3_stops_recording_with_honest_counts(small_disk: Path):
    """sqlite3 reports a full disk as SQLITE_FULL: the same single stop, every message counted once, no file left
    open, and what its committed transactions hold is rebuilt into a readable bag once there is room."""
    filler = small_disk / "filler"
    filler.write_bytes(bytes(800 * 1024))
    clock = Clock()
    robot = small_disk / "arm"
    recorder = Recorder(RecordingSettings(robot, storage="sqlite3", segment_s=3600.0, disk_threshold=100.0), "arm",
                        MONITOR_TOPICS, STORE, clock=clock)
    samples = Samples(recorder, clock)
    samples.next()
    first = recorder.segment.directory
    samples.until(lambda: recorder.stopped is not None)
    assert recorder.stopped.errno == errno.ENOSPC and open_files_under(small_disk) == []
    samples.until(lambda: samples.cycle % 1000 == 999)
    recorder.close()
    fed = samples.cycle + (samples.cycle + 99) // 100
    assert recorder.written + recorder.unrecorded == fed and recorder.unrecorded > 0
    assert [entry["kind"] for entry in read_event_log(robot)].count("recording_stopped") == 1
    filler.unlink()
    assert run(["bag", "repair", str(robot)]) == 0
    with Reader(robot / first.name) as reader:
        assert 0 < reader.message_count <= recorder.written
