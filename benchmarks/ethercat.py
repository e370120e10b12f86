"""plem's EtherCAT master on the virtual network, against a bare pysoem loop on the same emulator and cyclictest.

Usage: python benchmarks/ethercat.py [--soak-minutes 10] [--pairs 15] [--window 8] [--quick]
Needs root (SCHED_FIFO, raw sockets, network namespaces). Installs Debian's rt-tests when `cyclictest` is
missing. --quick: a 1-minute soak and 3 pairs of 3 s windows (a smoke run). The full run takes about
10 + 15 x (3 x 8 s + start-up) = 20 minutes.

What runs:
  network   one `plem ethercat simulate robot_type:=indy7_v2 master_index:=60` for the whole run: six emulated
            CiA402 drives (SCHED_FIFO 90) moving the simulated Indy7 v2 behind plemec60.
  soak      `plem launch bus:=ethercat eth_interface:=plemec60 robot_type:=indy7_v2 bridge:=false record:=false`
            (RT driver at 1 kHz, SCHED_FIFO 98), hold, then a trajectory running for --soak-minutes: move_joints
            between zero and POSE at half speed, one after the other. Figures over the soak window (driver
            statistics after minus before, wake-up latency of every cycle from the rt_raw ring): frames lost,
            working-counter errors, exchange round trip p50/p99/max (whole run of the driver: the soak plus
            a few hundred start-up exchanges), loop wake-up p99/p99.9, compute p99 (wake-up to the end of the
            cycle, the exchange included; whole run of the driver), and the emulator's CPU (% of one core).
  pairs     --pairs times, the order rotating: plem, bare pysoem, cyclictest, each for --window s.
              plem        a fresh launch as in the soak, holding with a trajectory running; round trip of
                          that launch's exchanges, wake-up latency of the window's cycles.
              bare        BARE below: the same bring-up (plem.fieldbus.ethercat.bringup, so the same PDOs),
                          then a bare loop at SCHED_FIFO 98: absolute clock_nanosleep, six outputs packed with
                          struct (controlwords enabling the drives, which then hold where they are, so the
                          emulator servos the same arm), send_processdata, receive_processdata(500 µs), six
                          inputs unpacked.
              cyclictest  cyclictest -m -p98 --policy=fifo -t1 -i1000 -D<window> (benchmarks/loop_latency.py).
            Ratios within each pair: plem round trip p50 and p99 / bare's; plem wake-up p99 / cyclictest's.
            Reported: the median over the pairs with the spread (min-max).
Targets: 0 lost frames in the soak; round trip ratio <= 1.2; wake-up p99 ratio <= 1.2.
"""

from __future__ import annotations

import argparse
import json
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

import launching
import loop_latency

INDEX = 60
INTERFACE = f"plemec{INDEX}"
POSE = [0.4, -0.3, 0.3, 0.5, -0.4, 0.5]

# argv: interface, seconds. Brings the segment to OP with plem's bring-up, runs a bare pysoem loop, prints JSON.
BARE = textwrap.dedent("""
    import json, os, struct, sys, time
    import numpy as np
    from plem.control.realtime import AbsoluteSleeper
    from plem.fieldbus.bus import DriveState
    from plem.fieldbus.cia402 import decode_statusword, next_controlword
    from plem.fieldbus.ethercat.bringup import bring_up, close_master
    from plem.launch.ethercat_sim import arm_of_plan
    from plem.launch.plan import plan_robot

    interface, seconds = sys.argv[1], float(sys.argv[2])
    arm = arm_of_plan(plan_robot({"bus": "ethercat", "robot_type": "indy7_v2", "eth_interface": interface},
                                 generate=False))
    os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(98))
    def exchange(master):
        master.send_processdata()
        master.receive_processdata(2000)
    segment = bring_up(interface, arm.joint_names, arm.drives, 1_000_000, exchange)
    master, slaves = segment.master, segment.slaves
    inputs = [struct.unpack("<HiihHb", slave.input) for slave in slaves]
    targets = [values[1] for values in inputs]                 # hold where the drives are
    controlwords = [0] * len(slaves)
    count = int(seconds * 1000)
    rtt, latency, compute = (np.zeros(count, dtype=np.int64) for _ in range(3))
    bad = 0
    sleeper = AbsoluteSleeper()
    period = 1_000_000
    deadline = time.monotonic_ns() + period
    try:
        for i in range(count):
            sleeper.sleep_until(deadline)
            woke = time.monotonic_ns()
            for d, (slave, values) in enumerate(zip(slaves, inputs)):
                controlwords[d] = next_controlword(decode_statusword(values[0]), DriveState.OPERATION_ENABLED,
                                                   controlwords[d])
                slave.output = struct.pack("<HiihB", controlwords[d], targets[d], 0, 0, 8)
            sent = time.perf_counter_ns()
            master.send_processdata()
            wkc = master.receive_processdata(500)
            rtt[i] = time.perf_counter_ns() - sent
            bad += wkc != master.expected_wkc
            inputs = [struct.unpack("<HiihHb", slave.input) for slave in slaves]
            done = time.monotonic_ns()
            latency[i], compute[i] = woke - deadline, done - woke
            deadline += period
            if done > deadline:
                deadline += ((done - deadline) // period + 1) * period
    finally:
        close_master(master)
    us = lambda a, q: float(np.percentile(a, q)) / 1e3
    print(json.dumps({"cycles": count, "bad": int(bad), "rtt_p50": us(rtt, 50), "rtt_p99": us(rtt, 99),
                      "rtt_max": float(rtt.max()) / 1e3, "latency_p99": us(latency, 99),
                      "compute_p99": us(compute, 99)}), flush=True)
""")


