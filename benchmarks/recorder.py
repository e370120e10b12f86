"""The recorder at 1 kHz: its CPU, its bytes per minute, what it drops, and its effect on the loop.

Usage: python benchmarks/recorder.py [--seconds 60] [--window 20] [--pairs 4] [--segment 20] [--storage mcap]
                                     [--quick]
Needs root for SCHED_FIFO (as `plem launch` on a real machine). --quick: a 10 s recording window with 4 s
segments and one pair of 3 s loop windows (a smoke run). The full run takes about 6 minutes (--seconds, then
2 x --pairs x --window plus about 10 s per recorder stop, two launches).

What runs:
  robot       `plem launch bus:=mock robot_id:=bench_rec_<hex> bridge:=false record:=true|false` (Indy7 v2,
              MockBus with dynamics, 1 kHz, SCHED_FIFO 98) in a subprocess, in hold mode; with record:=true also
              bag_dir:=<temp dir> bag_segment_seconds:=--segment bag_storage:=--storage. Every launch has a robot
              id of its own, is stopped with SIGINT after its phase (the benchmark's children are all stopped on
              any exit), and the temp directory with the bags is removed at the end. bridge:=false everywhere:
              no DDS, so the recorder is the only component besides the driver.
  recording   one launch with record:=true; after 1 s of samples (0.5 s with --quick), a window of --seconds:
                CPU        utime + stime of the recorder process (its pid from the launch summary line
                           `recorder      recording, pid N, into DIR (...)`) from /proc/<pid>/stat, over
                           SC_CLK_TCK and the window's length: % of one core. Target: <= 10 %. Baseline, in the
                           same window: a plem.bridge client in another process iterating client.stream() (reads
                           every rt_raw record from shared memory, as the recorder does, and writes nothing).
                cycles     the driver's cycle number (client.state()) at the window's start (c0) and end (c1);
                           the window ran c1 - c0 cycles.
                bytes      growth of bag_dir/<robot_id>/ (sum of file sizes) over the window, per minute. The
                           open MCAP segment reaches the disk every second, so the growth lags by up to 1 s of
                           data. Baseline: the rt_raw ring records of the window's cycles,
                           raw_record_length(dof) float64 values of 8 bytes each; ratio bag / records.
              After the launch stopped (the recorder closed its last segment), every segment is read back with
              rosbags and each rt_raw message decoded: recorded = distinct cycles in (c0, c1]; dropped =
              (c1 - c0) - recorded (target 0); the cycle numbers of the whole recording are checked for gaps
              and repeats. Messages per topic are counted between the stamps of rt_raw cycles c0 + 1 and c1.
              The recorder's own counters (/dev/shm/plem_recorder_<id>.json: rt_raw ring reads lost, messages
              not recorded) are read at the window's start and end.
  loop        one launch with record:=false (and bridge:=false), in hold mode; --pairs pairs of --window windows
              alternate: a recorder recording it / none (the order alternates between pairs: on/off, off/on, ...).
              The recorder is the launch's own component started as `plem launch` starts it (`python -m
              plem.launch.recorder '<launch arguments>'`, same bag_dir, segments and storage) before its window
              and stopped with SIGINT after it (it records on for its drain time and exits; then os.sync() puts
              what it wrote on disk, so no write-back of it falls into the next window). One launch for every
              window: launches differ from each other more than recording changes one. The loop's wake-up
              latency of every cycle of the window is read from the rt_raw ring (this process drains it every
              0.5 s); p50/p99/p99.9/max per window and the ratio p99.9 (and p50) on over off, median over the
              pairs, and p99.9 of all windows of each kind pooled. Target: p99.9 <= 1.1x.
              The recorder's CPU in each window with it and the 1-minute load average at each window's end are
              listed.
"""

from __future__ import annotations

import argparse
import os
import secrets
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import Reader

from plem.bridge import connect
from plem.bridge.client import RobotClient
from plem.ipc.records import raw_record_length
from plem.launch.recorder import DRAIN_TIMEOUT_S
from plem.middleware.types import library
from plem.recording.archive import directory_size
from plem.recording.status import read_status

from launching import (
    SHM_CLIENT,
    CpuMeter,
    Launch,
    begin_run,
    drain_loop,
    finish,
    first_sample,
    latency_figures,
    launch,
    ratio,
    result,
    start_component,
    start_reader,
    stop,
    stop_all,
    verdict,
)

TOPICS = ("rt_raw", "joint_states", "rt_monitor_stats", "rt_events")
CPU_TARGET = 10.0
LOOP_TARGET = 1.1


