"""The loop while a client floods the command path, against the same loop idle.

Usage: python benchmarks/command_flood.py [--pairs 15] [--window 4] [--quick]
Needs root for SCHED_FIFO (as `plem launch` on a real machine). --quick: 2 pairs of 2 s windows per flood
kind (a smoke run). The full run takes about 7 minutes (3 kinds x --pairs x 2 windows x --window, plus start-up).

What runs:
  robot      one `plem launch bus:=mock robot_id:=bench_flood_<hex> bridge:=false record:=false` (Indy7 v2,
             MockBus with dynamics, 1 kHz, SCHED_FIFO 98) in a subprocess, holding. One launch for every window.
  floods     a flooder process (ordinary priority, like any client) sending for one window:
               valid    the largest valid trajectory (5000 quintic points, 5.5 s, joint 0 moving 0.02 rad on a cycloid)
                        through plem.bridge's execute_trajectory, again and again: each one is validated,
                        fitted and handed to the loop by the command service and preempts the one before.
               invalid  requests refused by the command service, alternating: a 600 KB trajectory whose last
                        point is outside the position limits (read whole before it is refused) and a frame
                        announcing more than the 4 MiB request limit (the connection is closed; the flooder
                        reconnects).
               busy     the control: two processes parsing the invalid flood's 600 KB request in a loop, as
                        the flooder and the command service do, without touching the robot. What the loop
                        shows under it is what any such load costs it on this machine.
             It reports how many requests it sent and how many were accepted or refused.
  windows    for each kind, --pairs pairs of --window s: flood / idle, the order alternating between pairs.
             The loop's wake-up latency of every cycle of the window is read from the rt_raw ring (drained
             every 0.5 s). Per pair: p99.9 flood / idle; reported: the median ratio over the pairs with its
             spread (min-max), p50 ratio likewise, and p99.9 of all windows of each kind pooled.
             Faults: FAULT events over the whole run (target 0); overruns per kind of window from the driver's
             statistics (its record after the window minus the one before).
             Target: median p99.9 ratio <= 1.1x for the valid and invalid floods, and 0 faults.
"""

from __future__ import annotations

import argparse
import os
import secrets
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np

from plem.bridge import connect
from plem.control.events import EventKind

import launching

#: Processes of the "busy" control: about the CPU the invalid flood keeps busy (its client and the command service).
BUSY_PROCESSES = 2

# argv: robot_id, kind, seconds. Prints "start", floods for `seconds`, prints one JSON line, waits for stdin to close.
FLOODER = textwrap.dedent("""
    import json, math, socket, struct, sys, time
    from plem.bridge import connect
    from plem.control.trajectory import JointTrajectory
    from plem.errors import PlemError
    from plem.ipc.command_socket import frame, socket_path

    robot_id, kind, seconds = sys.argv[1], sys.argv[2], float(sys.argv[3])
    client = connect(robot_id)
    base = client.state().command_position.copy()
    sent = accepted = refused = 0

    def wave(points, lead, duration, amplitude):
        rows = []
        for i in range(points):
            t = duration * (i + 1) / points
            phase = 2 * math.pi * t / duration
            p, v, a = base.copy(), [0.0] * client.dof, [0.0] * client.dof
            p[0] += amplitude * (t / duration - math.sin(phase) / (2 * math.pi))     # a cycloid: at rest at both ends
            v[0] = amplitude / duration * (1 - math.cos(phase))
            a[0] = amplitude / duration * 2 * math.pi / duration * math.sin(phase)
            rows.append({"positions": p.tolist(), "time_from_start": lead + t, "velocities": v,
                         "accelerations": a})
        return rows

    valid = JointTrajectory.from_lists(client.joint_names, wave(5000, 0.5, 5.0, 0.02))
    invalid = wave(2400, 0.5, 5.0, 0.02)
    invalid[-1]["positions"] = [10.0] * client.dof   # outside every joint's range
    invalid_frame = frame(json.dumps({"id": "flood", "op": "execute_trajectory",
                                      "joint_names": list(client.joint_names), "points": invalid}).encode())
    oversized = struct.pack("<I", 5 << 20) + b"x" * 4096

    def raw():
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        sock.connect(str(socket_path(robot_id)))
        return sock

    print("start", flush=True)
    end = time.monotonic() + seconds
    sock = raw() if kind == "invalid" else None
    while time.monotonic() < end:
        sent += 1
        if kind == "busy":      # the same parsing work, done here: the robot is not involved
            json.loads(invalid_frame[4:])
            continue
        if kind == "valid":
            try:
                client.execute_trajectory(valid)
                accepted += 1
            except PlemError:
                refused += 1
            continue
        try:
            if sent % 2:
                sock.sendall(invalid_frame)
                answer = b""
                while len(answer) < 4 or len(answer) < 4 + struct.unpack("<I", answer[:4])[0]:
                    answer += sock.recv(1 << 16)
                refused += json.loads(answer[4:])["stage"] == "rejected"
            else:
                sock.sendall(oversized)
                while sock.recv(1 << 16):
                    pass
                refused += 1
                sock.close()
                sock = raw()
        except OSError:
            sock = raw()
    if kind == "valid":
        try:
            client.stop().wait(5)
        except PlemError:
            pass
    print(json.dumps({"sent": sent, "accepted": accepted, "refused": refused}), flush=True)
    sys.stdin.read()
""")


