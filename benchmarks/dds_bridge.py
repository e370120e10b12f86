"""The DDS bridge: rt_raw at 1 kHz to a ROS 2 subscriber in another process, its cost, and its effect on the loop.

Usage: python benchmarks/dds_bridge.py [--seconds 60] [--window 20] [--pairs 2] [--domain N] [--quick]
Needs root for SCHED_FIFO (as `plem launch` on a real machine). --quick: 2 s windows, one pair (a smoke run).
The full run takes about 4 minutes (2 x --seconds, 2 x --pairs x --window, 1 + 2 x --pairs launches).

What runs:
  robot       `plem launch bus:=mock robot_id:=bench_<pid> record:=false bridge:=true|false` (Indy7 v2, MockBus
              with dynamics, 1 kHz, SCHED_FIFO 98) in a subprocess, in hold mode, with ROS_DOMAIN_ID=--domain
              (default 1 + pid % 100) and ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST (ROS_STATIC_PEERS,
              ROS_LOCALHOST_ONLY and CYCLONEDDS_URI are removed), so the DDS traffic stays on this host and run.
              The same robot is launched several times (one launch per phase below); each window starts after
              1 s of samples flowing (0.5 s with --quick), and each launch is stopped with SIGINT after its
              phase (the benchmark's children are all stopped on any exit).
  rt_raw      launch with the bridge; a subscriber in another process (plem.middleware.node.Node, subscription
              on /<id>/rt_raw, plem_msgs/msg/RtRaw, QoS RT_RAW: reliable, keep last 1000, woken by a WaitSet)
              receives for --seconds. Per sample: latency = time.monotonic_ns() right after take() minus the
              message's monotonic_ns (the cycle's CLOCK_MONOTONIC time, same host), and its cycle number.
                published  cycles the loop produced in the window: last - first + 1 of the received cycles;
                           also the bridge's own dds:rt_raw written counter from /<id>/rt_monitor_stats (10 Hz;
                           the difference between the first and the last message of the window) and the
                           bridge's rt_raw ring reader losses (the rt_raw queue's dropped counter).
                received   valid samples with a cycle in [first, last]; dropped = published - received
                           (target 0).
              Baseline, same launch, right after, also --seconds: a plem.bridge client in another process
              iterating client.stream() (the shared-memory rt_raw ring, the bridge client path the bridge
              itself reads), with latency = time.monotonic_ns() when the sample is returned minus its
              monotonic_ns. The bridge keeps running (without a DDS subscriber) during the baseline.
  CPU         utime + stime from /proc/<pid>/stat at the window's start and end, over SC_CLK_TCK and the window's
              length: % of one core. The bridge's pid is the one the launch summary prints
              (`bridge        running, pid N`); next to it the subscriber's, and as baseline the shared-memory
              client's (a process reading every cycle from shared memory, as the bridge does, without DDS).
  loop        --pairs pairs of --window windows, each on a launch of its own, alternating: with the bridge
              (bridge:=true and the DDS subscriber above receiving rt_raw) / without it (bridge:=false: no DDS at
              all); the order alternates between pairs (with/without, without/with, ...). The loop's wake-up
              latency of every cycle of the window is read from the rt_raw ring (this process drains it every
              0.5 s in every window); p50/p99/p99.9/max per window and the ratio p99.9 with over without, median
              over the pairs. Target: <= 1.1x. The rt_raw window's loop figures are listed for information.
"""

from __future__ import annotations

import argparse
import os
import signal
import statistics
import subprocess
import tempfile
import textwrap
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from plem.bridge import connect
from plem.middleware.qos import RT_RAW

from launching import (
    SHM_CLIENT,
    CpuMeter,
    begin_run,
    drain_loop,
    finish,
    first_sample,
    latency_figures,
    launch,
    ratio,
    result,
    start_reader,
    stop,
    stop_all,
    verdict,
)

#: Environment variables that could widen discovery beyond this host and domain.
DISCOVERY_OVERRIDES = ("ROS_STATIC_PEERS", "ROS_LOCALHOST_ONLY", "CYCLONEDDS_URI")