def new_robot_id() -> str:
    return f"bench_rec_{secrets.token_hex(4)}"


# -- the recording window ------------------------------------------------------------------------------
@dataclass
class RecordingWindow:
    seconds: float
    first_cycle: int                       # c0: the window holds cycles c0 + 1 .. c1
    last_cycle: int
    bag_growth: int                        # bytes
    cpu: dict[str, float]                  # % of one core: recorder, client
    latency_us: np.ndarray
    ring_dropped: int                      # this process's rt_raw reader
    counters: dict[str, tuple[int, int]]   # recorder queue → (written, dropped) over the window

    @property
    def cycles(self) -> int:
        return self.last_cycle - self.first_cycle


def recorder_counters(robot_id: str) -> dict[str, tuple[int, int]]:
    return {queue.name: (queue.written, queue.dropped) for queue in read_status(robot_id)}


def recording_window(client: RobotClient, robot: Launch, reader: subprocess.Popen, seconds: float) -> RecordingWindow:
    """Recorder and shared-memory client CPU, cycles and bag growth over `seconds`."""
    assert robot.recorder_pid is not None and robot.bag_directory is not None
    counters = recorder_counters(client.robot_id)
    meter = CpuMeter({"recorder": robot.recorder_pid, "client": reader.pid})
    start = time.monotonic()
    size = directory_size(robot.bag_directory)
    first = client.state().cycle
    latency, ring_dropped = drain_loop(client, seconds)
    last = client.state().cycle
    growth = directory_size(robot.bag_directory) - size
    elapsed = time.monotonic() - start
    cpu = meter.done()
    after = recorder_counters(client.robot_id)
    deltas = {name: (written - counters.get(name, (0, 0))[0], dropped - counters.get(name, (0, 0))[1])
              for name, (written, dropped) in after.items()}
    return RecordingWindow(elapsed, first, last, growth, cpu, latency, ring_dropped, deltas)


# -- the bags, read back -------------------------------------------------------------------------------
@dataclass
class Bags:
    segments: int = 0
    closed: int = 0                        # with metadata.yaml
    size: int = 0                          # bytes, every file of the robot's bag directory
    cycles: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))   # rt_raw, in bag order
    raw_stamps: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    stamps: dict[str, np.ndarray] = field(default_factory=dict)                       # topic → stamps (ns)

    def gaps(self) -> tuple[int, int, int]:
        """Over the whole recording: (places where the next cycle is not the previous + 1, cycles missing,
        repeated or out-of-order messages)."""
        steps = np.diff(self.cycles)
        missing = int(np.sum(steps[steps > 1] - 1))
        return int(np.count_nonzero(steps != 1)), missing, int(np.count_nonzero(steps < 1))


def read_bags(directory: Path, robot_id: str) -> Bags:
    """Every segment under `directory`, in name (time) order: rt_raw cycle numbers and every topic's stamps."""
    store = library().store
    bags = Bags(size=directory_size(directory))
    cycles: list[int] = []
    raw_stamps: list[int] = []
    stamps: dict[str, list[int]] = {name: [] for name in TOPICS}
    for segment in sorted(p for p in directory.iterdir() if p.is_dir() and p.name.startswith(f"{robot_id}_")):
        bags.segments += 1
        if not (segment / "metadata.yaml").is_file():
            continue                       # not closed: the launch was killed; counted as segments - closed
        bags.closed += 1
        with Reader(segment) as reader:
            for connection, timestamp, data in reader.messages():
                name = connection.topic.rsplit("/", 1)[-1]
                stamps.setdefault(name, []).append(timestamp)
                if name == "rt_raw":
                    cycles.append(store.deserialize_cdr(data, connection.msgtype).cycle)
                    raw_stamps.append(timestamp)
    bags.cycles = np.array(cycles, dtype=np.int64)
    bags.raw_stamps = np.array(raw_stamps, dtype=np.int64)
    bags.stamps = {name: np.array(values, dtype=np.int64) for name, values in stamps.items()}
    return bags


# -- loop latency --------------------------------------------------------------------------------------
@dataclass
class LoopWindow:
    record: bool
    latency_us: np.ndarray
    ring_dropped: int
    recorder_cpu: float | None
    load: float

    def figures(self) -> tuple[float, float, float, float]:
        return latency_figures(self.latency_us)


