"""`plem bag info|plot|repair` on real bags written by the recorder: the figures shown, the timeline and the PNG
drawn from it, a segment read while it is recorded, killed segments rebuilt, and WHAT/WHY/HOW errors. The fast
RtRaw field reader is checked against rosbags."""

from __future__ import annotations

import json
import random
import re
import shutil
import uuid
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rosbags.rosbag2 import Reader

from plem.cli.app import run
from plem.control.events import Event, EventKind
from plem.control.modes import Mode
from plem.ipc.records import raw_record_length
from plem.middleware.monitor_feed import MONITOR_TOPICS, QueueCount
from plem.middleware.raw_cdr import RawEncoder, raw_dof, raw_dtype, raw_field, raw_sizes
from plem.middleware.types import library
from plem.recording import plot
from plem.recording.archive import Archive, iso_time
from plem.recording.bulk_cdr import raw_payloads
from plem.recording.recorder import Messages, Recorder
from plem.recording.segment import SegmentWriter
from plem.recording.settings import RecordingSettings
from plem.recording.status import remove_status, write_status
from plem.recording.summary import BagError, find_bags, pick_robot
from plem.recording.timeline import Marker, Timeline, read_timeline
from tests.e2e.cli import run_plem

S = 1_000_000_000
MS = 1_000_000
START = 1_800_000_000 * S                       # 2027-01-15T08:00:00Z
SEGMENTS = [f"arm_2027_01_15-08_00_0{second}" for second in range(4)]
JOINTS = [f"joint_{index + 1}" for index in range(6)]
LIBRARY = library()
STORE = LIBRARY.store


URDF = '<?xml version="1.0"?>\n<robot name="arm">\n  <link name="base_link"/>\n</robot>\n'
#: The events recorded at a sample: (kind, cause, reason, previous mode, mode); the mode holds until the next.
EVENTS = {1000: [(EventKind.MODE_CHANGED, "motion", "trajectory started", Mode.HOLD, Mode.TRAJECTORY)],
          1700: [(EventKind.FAULT, "drive_fault", "joint2 drive fault 0x7121", Mode.TRAJECTORY, Mode.FAULT)],
          2500: [(EventKind.FAULT_CLEARED, "reset_fault", "joint2 drive fault 0x7121", None, Mode.HOLD),
                 (EventKind.MODE_CHANGED, "drives_enabled", "drives enabled", Mode.FAULT, Mode.HOLD)]}


def cycle_of(index: int) -> int:
    """The cycle recorded at sample `index`: 5 cycles lost after 1499, a new driver run from sample 3000."""
    return index if index < 1500 else index + 5 if index < 3000 else index - 3000


def mode_of(index: int) -> Mode:
    """The mode at sample `index`: hold, a trajectory from 1000, a fault from 1700 cleared into hold at 2500."""
    return Mode.HOLD if index < 1000 or index >= 2500 else Mode.TRAJECTORY if index < 1700 else Mode.FAULT


def feed_samples(recorder: Recorder, now: list[int], indexes: range, start: int = START, raw: bool = True) -> None:
    """1 kHz rt_raw from `start` (commanded 0.01 rad ahead of measured) with joint_states, stats and `EVENTS`."""
    encoder, values = RawEncoder(6), np.zeros(raw_record_length(6))
    for index in indexes:
        stamp = now[0] = start + index * 1_000_000
        values[0], values[2], values[5] = cycle_of(index), mode_of(index), 20_000 + index % 100 * 10
        values[7:13] = np.arange(6) + index / 1000
        values[13:19] = -np.arange(6)
        values[25:31] = values[7:13] + 0.01
        if raw:
            recorder.rt_raw(encoder.encode(values, stamp), stamp)
        if index % 10 == 0:
            recorder.joint_state(LIBRARY.new(MONITOR_TOPICS["joint_states"], name=JOINTS, position=[0.0] * 6), stamp)
        if index % 100 == 0:
            queues = [LIBRARY.new("plem_msgs/msg/QueueStats", name=name, dropped=dropped)
                      for name, dropped in (("rt_raw", 4), ("events", 0), ("stats", 0), ("bag", 2 * (index > 0)))]
            recorder.rt_monitor_stats(LIBRARY.new(MONITOR_TOPICS["rt_monitor_stats"], queues=queues), stamp)
        for kind, cause, reason, previous, mode in EVENTS.get(index, []):
            event = Event(kind, cause, reason, mode, cycle_of(index), stamp, 0.0, previous)
            recorder.rt_event(LIBRARY.new(MONITOR_TOPICS["rt_events"], header=LIBRARY.new(
                "std_msgs/msg/Header", stamp=LIBRARY.stamp(stamp)), cycle=event.cycle, kind=kind.value, cause=cause,
                reason=reason, mode=str(mode), previous_mode="" if previous is None else str(previous)), event, stamp)


def recorder_of(robot_dir: Path, now: list[int], storage: str = "mcap", flush_period_s: float = 1.0) -> Recorder:
    """A started recorder of 1 s segments on the clock `now`, recording the URDF with every segment."""
    settings = RecordingSettings(robot_dir, storage=storage, segment_s=1.0, flush_period_s=flush_period_s)
    recorder = Recorder(settings, robot_dir.name, MONITOR_TOPICS, STORE, clock=lambda: now[0],
                        disk_usage=lambda _: (100, 10, 90), description=URDF)
    return recorder