# argv: robot_id, seconds, settle seconds. Prints "start" when its window starts, then one JSON line, then exits
# when its stdin closes (so that its CPU time can still be read).
SUBSCRIBER = textwrap.dedent("""
    import json, sys, time
    import numpy as np
    from cyclonedds.util import duration
    from plem.middleware.node import Node
    from plem.middleware.qos import DEFAULT, RT_RAW

    robot_id, seconds, settle = sys.argv[1], float(sys.argv[2]), float(sys.argv[3])
    node = Node()
    raw = node.subscription(f"/{robot_id}/rt_raw", "plem_msgs/msg/RtRaw", RT_RAW)
    stats = node.subscription(f"/{robot_id}/rt_monitor_stats", "plem_msgs/msg/RtMonitorStats", DEFAULT)
    waitset = node.waitset([raw, stats])
    wake = duration(milliseconds=100)

    def counters(message):
        queues = {queue.name: queue for queue in message.queues}
        return {"stamp_ns": message.header.stamp.sec * 1_000_000_000 + message.header.stamp.nanosec,
                "written": queues["dds:rt_raw"].written, "ring_dropped": queues["rt_raw"].dropped}

    deadline = time.monotonic() + 20.0
    first = None
    while first is None:
        if time.monotonic() > deadline:
            print(json.dumps({"error": f"no rt_raw sample within 20 s (publishers matched: {raw.publishers})"}),
                  flush=True)
            sys.exit(1)
        waitset.wait(wake)
        first = next((m for m in raw.take(1000) if m.sample_info.valid_data), None)
    end = time.monotonic() + settle
    while time.monotonic() < end:
        waitset.wait(wake)
        raw.take(1000)
        stats.take()
    cycles, latencies, stamps = [], [], []
    print("start", flush=True)
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        waitset.wait(wake)
        messages = raw.take(1000)
        now = time.monotonic_ns()
        for message in messages:
            if message.sample_info.valid_data:
                cycles.append(message.cycle)
                latencies.append(now - message.monotonic_ns)
        for message in stats.take():
            if message.sample_info.valid_data:
                stamps.append(counters(message))
    cycles = np.array(cycles, dtype=np.int64)
    latency_us = np.array(latencies, dtype=np.float64) / 1e3
    ordered = bool(np.all(np.diff(cycles) > 0)) if cycles.size else True
    p50, p99, p999 = np.percentile(latency_us, (50, 99, 99.9)) if cycles.size else (0.0, 0.0, 0.0)
    print(json.dumps({
        "received": int(cycles.size), "first": int(cycles.min()) if cycles.size else 0,
        "last": int(cycles.max()) if cycles.size else -1, "unique": int(np.unique(cycles).size),
        "in_order": ordered, "p50": p50, "p99": p99, "p999": p999,
        "max": float(latency_us.max()) if cycles.size else 0.0,
        "stats_first": stamps[0] if stamps else None, "stats_last": stamps[-1] if stamps else None,
    }), flush=True)
    sys.stdin.read()  # stay alive (for the CPU reading) until the benchmark closes our stdin
    node.close()
""")


