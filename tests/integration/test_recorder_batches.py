"""The recorder's batch path: bulk CDR against rosbags' serialiser, one ring copy per read, and segments named by
their first message, read back with rosbags."""

from __future__ import annotations

import time
import uuid
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag2 import Reader

from plem.ipc.records import raw_record_length
from plem.ipc.ring import SlotRing
from plem.ipc.segment import SharedSegment
from plem.middleware.monitor_feed import MONITOR_TOPICS
from plem.middleware.raw_cdr import RawEncoder
from plem.middleware.types import library
from plem.recording.archive import directory_size
from plem.recording.bulk_cdr import JointStateEncoder, raw_payloads
from plem.recording.disk_use import STATS_QUEUES, disk_use, size
from plem.recording.recorder import Messages, Recorder
from plem.recording.settings import RecordingSettings

S = 1_000_000_000
START = 1_800_000_000 * S + 700_000_000
LIBRARY = library()
STORE = LIBRARY.store


def records(count: int, dof: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    values = rng.normal(size=(count, raw_record_length(dof)))
    values[:, :7] = rng.integers(0, 2**40, size=(count, 7))
    values[:, 2:5] = rng.integers(0, 2, size=(count, 3))
    values[0, 5] = 2**33                                       # a latency beyond uint32: clipped as the encoder does
    return values


@pytest.mark.parametrize("dof", [6, 7])
def test_bulk_payloads_are_the_bytes_of_the_message_serialisers(dof: int):
    values = records(20, dof)
    stamps = START + np.arange(20, dtype=np.int64) * 1_234_567
    encoder = RawEncoder(dof)
    assert [bytes(row) for row in raw_payloads(values, stamps, dof)] == [
        encoder.encode(record, int(stamp)) for record, stamp in zip(values, stamps, strict=True)]
    names = [f"joint_{'x' * index}" for index in range(dof)]
    types = STORE.types
    for row, record, stamp in zip(JointStateEncoder(names).payloads(values, stamps), values, stamps, strict=True):
        position, velocity, effort = record[7:7 + 3 * dof].reshape(3, dof)
        message = types["sensor_msgs/msg/JointState"](
            header=types["std_msgs/msg/Header"](stamp=types["builtin_interfaces/msg/Time"](
                sec=int(stamp) // S, nanosec=int(stamp) % S), frame_id=""),
            name=names, position=position, velocity=velocity, effort=effort)
        assert bytes(row) == bytes(STORE.serialize_cdr(message, "sensor_msgs/msg/JointState"))


def test_one_ring_read_copies_every_new_record_and_counts_those_overwritten():
    name = f"/test_batch_ring_{uuid.uuid4().hex[:8]}"
    ring = SlotRing.create(name, 16, 8)
    try:
        reader = ring.reader()
        for value in range(5):
            ring.write_values(np.array([value, -value], np.float64))
        assert reader.read_values_many()[:, 0].tolist() == [0, 1, 2, 3, 4]
        assert reader.read_values_many().shape == (0, 2)
        for value in range(5, 20):                               # 15 records into 8 slots: the 7 oldest are gone
            ring.write_values(np.array([value, -value], np.float64))
        assert reader.read_values_many()[:, 0].tolist() == list(range(12, 20)) and reader.dropped == 7
    finally:
        ring.remove()
        SharedSegment.unlink(name)


def segment_name_time(wall_ns: int) -> str:
    return time.strftime("%Y_%m_%d-%H_%M_%S", time.gmtime(wall_ns // S))


def test_segments_are_named_by_their_first_message_when_the_recorder_runs_behind(tmp_path: Path):
    """The recorder's clock is 29 s past the messages it is handed (a recorder running behind): every segment is
    still named by the stamp of the first message it holds."""
    dof = 6
    recorder = Recorder(RecordingSettings(tmp_path / "arm", segment_s=1.0), "arm", MONITOR_TOPICS, STORE,
                        clock=lambda: START + 29 * S, description="<robot name='arm'/>")
    values = records(3500, dof)
    stamps = START + np.arange(3500, dtype=np.int64) * 1_000_000
    values[:, 0] = np.arange(3500)
    stats = library().new(MONITOR_TOPICS["rt_monitor_stats"]).serialize()
    for first in range(0, 3500, 100):                            # batches of 100 ms, as the recorder process reads
        batch = slice(first, first + 100)
        recorder.record([Messages("rt_raw", stamps[batch], raw_payloads(values[batch], stamps[batch], dof)),
                         Messages.one("rt_monitor_stats", int(stamps[first + 50]) + 1, stats)])
    recorder.close()
    segments = sorted(path for path in (tmp_path / "arm").iterdir() if path.is_dir())
    assert len(segments) == 4
    cycles = []
    for segment in segments:
        with Reader(segment) as reader:
            messages = list(reader.messages())
            assert segment.name == f"arm_{segment_name_time(messages[0][1])}", "named by its first message"
            assert reader.start_time == messages[0][1]
            cycles += [STORE.deserialize_cdr(data, connection.msgtype).cycle for connection, _, data in messages
                       if connection.topic == "/arm/rt_raw"]
            assert {connection.topic for connection, _, _ in messages} == {
                "/arm/rt_raw", "/arm/rt_monitor_stats", "/arm/robot_description"}
            assert [stamp for _, stamp, _ in messages] == sorted(stamp for _, stamp, _ in messages)
    assert cycles == list(range(3500))


def test_the_disk_use_estimate_matches_what_a_recording_takes(tmp_path: Path):
    """Ten seconds as the recorder writes them (rt_raw at 1 kHz, joint_states at 100 Hz, stats at 10 Hz naming the
    queues it reports, 5 s segments): the bag directory's growth per hour is within 5 % of the estimate."""
    dof, names = 6, [f"joint{index}" for index in range(6)]
    settings = RecordingSettings(tmp_path / "arm", segment_s=5.0, retention_s=1800.0)
    estimate = disk_use(settings, names, 0.001, 100.0, LIBRARY)
    recorder = Recorder(settings, "arm", MONITOR_TOPICS, STORE, clock=lambda: START)
    values = records(10_000, dof)
    stamps = START + np.arange(10_000, dtype=np.int64) * 1_000_000
    new = LIBRARY.new
    stats = new(MONITOR_TOPICS["rt_monitor_stats"], queues=[
        new("plem_msgs/msg/QueueStats", name=name, capacity=4096, written=10**6) for name in STATS_QUEUES]).serialize()
    joints = JointStateEncoder(names)
    for first in range(0, 10_000, 100):
        batch, picks = slice(first, first + 100), np.arange(first, first + 100, 10)
        recorder.record([Messages("rt_raw", stamps[batch], raw_payloads(values[batch], stamps[batch], dof)),
                         Messages("joint_states", stamps[picks], joints.payloads(values[picks], stamps[picks])),
                         Messages.one("rt_monitor_stats", int(stamps[first]), stats)])
    recorder.close()
    per_hour = directory_size(tmp_path / "arm") * 360
    assert per_hour == pytest.approx(estimate.bytes_per_hour, rel=0.05)
    assert estimate.retained_bytes == pytest.approx(estimate.bytes_per_hour * 1805 / 3600)
    text = estimate.describe()
    assert text.startswith(f"about {size(estimate.bytes_per_hour)} an hour at 1000 Hz; retention 30 min keeps at most")