def record(robot_dir: Path, storage: str = "mcap", samples: int = 3500, raw: bool = True, start: int = START,
           flush_period_s: float = 1.0) -> None:
    """One robot's bags: 1 s segments of `feed_samples`, a fault at sample 1700."""
    now = [start]
    recorder = recorder_of(robot_dir, now, storage, flush_period_s)
    feed_samples(recorder, now, range(samples), start, raw)
    recorder.close()


@pytest.fixture(scope="module")
def bag_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """bag_dir/arm recorded as MCAP, with one segment deleted before the first by retention."""
    directory = tmp_path_factory.mktemp("bags")
    record(directory / "arm")
    Archive(directory / "arm", "arm").log("deleted", "deleted segment arm_2027_01_15-07_00_00", segment=
                                           "arm_2027_01_15-07_00_00", reason="older than the retention window "
                                           "(3605 s > 3600 s)")
    return directory


def info_json(path: Path, capsys: pytest.CaptureFixture[str]) -> dict:
    assert run(["bag", "info", str(path), "--format", "json"]) == 0
    return json.loads(capsys.readouterr().out)


def killed_segment(destination: Path, cycles: int) -> None:
    """A segment as a killed recorder leaves it: its flushed chunks and no metadata.yaml."""
    encoder, values = RawEncoder(6), np.zeros(raw_record_length(6))
    writer = SegmentWriter(destination.parent / ".writing" / destination.name,
                           [("/arm/rt_raw", MONITOR_TOPICS["rt_raw"])], STORE)
    for cycle in range(cycles):
        values[0] = cycle
        writer.append("/arm/rt_raw", START + 10 * S + cycle * 1_000_000, encoder.encode(values, START))
        writer.flush_due()
    writer.flush()
    shutil.copytree(writer.directory, destination)
    writer.close()
    shutil.rmtree(writer.directory.parent)


def assert_plem_error(code: int, stderr: str, summary: str) -> None:
    assert code == 1
    assert f"ERROR: {summary}" in stderr and "\nWHAT: " in stderr and "\nWHY: " in stderr and "\nHOW: " in stderr
    assert "Traceback" not in stderr


# -- info ----------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_info_json_counts_segments_drops_faults_and_deletions(tmp_path: Path, bag_dir: Path, storage: str,
                                                               capsys: pytest.CaptureFixture[str]):
    if storage == "sqlite3":
        bag_dir = tmp_path
        record(bag_dir / "arm", storage)
    report = info_json(bag_dir, capsys)
    (arm,) = report["robots"]
    segments = arm["segments"]
    assert [s["name"] for s in segments] == SEGMENTS
    assert [s["storage"] for s in segments] == [storage] * 4 and all(s["state"] == "complete" for s in segments)
    assert [s["messages"]["/arm/rt_raw"] for s in segments] == [1000, 1000, 1000, 500]
    assert [s["messages"]["/arm/rt_events"] for s in segments] == [0, 2, 2, 0]
    assert [s["messages"]["/arm/robot_description"] for s in segments] == [1, 1, 1, 1]
    assert [s["kept"] for s in segments] == [True, True, False, False], "the 10 s before the fault are kept"
    assert segments[1]["start"] == "2027-01-15T08:00:01.000Z" and segments[3]["duration_s"] == pytest.approx(0.499)
    raw = arm["drops"]["rt_raw"]
    assert (raw["samples"], raw["gaps"], raw["missing_cycles"], raw["new_runs"]) == (3500, 1, 5, 1)
    assert raw["listed_gaps"] == [{"segment": SEGMENTS[1], "offset_s": 0.5, "after_cycle": 1499, "missing": 5}]
    recorder = arm["drops"]["recorder"]
    assert recorder["bag_dropped"] == 2 and recorder["ring_dropped"] == {"rt_raw": 4, "events": 0, "stats": 0}
    assert recorder["time"] == "2027-01-15T08:00:03.400Z", "the newest rt_monitor_stats"
    (fault,) = arm["faults"]
    assert (fault["segment"], fault["offset_s"], fault["cycle"]) == (SEGMENTS[1], 0.7, 1705)
    totals = report["totals"]
    assert totals["segments"] == 4 and totals["messages"]["/arm/rt_raw"] == 3500
    assert totals["messages"]["/arm/joint_states"] == 350 and totals["covered_s"] == pytest.approx(3.496)
    assert totals["bytes"] == sum(s["bytes"] for s in segments) > 3500 * raw_dtype(6).itemsize
    if storage == "mcap":
        assert arm["deletions"] == {"count": 1, "reasons": [{"reason": "older than the retention window "
                                                                       "(3605 s > 3600 s)", "count": 1}]}


def test_info_text_of_a_robot_directory(bag_dir: Path, capsys: pytest.CaptureFixture[str]):
    assert run(["bag", "info", str(bag_dir / "arm")]) == 0
    out = capsys.readouterr().out
    rows = {name: line for line in out.splitlines() for name in SEGMENTS if name in line and "│" in line}
    assert [("kept for a fault" in rows[name]) for name in SEGMENTS] == [True, True, False, False]
    assert "joint_states 100, robot_description 1, rt_events 2, rt_monitor_stats 10, rt_raw 1000" in rows[SEGMENTS[1]]
    assert "rt_raw: 3500 samples, 5 cycles missing in 1 gap, 1 new driver run" in out
    assert f"  {SEGMENTS[1]} at 0.500 s: 5 cycles missing after cycle 1499" in out
    assert "2 messages not recorded; ring records lost: rt_raw 4, events 0, stats 0" in out
    assert (f"2027-01-15T08:00:01.700Z cycle 1705: joint2 drive fault 0x7121 — segment {SEGMENTS[1]} at 0.700 s"
            in out)
    assert "deletions: 1 — 1 × older than the retention window (3605 s > 3600 s)" in out
    assert "total: 4 segments (4 complete), 3.496 s covered" in out