def flood_window(robot_id: str, kind: str, seconds: float, client, env: dict[str, str],
                 children: list[subprocess.Popen]) -> tuple[np.ndarray, dict]:
    processes = [subprocess.Popen([sys.executable, "-c", FLOODER, robot_id, kind, str(seconds)], stdin=subprocess.PIPE,
                                  stdout=subprocess.PIPE, text=True, env=env, start_new_session=True)
                 for _ in range(BUSY_PROCESSES if kind == "busy" else 1)]
    children.extend(processes)
    if any(launching.read_line(process, 60.0) != "start" for process in processes):
        raise SystemExit(f"the {kind} flooder did not start")
    latencies, _ = launching.drain_loop(client, seconds)
    counts = [launching.result(process, 60.0) for process in processes]
    for process in processes:
        launching.finish(process)
    client.wait_until_idle(30)
    return latencies, {key: sum(count[key] for count in counts) for key in counts[0]}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--pairs", type=int, default=15)
    parser.add_argument("--window", type=float, default=4.0)
    parser.add_argument("--quick", action="store_true")
    options = parser.parse_args(argv)
    if options.quick:
        options.pairs, options.window = 2, 2.0
    machine = launching.begin_run()
    robot_id = f"bench_flood_{secrets.token_hex(3)}"
    env = {**os.environ, "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    children: list[subprocess.Popen] = []
    print(f"# command flood: {machine}")
    print(f"# {options.pairs} pairs of {options.window:g} s windows per flood kind, one launch, robot {robot_id}")
    with tempfile.TemporaryDirectory() as directory:
        try:
            launching.launch(robot_id, env, Path(directory) / "launch.log", children, bridge=False, record=False)
            client = connect(robot_id)
            launching.first_sample(client, 1.0)
            events = client.events(timeout=0)
            overruns_before = client.stats()["overruns"]
            report = {}
            for kind in ("valid", "invalid", "busy"):
                report[kind] = measure(kind, options, robot_id, client, env, children)
            faults = [event for event in events if event.kind is EventKind.FAULT]
            overruns = client.stats()["overruns"] - overruns_before
        finally:
            launching.stop_all(children)
    print()
    print("| flood | requests sent (accepted/refused) | p99.9 flood/idle, median (min-max) | p50 median | "
          "pooled p99.9 flood / idle | overruns flood / idle |")
    print("|---|---|---|---|---|---|")
    met = not faults
    for kind, figures in report.items():
        met &= kind == "busy" or figures["median"] <= 1.1
        print(f"| {kind} | {figures['sent']} ({figures['accepted']}/{figures['refused']}) | "
              f"**{figures['median']:.2f}x** ({figures['low']:.2f}-{figures['high']:.2f}) | {figures['p50']:.2f}x | "
              f"{figures['pooled'][0]:.0f} µs / {figures['pooled'][1]:.0f} µs | "
              f"{figures['overruns']['flood']} / {figures['overruns']['idle']} |")
    print(f"\nfaults: {len(faults)} {[event.reason for event in faults]}; overruns over the run: {overruns}")
    print(f"target (median p99.9 <= 1.1x for the valid and invalid floods, 0 faults): {launching.verdict(met)}")
    return 0


def measure(kind: str, options: argparse.Namespace, robot_id: str, client, env: dict[str, str],
            children: list[subprocess.Popen]) -> dict:
    """Alternating flood and idle windows; the per-pair ratios and totals of one flood kind."""
    ratios, p50_ratios, pooled = [], [], {"flood": [], "idle": []}
    totals = {"sent": 0, "accepted": 0, "refused": 0}
    overruns = {"flood": 0, "idle": 0}
    for pair in range(options.pairs):
        figures = {}
        for window in (("flood", "idle") if pair % 2 == 0 else ("idle", "flood")):
            before = latest_stats(client)["overruns"]
            if window == "flood":
                latencies, counts = flood_window(robot_id, kind, options.window, client, env, children)
                totals = {key: totals[key] + counts[key] for key in totals}
            else:
                latencies, _ = launching.drain_loop(client, options.window)
            figures[window] = launching.latency_figures(latencies)
            pooled[window].append(latencies)
            overruns[window] += latest_stats(client)["overruns"] - before
        ratios.append(figures["flood"][2] / figures["idle"][2])
        p50_ratios.append(figures["flood"][0] / figures["idle"][0])
        print(f"{kind} pair {pair + 1}: p99.9 flood {figures['flood'][2]:.0f} µs, idle {figures['idle'][2]:.0f} µs "
              f"({ratios[-1]:.2f}x); max {figures['flood'][3]:.0f} / {figures['idle'][3]:.0f} µs; "
              f"load {os.getloadavg()[0]:.2f}", flush=True)
    pooled_p999 = tuple(float(np.percentile(np.concatenate(pooled[w]), 99.9)) for w in ("flood", "idle"))
    return {**totals, "median": statistics.median(ratios), "low": min(ratios), "high": max(ratios),
            "p50": statistics.median(p50_ratios), "pooled": pooled_p999, "overruns": overruns}


def latest_stats(client) -> dict:
    """The driver's next statistics record (they come 10 times a second), so a window's count is complete."""
    first = client.stats()
    deadline = time.monotonic() + 1.0
    while (record := client.stats()) == first and time.monotonic() < deadline:
        time.sleep(0.01)
    return record


if __name__ == "__main__":
    sys.exit(main())
