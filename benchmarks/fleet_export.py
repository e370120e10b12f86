"""The fleet export: its throughput against rosbags decoding the same bags, the dataset's size against the bags',
and the loop's wake-up latency with the continuous export on and off.

Usage: python benchmarks/fleet_export.py [--seconds 60] [--segment 20] [--repeats 3] [--pairs 15] [--window 8]
                                         [--loop-only] [--quick]
Needs root (the launched loop runs SCHED_FIFO). --quick: 10 s recorded, one repeat, 2 pairs of 3 s windows.
--loop-only: only the loop's pairs.

What runs:
  recording   `plem launch bus:=mock robot_id:=bench_fx_<hex> bridge:=false planner:=false record:=true
              bag_segment_seconds:=--segment` (Indy7 v2, the simulated arm at 1 kHz) for --seconds while the arm
              moves back and forth between two poses 0.6 rad apart on every joint (move_joints, speed_scale 0.5):
              bags as a working robot leaves them. The launch is stopped (SIGINT) and its segments are the input.
  throughput  in this process, --repeats times each, process CPU time (time.process_time):
                export     plem.fleet.export.export of the robot's directory into a fresh temp dataset (decode every
                           topic, write the Parquet files, segments row last), as `plem bag export` does;
                baseline   rosbags alone: AnyReader over the same segments (definitions from the bags), every
                           message of the four exported topics deserialised (rt_raw, rt_events, rt_monitor_stats,
                           joint_states), nothing written.
              Reported: rt_raw rows per CPU second, the median of the repeats, and export / baseline.
              Target: >= 5x.
  size        the dataset's bytes (every .parquet) over the bags' (.mcap files), per table too. Target: <= 0.5.
  loop        one launch with record:=true and bag_segment_seconds:=2 (a segment closes every 2 s), in hold;
              --pairs pairs of --window windows alternate (on/off, off/on, ...): the continuous export on (the
              process `export_dir:=` starts: `python -m plem.fleet.follow ROBOT_DIR DEST THRESHOLD`, started
              before the window, stopped with SIGTERM after it, same DEST throughout; it also exports what closed
              while it was off) / off. Every cycle's wake-up latency is read from the rt_raw ring; p99.9 per
              window, the ratio on / off per pair, its median and spread. Target: median <= 1.05x.
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
from collections import defaultdict
from pathlib import Path

import numpy as np
from rosbags.highlevel import AnyReader

from plem.bridge import connect
from plem.fleet.destination import open_destination
from plem.fleet.export import export
from plem.fleet.schema import TABLES

from launching import begin_run, drain_loop, first_sample, latency_figures, launch, ratio, stop, stop_all, verdict

TOPICS = TABLES[:-1]


def record(robot_id: str, seconds: float, segment: float, env: dict[str, str], logs: Path,
           children: list[subprocess.Popen]) -> Path:
    """A launched robot moving back and forth for `seconds`, recorded; its bag directory once stopped."""
    robot = launch(robot_id, env, logs / f"{robot_id}.log", children, bridge=False, record=True,
                   planner="false", bag_dir=str(logs / "bags"), bag_segment_seconds=f"{segment:g}")
    assert robot.bag_directory is not None
    with connect(robot_id) as client:
        first_sample(client, 0.5)
        poses = [np.full(client.dof, 0.3), np.full(client.dof, -0.3)]
        end, index = time.monotonic() + seconds, 0
        while time.monotonic() < end:
            client.move_joints(poses[index % 2], speed_scale=0.5).wait(30)
            index += 1
    stop(robot.process)
    return robot.bag_directory


def export_cpu(robot_dir: Path, work: Path, run: int) -> tuple[float, int, Path]:
    """CPU seconds of one export of the robot's directory into a fresh dataset, its rt_raw rows, the dataset."""
    target = work / f"dataset_{run}"
    start = time.process_time()
    report = export([robot_dir], open_destination(str(target)))
    return time.process_time() - start, report.rt_raw_rows, target


def rosbags_cpu(segments: list[Path], robot_id: str) -> tuple[float, int]:
    """CPU seconds of rosbags deserialising every message of the exported topics, and the rt_raw messages."""
    start, rows = time.process_time(), 0
    for segment in segments:
        with AnyReader([segment]) as reader:
            wanted = [c for c in reader.connections if c.topic in {f"/{robot_id}/{topic}" for topic in TOPICS}]
            for connection, _, data in reader.messages(connections=wanted):
                reader.deserialize(data, connection.msgtype)
                rows += connection.topic.endswith("/rt_raw")
    return time.process_time() - start, rows


def sizes(dataset: Path, segments: list[Path]) -> tuple[int, int, dict[str, int]]:
    """The dataset's bytes, the bags' .mcap bytes, and the dataset's bytes per table."""
    tables: dict[str, int] = defaultdict(int)
    for path in dataset.rglob("*.parquet"):
        tables[path.relative_to(dataset).parts[0]] += path.stat().st_size
    bags = sum(path.stat().st_size for segment in segments for path in segment.glob("*.mcap"))
    return sum(tables.values()), bags, dict(tables)