def start_network(env: dict[str, str], log: Path, children: list[subprocess.Popen]) -> subprocess.Popen:
    """`plem ethercat simulate` of the Indy7 v2, returned once it serves."""
    output = log.open("w")
    process = subprocess.Popen([sys.executable, "-m", "plem.cli", "ethercat", "simulate", "robot_type:=indy7_v2",
                                f"master_index:={INDEX}"], stdout=output, stderr=subprocess.STDOUT, text=True,
                               env=env, start_new_session=True)
    children.append(process)
    deadline = time.monotonic() + 60
    while f"behind {INTERFACE}" not in log.read_text():
        if process.poll() is not None or time.monotonic() > deadline:
            raise SystemExit(f"the virtual network did not start:\n{log.read_text()}")
        time.sleep(0.1)
    return process


def moving(client, seconds: float) -> tuple[np.ndarray, int]:
    """Keep a trajectory running while the loop's wake-up latencies of `seconds` are drained."""
    latencies: list[np.ndarray] = []
    dropped = 0
    end = time.monotonic() + seconds
    target = POSE
    while (left := end - time.monotonic()) > 0:
        handle = client.move_joints(target, speed_scale=0.5)
        window, lost = launching.drain_loop(client, min(left, 2.0))
        latencies.append(window)
        dropped += lost
        handle.wait(60)
        target = [0.0] * 6 if target is POSE else POSE
    return np.concatenate(latencies), dropped


def plem_window(env: dict[str, str], directory: Path, children: list[subprocess.Popen], seconds: float) -> dict:
    """One launch on the virtual network, holding with a trajectory running for `seconds`: its figures."""
    robot_id = f"bench_ec_{secrets.token_hex(3)}"
    started = launching.launch(robot_id, env, directory / f"{robot_id}.log", children, bridge=False, record=False,
                               bus="ethercat", eth_interface=INTERFACE, master_index=INDEX, robot_type="indy7_v2")
    try:
        with connect(robot_id) as client:
            client.set_mode("hold")
            before = stats_after(client, time.monotonic_ns())
            latency, dropped = moving(client, seconds)
            after = stats_after(client, time.monotonic_ns())
    finally:
        launching.stop(started.process)
        children.remove(started.process)
    bus = after["bus"]
    return {"lost": bus["lost_frames"] - before["bus"]["lost_frames"],
            "wkc_errors": bus["working_counter_errors"] - before["bus"]["working_counter_errors"],
            "rtt_p50": bus["round_trip"]["p50_us"], "rtt_p99": bus["round_trip"]["p99_us"],
            "rtt_max": bus["round_trip"]["max_us"], "rtt_samples": bus["round_trip"]["samples"],
            "latency_p99": float(np.percentile(latency, 99)), "latency_p999": float(np.percentile(latency, 99.9)),
            "compute_p99": after["compute"]["p99_us"], "cycles": int(latency.size),
            "ring_dropped": dropped, "overruns": after["overruns"] - before["overruns"],
            "fault": after["fault_reason"]}


def stats_after(client, monotonic_ns: int) -> dict:
    """The driver's first statistics record written after `monotonic_ns`."""
    deadline = time.monotonic() + 5
    while time.monotonic() < deadline:
        stats = client.stats()
        if stats is not None and stats["monotonic_ns"] > monotonic_ns:
            return stats
        time.sleep(0.02)
    raise SystemExit("the driver published no statistics")