# -- processes -----------------------------------------------------------------------------------------
def discovery_environment(domain: int) -> dict[str, str]:
    env = {name: value for name, value in os.environ.items() if name not in DISCOVERY_OVERRIDES}
    env.update(ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    return env


# -- loop latency --------------------------------------------------------------------------------------
@dataclass
class LoopWindow:
    bridge: bool
    latency_us: np.ndarray
    ring_dropped: int
    dds: dict | None = None

    def figures(self) -> tuple[float, float, float, float]:
        return latency_figures(self.latency_us)


def loop_window(robot_id: str, bridge: bool, seconds: float, settle: float, env: dict[str, str], log: Path,
                children: list[subprocess.Popen]) -> LoopWindow:
    """One launch, with the bridge and a DDS subscriber or without the bridge; the loop latency of its window."""
    robot = launch(robot_id, env, log, children, bridge=bridge, record=False)
    subscriber = None
    try:
        client = connect(robot_id)
        first_sample(client, 0.0 if bridge else settle)
        if bridge:
            subscriber = start_reader(SUBSCRIBER, robot_id, seconds, settle, env, children)
        latency, dropped = drain_loop(client, seconds)
        dds = None
        if subscriber is not None:
            dds = result(subscriber, 30.0)
            finish(subscriber)
        client.close()
        return LoopWindow(bridge, latency, dropped, dds)
    finally:
        if subscriber is not None:
            stop(subscriber, signal.SIGTERM, 5.0)
        stop(robot.process)


# -- report --------------------------------------------------------------------------------------------
def counts(data: dict) -> tuple[int, int, int]:
    published = data["last"] - data["first"] + 1
    return published, data["unique"], published - data["unique"]


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0, help="rt_raw window over DDS (and its baseline)")
    parser.add_argument("--window", type=float, default=20.0, help="each loop-latency window")
    parser.add_argument("--pairs", type=int, default=2, help="pairs of loop-latency windows with/without bridge")
    parser.add_argument("--domain", type=int, default=1 + os.getpid() % 100, help="ROS_DOMAIN_ID of the run")
    parser.add_argument("--quick", action="store_true", help="2 s windows, one pair: a smoke run")
    args = parser.parse_args(argv)
    settle = 1.0
    if args.quick:
        args.seconds, args.window, args.pairs, settle = 2.0, 2.0, 1, 0.5
    print(f"machine: {begin_run()}")
    robot_id = f"bench_{os.getpid()}"
    env = discovery_environment(args.domain)
    logs = Path(tempfile.gettempdir())
    children: list[subprocess.Popen] = []
    try:
        # -- rt_raw over DDS and its shared-memory baseline, one launch with the bridge ---------------
        robot = launch(robot_id, env, logs / f"{robot_id}_dds.log", children, bridge=True, record=False)
        print(f"robot {robot_id}, ROS_DOMAIN_ID={args.domain}, discovery localhost; rt_driver pid {robot.driver_pid}, "
              f"bridge pid {robot.bridge_pid}")
        client = connect(robot_id)
        first_sample(client, 0.0)
        subscriber = start_reader(SUBSCRIBER, robot_id, args.seconds, settle, env, children)
        meter = CpuMeter({"bridge": robot.bridge_pid, "subscriber": subscriber.pid})
        dds_loop, dds_loop_dropped = drain_loop(client, args.seconds)
        dds = result(subscriber, 30.0)
        dds_cpu = meter.done()
        finish(subscriber)
        shm_client = start_reader(SHM_CLIENT, robot_id, args.seconds, settle, env, children)
        meter = CpuMeter({"client": shm_client.pid, "bridge": robot.bridge_pid})
        time.sleep(args.seconds)
        shm = result(shm_client, 30.0)
        shm_cpu = meter.done()
        finish(shm_client)
        client.close()
        stop(robot.process)

        depth = f"QoS {RT_RAW.describe()}"
        print(f"\nrt_raw at 1 kHz, {args.seconds:.0f} s to a subscriber in another process ({depth}); "
              f"baseline: plem.bridge client stream() over shared memory, {args.seconds:.0f} s, same launch")
        print(f"  {'':<34}{'DDS':>12}{'shm (baseline)':>16}{'ratio':>9}   target")
        dds_published, dds_received, dds_dropped = counts(dds)
        shm_published, shm_received, shm_dropped = counts(shm)
        print(f"  {'published (cycles first..last)':<34}{dds_published:>12}{shm_published:>16}")
        print(f"  {'received':<34}{dds_received:>12}{shm_received:>16}")
        print(f"  {'dropped':<34}{dds_dropped:>12}{shm_dropped:>16}{'':>9}   0: {verdict(dds_dropped == 0)}")
        for key, name in (("p50", "p50"), ("p99", "p99"), ("p999", "p99.9"), ("max", "max")):
            print(f"  {'latency ' + name + ' (µs)':<34}{dds[key]:>12.0f}{shm[key]:>16.0f}"
                  f"{ratio(dds[key], shm[key]):>9}")
        print(f"  {'CPU, % of one core':<34}{dds_cpu['bridge']:>12.1f}{shm_cpu['client']:>16.1f}"
              f"{ratio(dds_cpu['bridge'], shm_cpu['client']):>9}   (bridge process vs shm client process)")
        print(f"  {'CPU of the DDS subscriber':<34}{dds_cpu['subscriber']:>12.1f}"
              f"   (bridge with no DDS subscriber, during the baseline: {shm_cpu['bridge']:.1f})")
        first, last = dds["stats_first"], dds["stats_last"]
        if first and last and last["stamp_ns"] > first["stamp_ns"]:
            span = (last["stamp_ns"] - first["stamp_ns"]) / 1e9
            print(f"  bridge counters over {span:.1f} s of rt_monitor_stats: dds:rt_raw written "
                  f"{last['written'] - first['written']} ({(last['written'] - first['written']) / span:.0f}/s), "
                  f"rt_raw ring reads lost {last['ring_dropped'] - first['ring_dropped']}")
        else:
            print("  bridge counters: fewer than two rt_monitor_stats messages in the window")
        if not (dds["in_order"] and shm["in_order"]):
            print(f"  note: samples out of order (DDS in order: {dds['in_order']}, shm: {shm['in_order']})")

        # -- loop wake-up latency, alternating launches with and without the bridge ------------------
        windows: list[tuple[int, LoopWindow]] = []
        for pair in range(1, args.pairs + 1):
            order = (True, False) if pair % 2 else (False, True)
            for bridge in order:
                name = "with" if bridge else "without"
                windows.append((pair, loop_window(robot_id, bridge, args.window, settle, env,
                                                  logs / f"{robot_id}_{pair}_{name}.log", children)))

        print(f"\nloop wake-up latency (µs), bridge:=true with a DDS rt_raw subscriber vs bridge:=false, "
              f"{args.pairs} pair{'s' * (args.pairs != 1)} of {args.window:.0f} s windows, each on its own launch")
        print(f"  {'pair':<8}{'bridge':<9}{'cycles':>8}{'p50':>7}{'p99':>7}{'p99.9':>7}{'max':>7}"
              f"{'ring lost':>11}{'DDS dropped':>13}")
        dds_row = LoopWindow(True, dds_loop, dds_loop_dropped, dds)
        rows = [("rt_raw", dds_row), *((str(pair), window) for pair, window in windows)]
        for label, window in rows:
            p50, p99, p999, top = window.figures()
            dropped = counts(window.dds)[2] if window.dds else "-"
            print(f"  {label:<8}{'with' if window.bridge else 'without':<9}{window.latency_us.size:>8}{p50:>7.0f}"
                  f"{p99:>7.0f}{p999:>7.0f}{top:>7.0f}{window.ring_dropped:>11}{dropped:>13}")
        ratios = []
        for pair in range(1, args.pairs + 1):
            by_kind = {window.bridge: window for p, window in windows if p == pair}
            ratios.append(by_kind[True].figures()[2] / by_kind[False].figures()[2])
        median = statistics.median(ratios)
        print(f"  p99.9 with / without per pair: {', '.join(f'{r:.2f}' for r in ratios)}; median {median:.2f}x "
              f"(target <= 1.1x: {verdict(median <= 1.1)})")

        print("\ntargets")
        print(f"  rt_raw dropped over DDS: {dds_dropped} of {dds_published} (target 0): {verdict(dds_dropped == 0)}")
        print(f"  loop p99.9 with bridge / without: {median:.2f}x (target <= 1.1x): {verdict(median <= 1.1)}")
    finally:
        stop_all(children)


if __name__ == "__main__":
    try:
        main()
    except KeyboardInterrupt:
        raise SystemExit("interrupted; the launches and readers were stopped") from None