def loop_pairs(robot_id: str, pairs: int, window: float, env: dict[str, str], logs: Path,
               children: list[subprocess.Popen]) -> list[tuple[float, float, float, float]]:
    """(p99.9 on, p99.9 off, p50 on, p50 off) per pair of windows with the continuous export on and off."""
    robot = launch(robot_id, env, logs / f"{robot_id}.log", children, bridge=False, record=True,
                   planner="false", bag_dir=str(logs / "loop_bags"), bag_segment_seconds="2")
    assert robot.bag_directory is not None
    destination = logs / "loop_dataset"
    results = []
    with connect(robot_id) as client:
        first_sample(client, 1.0)
        for pair in range(pairs):
            figures: dict[bool, tuple[float, float]] = {}
            for on in ((True, False) if pair % 2 == 0 else (False, True)):
                follower = None
                if on:
                    follower = subprocess.Popen([sys.executable, "-m", "plem.fleet.follow", str(robot.bag_directory),
                                                 str(destination), "99"], env=env, stdout=subprocess.DEVNULL,
                                                stderr=(logs / "follow.log").open("a"))
                    children.append(follower)
                latency, _ = drain_loop(client, window)
                if follower is not None:
                    stop(follower, signal.SIGTERM, 60.0)
                p50, _, p999, _ = latency_figures(latency)
                figures[on] = (p999, p50)
            results.append((figures[True][0], figures[False][0], figures[True][1], figures[False][1]))
            print(f"  pair {pair + 1}: p99.9 on {figures[True][0]:.0f} µs, off {figures[False][0]:.0f} µs, "
                  f"ratio {figures[True][0] / figures[False][0]:.2f}", flush=True)
    stop(robot.process)
    exported = len(list((destination / "segments").rglob("*.parquet"))) if destination.exists() else 0
    print(f"  the continuous export wrote {exported} segments during the on windows", flush=True)
    return results


def throughput_and_size(args: argparse.Namespace, env: dict[str, str], work: Path,
                        children: list[subprocess.Popen]) -> None:
    """Record a moving arm, then time the export against rosbags on its bags and compare the sizes."""
    robot_id = f"bench_fx_{secrets.token_hex(3)}"
    robot_dir = record(robot_id, args.seconds, args.segment, env, work, children)
    segments = sorted(path for path in robot_dir.iterdir() if path.is_dir())
    exports, baselines = [], []
    for run in range(args.repeats):
        seconds, rows, dataset = export_cpu(robot_dir, work, run)
        exports.append(rows / seconds)
        base_seconds, base_rows = rosbags_cpu(segments, robot_id)
        baselines.append(base_rows / base_seconds)
        assert rows == base_rows, f"export {rows} rt_raw rows, rosbags {base_rows}"
        print(f"  repeat {run + 1}: export {rows / seconds:,.0f} rt_raw rows/s ({seconds:.2f} s CPU), rosbags "
              f"{base_rows / base_seconds:,.0f} rows/s ({base_seconds:.2f} s CPU)", flush=True)
    export_rate, base_rate = statistics.median(exports), statistics.median(baselines)
    print(f"throughput ({rows} rt_raw rows in {len(segments)} segments): export {export_rate:,.0f} rows/s, "
          f"rosbags alone {base_rate:,.0f} rows/s: {ratio(export_rate, base_rate)} "
          f"(target >= 5x: {verdict(export_rate >= 5 * base_rate)})")
    total, bags, tables = sizes(dataset, segments)
    print(f"size: dataset {total / 1e6:.2f} MB, bags (.mcap) {bags / 1e6:.2f} MB: {total / bags:.3f} "
          f"(target <= 0.5: {verdict(total <= 0.5 * bags)}); per table: "
          + ", ".join(f"{name} {size / 1e6:.2f} MB" for name, size in sorted(tables.items())), flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--segment", type=float, default=20.0)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--pairs", type=int, default=15)
    parser.add_argument("--window", type=float, default=8.0)
    parser.add_argument("--loop-only", action="store_true")
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    if args.quick:
        args.seconds, args.segment, args.repeats, args.pairs, args.window = 10.0, 4.0, 1, 2, 3.0
    machine = begin_run()
    print(f"machine: {machine}")
    print(f"command: .venv/bin/python benchmarks/fleet_export.py --seconds {args.seconds:g} --segment "
          f"{args.segment:g} --repeats {args.repeats} --pairs {args.pairs} --window {args.window:g}"
          + (" --loop-only" if args.loop_only else ""), flush=True)
    env = dict(os.environ)
    children: list[subprocess.Popen] = []
    work = Path(tempfile.mkdtemp(prefix="plem_fleet_bench_"))
    try:
        if not args.loop_only:
            throughput_and_size(args, env, work, children)
        print(f"loop: {args.pairs} pairs of {args.window:g} s windows, continuous export on / off", flush=True)
        pairs = loop_pairs(f"bench_fl_{secrets.token_hex(3)}", args.pairs, args.window, env, work, children)
        ratios = [on / off for on, off, _, _ in pairs]
        median = statistics.median(ratios)
        print(f"loop p99.9 on / off: median {median:.2f}x over {len(pairs)} pairs, spread {min(ratios):.2f}-"
              f"{max(ratios):.2f}x (target <= 1.05x: {verdict(median <= 1.05)}); p50 median "
              f"{statistics.median(on / off for _, _, on, off in pairs):.2f}x; median window p99.9 on "
              f"{statistics.median(on for on, _, _, _ in pairs):.0f} µs, off "
              f"{statistics.median(off for _, off, _, _ in pairs):.0f} µs")
    finally:
        stop_all(children)
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