def loop_window(client: RobotClient, record: bool, seconds: float, settle: float, arguments: dict[str, str],
                env: dict[str, str], log: Path, children: list[subprocess.Popen]) -> LoopWindow:
    """The loop latency of one window of the running launch, with a recorder of its own started for the window
    (and stopped after it: it records on until its drain time ends, `DRAIN_TIMEOUT_S`) or without one."""
    recorder = start_component("plem.launch.recorder", arguments, env, log, children) if record else None
    try:
        time.sleep(settle)
        meter = CpuMeter({"recorder": recorder.pid}) if recorder else None
        latency, dropped = drain_loop(client, seconds)
        cpu = meter.done()["recorder"] if meter else None
        return LoopWindow(record, latency, dropped, cpu, os.getloadavg()[0])
    finally:
        if recorder is not None:
            stop(recorder, signal.SIGINT, DRAIN_TIMEOUT_S + 10.0)
            children.remove(recorder)
            os.sync()                      # what it wrote reaches the disk now, not during the next window


# -- report ----------------------------------------------------------------------------------------------
def megabytes(value: float) -> str:
    return f"{value / 1e6:.2f} MB"


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0, help="the recording window (CPU, bytes, drops)")
    parser.add_argument("--window", type=float, default=20.0, help="each loop-latency window")
    parser.add_argument("--pairs", type=int, default=4, help="pairs of loop-latency windows record:=true/false")
    parser.add_argument("--segment", type=float, default=20.0, help="bag_segment_seconds of the launches")
    parser.add_argument("--storage", choices=("mcap", "sqlite3"), default="mcap", help="bag_storage")
    parser.add_argument("--quick", action="store_true", help="10 s recording, 4 s segments, one pair of 3 s windows")
    args = parser.parse_args(argv)
    settle = 1.0
    if args.quick:
        args.seconds, args.segment, args.window, args.pairs, settle = 10.0, 4.0, 3.0, 1, 0.5
    machine = begin_run()
    command = (f".venv/bin/python benchmarks/recorder.py --seconds {args.seconds:g} --window {args.window:g} "
               f"--pairs {args.pairs} --segment {args.segment:g} --storage {args.storage}")
    print(f"machine: {machine}; load average {os.getloadavg()[0]:.2f}")
    work = Path(tempfile.mkdtemp(prefix="plem-bench-rec-"))
    bag_dir, logs = work / "bags", work / "logs"
    logs.mkdir()
    bag_arguments: dict[str, object] = {"bag_dir": bag_dir, "bag_segment_seconds": f"{args.segment:g}",
                                        "bag_storage": args.storage}
    env = dict(os.environ)
    children: list[subprocess.Popen] = []
    succeeded = False
    try:
        # -- one recording launch: CPU, bytes, drops -------------------------------------------------
        robot_id = new_robot_id()
        robot = launch(robot_id, env, logs / f"{robot_id}.log", children, bridge=False, record=True,
                       **bag_arguments)
        assert robot.bag_directory is not None
        print(f"robot {robot_id}: rt_driver pid {robot.driver_pid}, recorder pid {robot.recorder_pid}, "
              f"bags in {robot.bag_directory} ({args.storage}, {args.segment:g} s segments)")
        client = connect(robot_id)
        dof = client.dof
        first_sample(client, settle)
        reader = start_reader(SHM_CLIENT, robot_id, args.seconds, settle, env, children)
        window = recording_window(client, robot, reader, args.seconds)
        shm = result(reader, 30.0)
        finish(reader)
        client.close()
        stop(robot.process)
        if robot.process.returncode not in (0, None):
            print(f"note: plem launch exited {robot.process.returncode}; log {robot.log}")
        bags = read_bags(robot.bag_directory, robot_id)

        in_window = (bags.cycles > window.first_cycle) & (bags.cycles <= window.last_cycle)
        recorded = int(np.unique(bags.cycles[in_window]).size)
        dropped = window.cycles - recorded
        start_ns = int(bags.raw_stamps[in_window].min()) if recorded else 0
        end_ns = int(bags.raw_stamps[in_window].max()) if recorded else -1
        per_topic = {name: int(np.count_nonzero((stamps >= start_ns) & (stamps <= end_ns)))
                     for name, stamps in bags.stamps.items()}
        span_s = (end_ns - start_ns) / 1e9 if recorded > 1 else 0.0
        gaps, missing, repeats = bags.gaps()
        per_minute = 60.0 / window.seconds
        bag_rate = window.bag_growth * per_minute
        record_bytes = raw_record_length(dof) * 8
        raw_rate = window.cycles * record_bytes * per_minute
        whole_rate = bags.size / bags.cycles.size * 60_000 if bags.cycles.size else 0.0
        cpu, client_cpu = window.cpu["recorder"], window.cpu["client"]

        print(f"\nrecording rt_raw (and joint_states, rt_monitor_stats, rt_events) at 1 kHz, window "
              f"{window.seconds:.1f} s, {dof} DOF; baseline: a plem.bridge client stream() over shared memory, "
              f"same window")
        print(f"  {'':<36}{'recorder':>14}{'baseline':>14}{'ratio':>9}   target")
        print(f"  {'CPU, % of one core':<36}{cpu:>14.1f}{client_cpu:>14.1f}{ratio(cpu, client_cpu):>9}"
              f"   <= {CPU_TARGET:g} %: {verdict(cpu <= CPU_TARGET)}")
        print(f"  {'bytes per minute':<36}{megabytes(bag_rate):>14}{megabytes(raw_rate):>14}"
              f"{ratio(bag_rate, raw_rate):>9}   (bag directory growth vs rt_raw records of "
              f"{record_bytes} B)")
        print(f"  {'cycles in the window':<36}{window.cycles:>14}{shm['last'] - shm['first'] + 1:>14}"
              f"   (baseline: its own window, first..last cycle read)")
        print(f"  {'rt_raw recorded (read back)':<36}{recorded:>14}{shm['unique']:>14}")
        print(f"  {'dropped':<36}{dropped:>14}{shm['last'] - shm['first'] + 1 - shm['unique']:>14}"
              f"{'':>9}   0: {verdict(dropped == 0)}")
        print(f"  messages per topic between the stamps of cycles c0+1 and c1 ({span_s:.1f} s): "
              + ", ".join(f"{name} {per_topic.get(name, 0)} ({per_topic.get(name, 0) / span_s if span_s else 0:.4g}/s)"
                          for name in TOPICS))
        print(f"  whole recording: {bags.segments} segments ({bags.closed} closed), {bags.size} bytes, "
              f"{bags.cycles.size} rt_raw messages (cycles {bags.cycles.min() if bags.cycles.size else '-'}.."
              f"{bags.cycles.max() if bags.cycles.size else '-'}): {megabytes(whole_rate)} per minute of rt_raw "
              f"(index, summaries and metadata included); {gaps} breaks in the cycle sequence "
              f"({missing} cycles missing, {repeats} repeated or out of order)")
        ring_lost = window.counters.get("recorder:rt_raw", (0, 0))[1]
        unrecorded = window.counters.get("recorder:bag", (0, 0))[1]
        written = window.counters.get("recorder:bag", (0, 0))[0]
        print(f"  recorder counters over the window: {written} messages written, {unrecorded} not recorded, "
              f"{ring_lost} rt_raw ring reads lost; this process's ring reader lost {window.ring_dropped}")
        p50, p99, p999 = np.percentile(window.latency_us, (50, 99, 99.9))
        print(f"  loop in this window (recorder and baseline client running): p50 {p50:.0f} µs, p99 {p99:.0f} µs, "
              f"p99.9 {p999:.0f} µs, max {window.latency_us.max():.0f} µs")
        if bags.segments < 3:
            print(f"  note: only {bags.segments} segments; --segment {args.segment:g} is long for the window")

        # -- loop wake-up latency, alternating launches with and without the recorder ---------------
        robot_id = new_robot_id()
        robot = launch(robot_id, env, logs / f"{robot_id}.log", children, bridge=False, record=False)
        client = connect(robot_id)
        first_sample(client, settle)
        recorder_arguments = {"bus": "mock", "robot_id": robot_id,
                              **{name: str(value) for name, value in bag_arguments.items()}}
        windows: list[tuple[int, LoopWindow]] = []
        for pair in range(1, args.pairs + 1):
            for record in ((True, False) if pair % 2 else (False, True)):
                windows.append((pair, loop_window(client, record, args.window, settle, recorder_arguments, env,
                                                  logs / f"{robot_id}_recorder.log", children)))
        client.close()
        stop(robot.process)

        print(f"\nloop wake-up latency (µs) of one launch (record:=false, bridge:=false), {args.pairs} "
              f"pair{'s' * (args.pairs != 1)} of {args.window:g} s windows with and without a recorder "
              f"(python -m plem.launch.recorder, as the launch starts it) recording it")
        print(f"  {'pair':<6}{'record':<8}{'cycles':>8}{'p50':>7}{'p99':>7}{'p99.9':>7}{'max':>7}{'ring lost':>11}"
              f"{'rec CPU %':>11}{'load':>7}")
        for pair, loop in windows:
            p50, p99, p999, top = loop.figures()
            rec_cpu = f"{loop.recorder_cpu:.1f}" if loop.recorder_cpu is not None else "-"
            print(f"  {pair:<6}{'on' if loop.record else 'off':<8}{loop.latency_us.size:>8}{p50:>7.0f}{p99:>7.0f}"
                  f"{p999:>7.0f}{top:>7.0f}{loop.ring_dropped:>11}{rec_cpu:>11}{loop.load:>7.2f}")
        p999_ratios, p50_ratios = [], []
        rows = []
        for pair in range(1, args.pairs + 1):
            by_kind = {loop.record: loop.figures() for p, loop in windows if p == pair}
            p999_ratios.append(by_kind[True][2] / by_kind[False][2])
            p50_ratios.append(by_kind[True][0] / by_kind[False][0])
            rows.append((pair, by_kind[True], by_kind[False]))
        median = statistics.median(p999_ratios)
        median_p50 = statistics.median(p50_ratios)
        pooled = {record: np.percentile(np.concatenate([loop.latency_us for _, loop in windows
                                                        if loop.record == record]), 99.9) for record in (True, False)}
        print(f"  p99.9 on / off per pair: {', '.join(f'{r:.2f}' for r in p999_ratios)}; median {median:.2f}x "
              f"(target <= {LOOP_TARGET:g}x: {verdict(median <= LOOP_TARGET)})")
        print(f"  p50 on / off per pair: {', '.join(f'{r:.2f}' for r in p50_ratios)}; median {median_p50:.2f}x")
        print(f"  p99.9 of all windows pooled: on {pooled[True]:.0f} µs, off {pooled[False]:.0f} µs, "
              f"{pooled[True] / pooled[False]:.2f}x")

        # -- the block for BENCHMARKS.md ------------------------------------------------------------
        print("\n---- results (for BENCHMARKS.md) ----")
        print(f"Command: `{command}` (as root). Machine: {machine}.")
        print(f"Recording window {window.seconds:.1f} s at 1 kHz, {dof} DOF, {args.storage} segments of "
              f"{args.segment:g} s, bridge:=false.\n")
        print("| measure | recorder | baseline (same run) | ratio | target |")
        print("| --- | --- | --- | --- | --- |")
        print(f"| CPU, % of one core | {cpu:.1f} | shared-memory client reading every cycle: {client_cpu:.1f} | "
              f"{ratio(cpu, client_cpu)} | ≤ {CPU_TARGET:g} %: {verdict(cpu <= CPU_TARGET)} |")
        print(f"| bytes per minute per robot | {megabytes(bag_rate)} (whole recording {megabytes(whole_rate)}) | "
              f"rt_raw records ({record_bytes} B each): {megabytes(raw_rate)} | {ratio(bag_rate, raw_rate)} | |")
        print(f"| rt_raw recorded / cycles run | {recorded} / {window.cycles}, dropped **{dropped}** | | | "
              f"0 dropped: {verdict(dropped == 0)} |")
        print(f"| messages in {span_s:.1f} s | " + ", ".join(f"{name} {per_topic.get(name, 0)}" for name in TOPICS)
              + " | | | |")
        print(f"\nWhole recording: {bags.segments} segments ({bags.closed} closed), {gaps} breaks in the rt_raw "
              f"cycle sequence ({missing} missing, {repeats} repeated).\n")
        print("| pair | p99.9 on | p99.9 off | ratio | p50 on | p50 off |")
        print("| --- | --- | --- | --- | --- | --- |")
        for (pair, on, off), value in zip(rows, p999_ratios, strict=False):
            print(f"| {pair} | {on[2]:.0f} | {off[2]:.0f} | {value:.2f} | {on[0]:.0f} | {off[0]:.0f} |")
        print(f"\nLoop p99.9 recording / not recording (one launch), median over {args.pairs} pair(s) of "
              f"{args.window:g} s: **{median:.2f}×** "
              f"(target ≤ {LOOP_TARGET:g}×: {verdict(median <= LOOP_TARGET)}); "
              f"p50 {median_p50:.2f}×; "
              f"p99.9 of all windows pooled {pooled[True]:.0f} / {pooled[False]:.0f} µs = "
              f"{pooled[True] / pooled[False]:.2f}×.")
        succeeded = True
    finally:
        stop_all(children)
        shutil.rmtree(bag_dir, ignore_errors=True)
        if succeeded:
            shutil.rmtree(work, ignore_errors=True)
        else:
            print(f"launch logs kept in {logs}", file=sys.stderr)


if __name__ == "__main__":
    try:
        main()
    except KeyboardInterrupt:
        raise SystemExit("interrupted; the launches and readers were stopped, the bags removed") from None