def bare_window(env: dict[str, str], seconds: float) -> dict:
    done = subprocess.run([sys.executable, "-c", BARE, INTERFACE, str(seconds)], capture_output=True, text=True,
                          env=env, timeout=seconds + 60)
    if done.returncode != 0:
        raise SystemExit(f"the bare pysoem loop failed:\n{done.stderr[-2000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def spread(values: list[float]) -> str:
    return f"{statistics.median(values):.2f}x ({min(values):.2f}-{max(values):.2f})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--soak-minutes", type=float, default=10.0)
    parser.add_argument("--pairs", type=int, default=15)
    parser.add_argument("--window", type=float, default=8.0)
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    if args.quick:
        args.soak_minutes, args.pairs, args.window = 1.0, 3, 3.0
    machine = launching.begin_run()
    cyclictest = loop_latency.ensure_cyclictest()
    print(f"machine: {machine}", flush=True)
    children: list[subprocess.Popen] = []
    with tempfile.TemporaryDirectory(prefix="plem-bench-ethercat-") as tmp:
        directory = Path(tmp)
        env = {**os.environ, "PLEM_HOME": str(directory / "home")}
        try:
            network = start_network(env, directory / "network.log", children)
            meter = launching.CpuMeter({"emulator": network.pid})
            soak = plem_window(env, directory, children, args.soak_minutes * 60)
            emulator_cpu = meter.done()["emulator"]
            print(f"soak ({args.soak_minutes:g} min at 1 kHz, trajectory running): {soak['cycles']} cycles, "
                  f"frames lost {soak['lost']}, working-counter errors {soak['wkc_errors']}, overruns "
                  f"{soak['overruns']}, fault: {soak['fault'] or 'none'}", flush=True)
            print(f"  round trip p50 {soak['rtt_p50']:.0f} µs, p99 {soak['rtt_p99']:.0f} µs, max "
                  f"{soak['rtt_max']:.0f} µs ({soak['rtt_samples']} exchanges); wake-up p99 "
                  f"{soak['latency_p99']:.0f} µs, p99.9 {soak['latency_p999']:.0f} µs; compute p99 "
                  f"{soak['compute_p99']:.0f} µs; emulator CPU {emulator_cpu:.0f} % of a core", flush=True)
            print(f"  target 0 lost frames: {launching.verdict(soak['lost'] == 0)}", flush=True)
            rtt50, rtt99, wake = [], [], []
            sides = ("plem", "bare", "cyclictest")
            for pair in range(args.pairs):
                results: dict[str, dict] = {}
                for side in sides[pair % 3:] + sides[:pair % 3]:
                    if side == "plem":
                        results[side] = plem_window(env, directory, children, args.window)
                    elif side == "bare":
                        results[side] = bare_window(env, args.window)
                    else:
                        run, _ = loop_latency.run_cyclictest(cyclictest, 1000, max(1, round(args.window)))
                        results[side] = {"latency_p99": float(run.latency.p99)}
                plem, bare, cyclic = results["plem"], results["bare"], results["cyclictest"]
                rtt50.append(plem["rtt_p50"] / bare["rtt_p50"])
                rtt99.append(plem["rtt_p99"] / bare["rtt_p99"])
                wake.append(plem["latency_p99"] / cyclic["latency_p99"])
                print(f"pair {pair + 1:2d}: round trip p50 plem {plem['rtt_p50']:.0f} / bare {bare['rtt_p50']:.0f} µs, "
                      f"p99 {plem['rtt_p99']:.0f} / {bare['rtt_p99']:.0f} µs (max {plem['rtt_max']:.0f} / "
                      f"{bare['rtt_max']:.0f}); wake-up p99 plem {plem['latency_p99']:.0f} / cyclictest "
                      f"{cyclic['latency_p99']:.0f} µs; lost plem {plem['lost']} bare {bare['bad']}", flush=True)
            print(f"round trip p50 plem/bare: {spread(rtt50)}; p99: {spread(rtt99)}; target <= 1.2x: "
                  f"{launching.verdict(statistics.median(rtt99) <= 1.2 and statistics.median(rtt50) <= 1.2)}")
            print(f"wake-up p99 plem/cyclictest: {spread(wake)}; target <= 1.2x: "
                  f"{launching.verdict(statistics.median(wake) <= 1.2)}")
        finally:
            launching.stop_all(children)


if __name__ == "__main__":
    main()