def test_info_of_one_segment_shows_that_segment_and_its_fault(bag_dir: Path, capsys: pytest.CaptureFixture[str]):
    (arm,) = info_json(bag_dir / "arm" / SEGMENTS[1], capsys)["robots"]
    assert [s["name"] for s in arm["segments"]] == [SEGMENTS[1]]
    assert arm["drops"]["rt_raw"]["samples"] == 1000 and arm["drops"]["rt_raw"]["missing_cycles"] == 5
    assert len(arm["faults"]) == 1 and arm["deletions"]["count"] == 0
    (arm,) = info_json(bag_dir / "arm" / SEGMENTS[2], capsys)["robots"]
    assert arm["faults"] == [] and arm["drops"]["rt_raw"]["gaps"] == 0


def test_cycles_are_not_compared_across_a_deleted_segment(tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    robot = tmp_path / "arm"
    record(robot, samples=2500)
    shutil.rmtree(robot / SEGMENTS[1])                   # cycles 1000..2004 gone with it
    assert info_json(tmp_path, capsys)["robots"][0]["drops"]["rt_raw"]["missing_cycles"] == 1005
    Archive(robot, "arm").log("deleted", "gone", segment=SEGMENTS[1], reason="disk 80.5 % full")
    raw = info_json(tmp_path, capsys)["robots"][0]["drops"]["rt_raw"]
    assert raw["missing_cycles"] == 0 and raw["not_compared_across"] == [f"{SEGMENTS[1]} (deleted)"]


def open_segment(directory: Path, cycles: int) -> SegmentWriter:
    """A segment a live writer holds open, with `cycles` rt_raw messages flushed into it."""
    encoder, values = RawEncoder(6), np.zeros(raw_record_length(6))
    writer = SegmentWriter(directory, [("/arm/rt_raw", MONITOR_TOPICS["rt_raw"])], STORE)
    for cycle in range(cycles):
        values[0] = cycle
        writer.append("/arm/rt_raw", START + 20 * S + cycle * 1_000_000, encoder.encode(values, START))
    writer.flush()
    return writer


def test_info_tells_killed_segments_from_the_one_being_recorded(tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    """A recorder of the same robot id runs (its status file is there): only the segment a writer holds open is
    'being recorded'; the segments of killed recorders, older or newer, are unfinished and repairable."""
    robot_id = f"arm{uuid.uuid4().hex[:8]}"
    robot = tmp_path / robot_id
    record(robot, samples=1600)
    killed = f"{robot_id}_2027_01_15-08_00_00_1"          # sorts between the two complete segments
    killed_segment(robot / killed, 300)
    (arm,) = info_json(tmp_path, capsys)["robots"]
    assert arm["segments"][1]["note"] == "unfinished (recorder killed) — run `plem bag repair`"
    assert run(["bag", "info", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "rt_raw: 1600 samples, 5 cycles missing in 1 gap" in out
    assert f"cycles not compared across: {killed} (killed)" in out
    newest_killed = f"{robot_id}_2027_01_15-08_00_30"
    killed_segment(robot / newest_killed, 300)
    writing = f"{robot_id}_2027_01_15-08_00_20"
    writer = open_segment(robot / writing, 200)
    write_status(robot_id, [QueueCount("bag", 0, 0, 0, 0)])   # a recorder of this robot runs: this process
    try:
        (arm,) = info_json(tmp_path, capsys)["robots"]
        states = {s["name"]: (s["state"], s["note"]) for s in arm["segments"]}
        assert states[writing] == ("recording", "being recorded (so far)")
        for name in (killed, newest_killed):
            assert states[name] == ("killed", "unfinished (recorder killed) — run `plem bag repair`")
        assert run(["bag", "repair", str(tmp_path)]) == 0
        out = capsys.readouterr().out
        assert f"{writing}: left alone, a recorder is writing it" in out
        assert f"{killed}: repaired, 300 messages recovered" in out and f"{newest_killed}: repaired" in out
    finally:
        remove_status(robot_id)
        writer.close()
    (arm,) = info_json(tmp_path, capsys)["robots"]
    assert all(segment["state"] == "complete" for segment in arm["segments"])
    with Reader(robot / writing) as reader:
        assert reader.message_count == 200


def plem(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    """`plem ARGS` in this process: exit code, stdout, stderr."""
    code = run(list(args))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_a_truncated_segment_says_how_much_reads_and_repair_rebuilds_it(tmp_path: Path,
                                                                        capsys: pytest.CaptureFixture[str]):
    robot = tmp_path / "arm"
    record(robot, samples=1200, flush_period_s=0.0)         # a chunk per message: a cut keeps the ones before it
    mcap = robot / SEGMENTS[0] / f"{SEGMENTS[0]}.mcap"
    mcap.write_bytes(mcap.read_bytes()[:mcap.stat().st_size // 2])
    code, out, err = plem(capsys, "bag", "info", str(tmp_path))
    assert_plem_error(code, err, f"segment {SEGMENTS[0]} is damaged")
    match = re.search(r"ends before its summary \(truncated\); (\d+) of 1\d{3} messages can be read", err)
    assert match and 100 < int(match[1]) < 1000, err
    assert f"HOW: run `plem bag repair {robot / SEGMENTS[0]}`" in err
    assert SEGMENTS[0] in out and SEGMENTS[1] in out, "the other segment is still reported"
    code, out, err = plem(capsys, "bag", "repair", str(robot))
    assert code == 0, err
    assert f"{SEGMENTS[0]}: repaired, {match[1]} messages recovered" in out
    with Reader(robot / SEGMENTS[0]) as reader:
        assert reader.message_count == int(match[1])
    assert plem(capsys, "bag", "info", str(tmp_path))[0] == 0


ALIAS_BOMB = "a: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(            # 10**9 values once expanded
    f"{name}: &{name} [{', '.join([f'*{previous}'] * 10)}]\n"
    for previous, name in zip("abcdefgh", "bcdefghi", strict=True))


def test_info_reports_each_unreadable_file_and_still_the_rest(tmp_path: Path):  # a real process: no traceback
    """Random bytes named .mcap, a metadata.yaml nested too deep or an alias bomb, a non-UTF-8 event log: one
    WHAT/WHY/HOW each, the readable segments and robots still reported, never an internal error."""
    robot = tmp_path / "arm"
    record(robot, samples=3500)
    (robot / SEGMENTS[0] / f"{SEGMENTS[0]}.mcap").write_bytes(random.Random(0).randbytes(50_000))
    (robot / SEGMENTS[1] / "metadata.yaml").write_text("a: " + "[" * 5000 + "]" * 5000)
    (robot / SEGMENTS[2] / "metadata.yaml").write_text(ALIAS_BOMB)
    other = tmp_path / "other"
    record(other, samples=500)
    (other / "event_log.jsonl").write_bytes(b'{"kind": "deleted"}\n\xff\xfe not utf-8\n')
    result = run_plem("bag", "info", str(tmp_path))
    assert_plem_error(result.returncode, result.stderr, f"4 problems in the bags under {tmp_path}")
    assert "Internal error" not in result.stderr
    assert f"ERROR: segment {SEGMENTS[0]} cannot be read" in result.stderr and "not an MCAP file" in result.stderr
    assert f"ERROR: segment {SEGMENTS[1]} cannot be read" in result.stderr and "64 deep" in result.stderr
    assert f"ERROR: segment {SEGMENTS[2]} cannot be read" in result.stderr and "alias" in result.stderr
    assert "ERROR: Not UTF-8" in result.stderr and "event_log.jsonl" in result.stderr
    assert result.stderr.count("\nHOW: ") == 4
    assert "arm_2027_01_15-08_00_03" in result.stdout and "rt_raw 500" in result.stdout
    assert "total: 5 segments (2 complete)" in result.stdout


# -- plot ----------------------------------------------------------------------------------------------------
def test_plot_writes_a_png_of_the_expected_size(bag_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    import matplotlib.image

    out = tmp_path / "plots" / "arm.png"
    out.parent.mkdir()
    assert run(["bag", "plot", str(bag_dir), "--out", str(out)]) == 0
    assert f"wrote {out}" in capsys.readouterr().out
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    width, height = plot.SIZE
    assert matplotlib.image.imread(out).shape[:2] == (height * plot.DPI, width * plot.DPI)
    assert [path.name for path in out.parent.iterdir()] == ["arm.png"], "no temporary file left"


def test_plot_of_a_bag_dir_with_several_robots_plots_the_newest_and_says_so(tmp_path: Path,
                                                                         capsys: pytest.CaptureFixture[str]):
    record(tmp_path / "arm", samples=1200)
    record(tmp_path / "arm2", samples=1200, start=START + 3600 * S)       # recorded an hour later
    out = tmp_path / "run.png"
    code, stdout, err = plem(capsys, "bag", "plot", str(tmp_path), "--out", str(out))
    assert code == 0, err
    assert (f"WARNING: {tmp_path} holds the bags of 2 robots (arm, arm2): plotting arm2, the one whose last message "
            "is the latest (2027-01-15T09:00:01.") in err
    assert "; pass --robot ID for another, or --robot all for one PNG per robot" in err
    assert f"wrote {out} (" in stdout and "): arm2 from 2027-01-15T09:00:00.000Z" in stdout
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    code, stdout, err = plem(capsys, "bag", "plot", str(tmp_path), "--out", str(out), "--robot", "all")
    assert code == 0 and "WARNING" not in err, err
    written = [tmp_path / "run-arm.png", tmp_path / "run-arm2.png"]
    assert [line.split(" (")[0] for line in stdout.splitlines()] == [f"wrote {path}" for path in written]
    assert all(path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for path in written)
    assert sorted(path.name for path in tmp_path.glob("*.png")) == ["run-arm.png", "run-arm2.png", "run.png"]


def test_the_default_robot_is_the_one_whose_last_message_is_latest(tmp_path: Path):
    """arm's newest segment starts after arm2's only one, but arm2 recorded on for longer: arm2 is picked, and the
    warning says why (its segment names alone would pick arm)."""
    record(tmp_path / "arm", samples=3000, start=START + 30 * S)            # segments from 30 s; the last ends at 33 s
    recorder = Recorder(RecordingSettings(tmp_path / "arm2", segment_s=60.0), "arm2", MONITOR_TOPICS, STORE,
                        clock=lambda: START)
    stamps = START + np.arange(40_000, dtype=np.int64) * 1_000_000       # one segment from 0 s to 40 s
    recorder.record([Messages("rt_raw", stamps, raw_payloads(np.zeros((40_000, raw_record_length(6))), stamps, 6))])
    recorder.close()
    chosen, warnings = pick_robot(find_bags(tmp_path), None, tmp_path, "plotting")
    assert chosen.robot_id == "arm2"
    assert warnings == [f"{tmp_path} holds the bags of 2 robots (arm, arm2): plotting arm2, the one whose last message "
                        f"is the latest ({iso_time(int(stamps[-1]))}); pass --robot ID for another"]


def test_plot_writes_only_a_regular_file_in_an_existing_directory(bag_dir: Path, tmp_path: Path,
                                                                  capsys: pytest.CaptureFixture[str]):
    (tmp_path / "folder.png").mkdir()
    (tmp_path / "link.png").symlink_to(tmp_path / "target.png")
    cases = {"/dev/full": ("/dev/full is not a regular file", "WHY: /dev/full is a character device"),
             str(tmp_path / "folder.png"): (f"{tmp_path / 'folder.png'} is not a regular file", "is a directory"),
             str(tmp_path / "link.png"): (f"{tmp_path / 'link.png'} is not a regular file", "is a symbolic link"),
             "/nonexistent/x.png": ("cannot write /nonexistent/x.png: /nonexistent is not a directory",
                                    "HOW: create it first (mkdir -p /nonexistent)")}
    for out, (summary, detail) in cases.items():
        code, _, err = plem(capsys, "bag", "plot", str(bag_dir), "--out", out)
        assert_plem_error(code, err, summary)
        assert detail in err
    assert not Path("/nonexistent").exists() and Path("/dev/full").is_char_device()
    assert not (tmp_path / "target.png").exists() and (tmp_path / "folder.png").is_dir()


def read_back(robot: Path, topic: str) -> list[tuple[int, Any]]:
    """(log time, message) of `topic` over a robot's segments, read with rosbags."""
    found = []
    for segment in sorted(path for path in robot.iterdir() if path.is_dir()):
        with Reader(segment) as reader:
            connections = [connection for connection in reader.connections if connection.topic == topic]
            found += [(stamp, STORE.deserialize_cdr(data, connection.msgtype))
                      for connection, stamp, data in reader.messages(connections)]
    return found


def test_every_segment_starts_with_the_urdf_as_robot_description(bag_dir: Path):
    for name in SEGMENTS:
        with Reader(bag_dir / "arm" / name) as reader:
            [connection] = [c for c in reader.connections if c.topic == "/arm/robot_description"]
            [(_, stamp, data)] = list(reader.messages([connection]))
            assert connection.msgtype == "std_msgs/msg/String" and stamp == reader.start_time
            assert STORE.deserialize_cdr(data, connection.msgtype).data == URDF


def test_timeline_decimates_samples_keeps_every_latency_and_marks_events(bag_dir: Path):
    (robot,) = find_bags(bag_dir)
    line = read_timeline(robot, max_points=1000)
    assert (line.robot_id, line.joint_names, line.description) == ("arm", JOINTS, URDF)
    np.testing.assert_array_equal(line.all_latency_us, [(20_000 + i % 100 * 10) / 1e3 for i in range(3500)])
    samples = np.arange(0, 3500, 4)                      # every 4th of 3500 samples
    np.testing.assert_array_equal(line.time_ns, START + samples * MS)
    np.testing.assert_allclose(line.position, np.arange(6) + samples[:, None] / 1000)
    np.testing.assert_allclose(line.command_position, line.position + 0.01)
    np.testing.assert_array_equal(line.velocity, np.broadcast_to(-np.arange(6.0), (875, 6)))
    np.testing.assert_array_equal(line.mode, [mode_of(index) for index in samples])
    np.testing.assert_array_equal(line.latency_us, line.all_latency_us[samples])
    events = read_back(bag_dir / "arm", "/arm/rt_events")
    assert [(marker.time_ns, marker.cycle) for marker in line.markers] == [(t, event.cycle) for t, event in events]
    assert [(marker.kind, marker.label) for marker in line.markers] == [
        ("mode", "hold → trajectory"), ("fault", "fault: joint2 drive fault 0x7121"),
        ("fault_cleared", "fault cleared: joint2 drive fault 0x7121"), ("mode", "fault → hold")]
    assert line.faults() == [line.markers[1]] and line.faults()[0].time_ns == START + 1700 * MS


def test_timeline_between_two_times_holds_only_them(bag_dir: Path):
    (robot,) = find_bags(bag_dir)
    line = read_timeline(robot, START + 1200 * MS, START + 2200 * MS)
    np.testing.assert_array_equal(line.time_ns, START + np.arange(1200, 2201) * MS)
    assert len(line.all_latency_us) == 1001 and [marker.kind for marker in line.markers] == ["fault"]
    coarse = read_timeline(robot, START + 1200 * MS, START + 2200 * MS, max_points=100)
    assert len(coarse.time_ns) <= 100 and np.all(np.diff(coarse.time_ns) == 11 * MS), "evenly spaced"
    assert len(coarse.all_latency_us) == 1001
    with pytest.raises(BagError) as raised:
        read_timeline(robot, START + 10 * S)
    assert raised.value.summary == "no rt_raw samples from 2027-01-15T08:00:10.000Z"
    assert raised.value.why == "the recording covers 2027-01-15T08:00:00.000Z to 2027-01-15T08:00:03.499Z"


def test_plot_marks_faults_and_modes_and_draws_commanded_against_measured(bag_dir: Path):
    from matplotlib.dates import ConciseDateFormatter, date2num, num2date
    from matplotlib.legend import Legend

    def x_of(ns: int) -> float:
        return float(date2num(np.datetime64(ns, "ns")))

    (robot,) = find_bags(bag_dir)
    figure = plot.figure(read_timeline(robot), "arm")
    position = figure.axes[0]

    def with_gid(gid: str) -> list[Any]:
        return figure.findobj(lambda artist: artist.get_gid() == gid)

    faults = with_gid("fault")
    assert len(faults) == 3, "one line on each axes over time"
    assert all(line.get_xdata()[0] == pytest.approx(x_of(START + 1700 * MS), abs=1e-10) for line in faults)
    [label] = with_gid("fault_label")
    assert "fault: joint2 drive fault 0x7121" in label.get_text()
    modes = {artist.get_gid() for artist in figure.findobj() if str(artist.get_gid()).startswith("mode:")}
    assert modes == {"mode:hold", "mode:trajectory", "mode:fault"}
    [fault_band, *_] = with_gid("mode:fault")
    [band] = fault_band.get_paths()
    assert band.vertices[:, 0].min() == pytest.approx(x_of(START + 1700 * MS), abs=1e-10)
    assert band.vertices[:, 0].max() == pytest.approx(x_of(START + 2500 * MS), abs=1e-10)
    assert len(with_gid("mode:hold")[0].get_paths()) == 2, "hold before the trajectory and after the fault"
    for joint in JOINTS:
        [measured], [commanded] = with_gid(f"measured:{joint}"), with_gid(f"commanded:{joint}")
        assert measured.axes is commanded.axes is position and measured.get_color() == commanded.get_color()
        assert (measured.get_linestyle(), commanded.get_linestyle()) == ("-", "--")
        np.testing.assert_allclose(commanded.get_ydata(), measured.get_ydata() + 0.01)
    figure.canvas.draw()
    renderer = figure.canvas.get_renderer()
    for axes in (figure.axes[0], *figure.axes[2:]):
        legend, box = axes.get_legend(), axes.get_window_extent(renderer)
        assert legend is not None and legend.get_window_extent(renderer).x0 > box.x1, "legends right of the data"
        assert not legend.get_window_extent(renderer).overlaps(box)
    # the modes hold for every panel over time: one legend above them all, under the title
    [modes_legend] = [artist for artist in position.artists if isinstance(artist, Legend)]
    assert [t.get_text() for t in modes_legend.get_texts()] == ["hold", "trajectory", "fault", "fault event"]
    assert "position, velocity and latency panels" in modes_legend.get_title().get_text()
    above = modes_legend.get_window_extent(renderer)
    assert all(above.y0 >= axes.get_window_extent(renderer).y1 for axes in figure.axes), "above every panel"
    [title] = figure.texts
    assert above.y1 <= title.get_window_extent(renderer).y0, "under the title"
    assert figure.axes[1].get_legend() is None, "no legend of its own by the velocity panel"
    assert isinstance(position.xaxis.get_major_formatter(), ConciseDateFormatter)
    first, last = (num2date(x) for x in position.get_xlim())
    assert first <= datetime(2027, 1, 15, 8, 0, tzinfo=UTC) < datetime(2027, 1, 15, 8, 0, 3, 499000, tzinfo=UTC) <= last
    assert (last - first).total_seconds() < 4, "absolute UTC time, zoomed on the recording"


def test_plot_from_to_narrows_the_range_and_refuses_bad_values(bag_dir: Path, tmp_path: Path,
                                                               capsys: pytest.CaptureFixture[str]):
    out = str(tmp_path / "zoom.png")
    code, stdout, err = plem(capsys, "bag", "plot", str(bag_dir), "--out", out, "--from", "08:00:01.2", "--to", "+2.2")
    assert code == 0, err
    assert "arm from 2027-01-15T08:00:01.200Z to 2027-01-15T08:00:02.200Z" in stdout
    code, stdout, err = plem(capsys, "bag", "plot", str(bag_dir), "--out", out, "--from", "2027-01-15T09:00:03+01:00")
    assert code == 0, err
    assert "arm from 2027-01-15T08:00:03.000Z to 2027-01-15T08:00:03.499Z" in stdout
    for flag, bad in (("--from", "yesterday"), ("--to", "+soon"), ("--from", "+-1"), ("--to", "25:61")):
        code, _, err = plem(capsys, "bag", "plot", str(bag_dir), "--out", out, flag, bad)
        assert code == 2 and f"ERROR: {flag} '{bad}' is not a time" in err and "Traceback" not in err
        assert f"WHAT: {flag} as an ISO date and time (2026-11-24T18:30:05" in err
        assert "a clock time on the recording's day (18:30:05" in err and "start (+12.5)" in err
    code, _, err = plem(capsys, "bag", "plot", str(bag_dir), "--out", out, "--from", "+3", "--to", "+1")
    assert code == 2 and "ERROR: --from +3 comes after --to +1" in err
    code, _, err = plem(capsys, "bag", "plot", str(bag_dir), "--out", out, "--from", "09:00:00")
    assert_plem_error(code, err, "no rt_raw samples from 2027-01-15T09:00:00.000Z")
    assert "WHY: the recording covers 2027-01-15T08:00:00.000Z to 2027-01-15T08:00:03.499Z" in err
    assert "HOW: pass --from/--to within it" in err


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_a_segment_being_recorded_shows_what_it_holds_so_far(tmp_path: Path, storage: str,
                                                            capsys: pytest.CaptureFixture[str]):
    """The recorder has written 1.8 s and still holds its second segment open: info counts what that holds so far,
    plot reads it as far as written and says so; once closed it is complete with the same messages."""
    robot, now = tmp_path / "arm", [START]
    recorder = recorder_of(robot, now, storage)
    try:
        feed_samples(recorder, now, range(1800))
        recorder.segment.flush()                             # as the recorder does every second
        segments = info_json(tmp_path, capsys)["robots"][0]["segments"]
        assert [(s["name"], s["state"]) for s in segments] == [(SEGMENTS[0], "complete"), (SEGMENTS[1], "recording")]
        live = segments[1]
        assert live["note"] == "being recorded (so far)" and live["start"] == "2027-01-15T08:00:01.000Z"
        assert live["duration_s"] == pytest.approx(0.799)
        assert live["messages"] == {"/arm/rt_raw": 800, "/arm/rt_events": 2, "/arm/joint_states": 80,
                                    "/arm/rt_monitor_stats": 8, "/arm/robot_description": 1}
        result = run_plem("bag", "info", str(tmp_path))       # another process, as a user would run it
        assert result.returncode == 0, result.stderr
        [row] = [line for line in result.stdout.splitlines() if SEGMENTS[1] in line and "│" in line]
        assert "being recorded (so far)" in row and "rt_raw 800" in result.stdout
        assert "rt_raw: 1800 samples" in result.stdout
        assert "total: 2 segments (1 complete), 1.798 s covered" in result.stdout
        code, stdout, err = plem(capsys, "bag", "plot", str(tmp_path), "--out", str(tmp_path / "live.png"))
        assert code == 0 and f"WARNING: {SEGMENTS[1]} is being recorded: read as far as written so far" in err
        assert "arm from 2027-01-15T08:00:00.000Z to 2027-01-15T08:00:01.799Z" in stdout
        assert len(read_timeline(find_bags(tmp_path)[0]).all_latency_us) == 1800
    finally:
        recorder.close()
    segments = info_json(tmp_path, capsys)["robots"][0]["segments"]
    assert segments[1]["state"] == "complete" and segments[1]["messages"]["/arm/rt_raw"] == 800


def test_plot_errors(bag_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    two = tmp_path / "two"
    shutil.copytree(bag_dir / "arm", two / "arm")
    record(two / "other", samples=300, raw=False)
    out = str(tmp_path / "x.png")
    code = run(["bag", "plot", str(two), "--out", out, "--robot", "nobody"])
    assert_plem_error(code, capsys.readouterr().err, f"no bags of robot nobody in {two}")
    code = run(["bag", "plot", str(two), "--out", out, "--robot", "other"])
    assert_plem_error(code, capsys.readouterr().err, "no rt_raw samples in the bags")
    (tmp_path / "file").write_text("")
    code = run(["bag", "plot", str(bag_dir), "--out", str(tmp_path / "file" / "x.png")])
    assert_plem_error(code, capsys.readouterr().err, f"cannot write {tmp_path / 'file' / 'x.png'}")
    assert not Path(out).exists()


# -- repair --------------------------------------------------------------------------------------------------
def test_repair_rebuilds_a_killed_segment_and_leaves_complete_ones(tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    robot = tmp_path / "arm"
    record(robot, samples=1500)
    killed = robot / "arm_2027_01_15-08_00_10"
    killed_segment(killed, 300)
    assert not (killed / "metadata.yaml").exists()
    assert run(["bag", "repair", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert f"{SEGMENTS[0]}: already complete" in out and f"{SEGMENTS[1]}: already complete" in out
    assert f"{killed.name}: repaired, 300 messages recovered" in out
    with Reader(killed) as reader:
        cycles = [STORE.deserialize_cdr(data, MONITOR_TOPICS["rt_raw"]).cycle for _, _, data in reader.messages()]
    assert cycles == list(range(300))
    segments = info_json(tmp_path, capsys)["robots"][0]["segments"]
    assert segments[-1]["state"] == "complete" and segments[-1]["messages"] == {"/arm/rt_raw": 300}
    assert run(["bag", "repair", str(killed)]) == 0
    assert capsys.readouterr().out == f"{killed.name}: already complete\n"


def test_repair_that_fails_exits_non_zero_with_what_why_how(tmp_path: Path):
    robot = tmp_path / "arm"
    record(robot, samples=500)
    broken = robot / "arm_2027_01_15-08_00_10"
    broken.mkdir()
    (broken / f"{broken.name}.mcap").write_bytes(b"not an mcap file")
    result = run_plem("bag", "repair", str(tmp_path))
    assert f"{SEGMENTS[0]}: already complete" in result.stdout
    assert f"{broken.name}: not repaired: " in result.stdout
    assert_plem_error(result.returncode, result.stderr, "1 segment could not be repaired")
    assert f"{broken.name}: its first bytes differ" in result.stderr


# -- errors --------------------------------------------------------------------------------------------------
def test_directories_without_bags_are_what_why_how_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    result = run_plem("bag", "info", str(tmp_path / "missing"))
    assert_plem_error(result.returncode, result.stderr, f"{tmp_path / 'missing'} is not a bag directory")
    assert "WHY: it does not exist" in result.stderr
    (tmp_path / "empty" / "arm").mkdir(parents=True)
    for command in (["info"], ["repair"], ["plot", "--out", str(tmp_path / "x.png")]):
        code = run(["bag", *command, str(tmp_path / "empty")])
        assert_plem_error(code, capsys.readouterr().err, f"no bags in {tmp_path / 'empty'}")


# -- the RtRaw field reader ----------------------------------------------------------------------------------
@pytest.mark.parametrize("dof", [6, 7])
def test_raw_field_matches_rosbags_deserialization(dof: int):
    rng = np.random.default_rng(dof)
    encoder = RawEncoder(dof)
    payloads, starts, buffer = [], [], bytearray()
    for cycle in range(50):
        values = rng.normal(size=raw_record_length(dof))
        values[:7] = [cycle * 7 + 3, rng.integers(1 << 40), cycle % 5, cycle % 2, 1, rng.integers(1 << 20),
                      rng.integers(1 << 20)]
        payloads.append(encoder.encode(values, int(rng.integers(1 << 60))))
        buffer += bytes(int(rng.integers(0, 9)))         # payloads at irregular offsets, as in a chunk
        starts.append(len(buffer))
        buffer += payloads[-1]
    data, starts_array = np.frombuffer(bytes(buffer), np.uint8), np.array(starts)
    assert raw_dof(payloads[0]) == dof and raw_dtype(dof).itemsize == len(payloads[0])
    messages = [STORE.deserialize_cdr(payload, MONITOR_TOPICS["rt_raw"]) for payload in payloads]
    for name in ("cycle", "monotonic_ns", "mode", "faulted", "drives_enabled", "latency_ns", "compute_ns"):
        np.testing.assert_array_equal(raw_field(data, starts_array, name), [getattr(m, name) for m in messages])
    for name in ("sec", "nanosec"):
        np.testing.assert_array_equal(raw_field(data, starts_array, name), [getattr(m.header.stamp, name)
                                                                             for m in messages])
    for name in ("position", "velocity", "effort", "command_position", "command_velocity", "command_acceleration"):
        np.testing.assert_array_equal(raw_field(data, starts_array, name, dof), [getattr(m, name) for m in messages])
    np.testing.assert_array_equal(raw_field(data, starts_array, "speed_override", dof),
                                  [m.speed_override for m in messages])


def test_plot_keeps_joints_on_one_path_apart_and_fault_labels_inside_their_panel():
    """Two joints moving identically: each measured line has its own marker at its own offset, so both show; a
    fault label longer than the panel is clipped to it."""
    count = 400
    stamps = START + np.arange(count, dtype=np.int64) * MS
    same = np.linspace(0.0, 1.0, count)
    positions = np.column_stack([same, same, -same])
    fault = Marker(int(stamps[200]), "fault", "fault: " + "a very long reason " * 10, 200)
    line = Timeline("arm", ["joint_1", "joint_2", "joint_3"], stamps, positions, positions, np.zeros_like(positions),
                    np.full(count, int(Mode.HOLD)), np.full(count, 50.0), np.full(count, 50.0), [fault], None)
    figure = plot.figure(line, "arm")
    lines = {artist.get_gid(): artist for axes in figure.axes for artist in axes.get_lines()}
    first, second = lines["measured:joint_1"], lines["measured:joint_2"]
    assert first.get_marker() != second.get_marker() and "None" not in (first.get_marker(), second.get_marker())
    assert first.get_markevery()[0] != second.get_markevery()[0], "markers at different samples"
    [label] = [text for axes in figure.axes for text in axes.texts if text.get_gid() == "fault_label"]
    assert label.get_clip_on() and label.get_clip_box() is not None
    assert label.get_clip_box().bounds == label.axes.bbox.bounds, "clipped to its own panel"


def test_bags_recorded_before_rtraw_had_a_speed_override_still_read(tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    """An rt_raw recorded with RtRaw as it was (its definition without speed_override, in the bag): info and plot
    read it as they read today's."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    text = (Path(__file__).parents[2] / "src/plem/middleware/interfaces/plem_msgs/msg/RtRaw.msg").read_text()
    old_text = text[:text.index("# The speed override")]
    store = get_typestore(Stores.ROS2_JAZZY)
    store.register(get_types_from_msg(old_text, MONITOR_TOPICS["rt_raw"]))
    robot = tmp_path / "arm"
    robot.mkdir()
    writer = SegmentWriter(robot / "arm_2027_01_15-08_00_00", [("/arm/rt_raw", MONITOR_TOPICS["rt_raw"])], store)
    encoder, values = RawEncoder(6), np.zeros(raw_record_length(6))
    old_size = raw_sizes(6)[1]
    for cycle in range(2000):
        values[0], values[7:13] = cycle, np.arange(6) + cycle / 1000
        payload = encoder.encode(values, START + cycle * 1_000_000)[:old_size]
        assert store.deserialize_cdr(payload, MONITOR_TOPICS["rt_raw"]).cycle == cycle
        writer.append("/arm/rt_raw", START + cycle * 1_000_000, payload)
    writer.close()
    assert run(["bag", "info", str(tmp_path)]) == 0
    assert "rt_raw: 2000 samples" in capsys.readouterr().out
    out = tmp_path / "arm.png"
    assert run(["bag", "plot", str(tmp_path), "--out", str(out)]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
