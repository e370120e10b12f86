"""The bring-up's shared-memory path: command latency, cost of a state read, loop latency under polling clients.

Usage: python benchmarks/bridge_ipc.py [--seconds 20] [--pairs 3] [--clients 10] [--moves 200]
Needs root for SCHED_FIFO (as `plem launch` on a real machine).

What runs:
  robot       `plem launch bus:=mock robot_id:=bench_<pid> bridge:=false record:=false` (Indy7 v2, MockBus
              with dynamics, 1 kHz, SCHED_FIFO 98) in a subprocess, in hold mode: the RT driver alone. The
              measurements are made from this process through plem.bridge.connect, as any client would.
  command     --moves small move_joints (0.02 rad on every joint, back and forth), each waited for. Latency =
              from just before the client's move_joints() call to the loop cycle that starts the motion (its
              motion_started event): in cycles (1 = the first cycle after the call; counted from the last
              cycle published before the call) and in
              µs (event time minus the call time). Baseline, same run: the same moves on an in-process Robot
              (same model and bus, loop in a thread of this process), where move_joints plans in the caller and
              hands the motion to the loop through a deque. It runs only for its own moves, after the client's
              moves and reads, so its loop thread disturbs neither.
  state read  client.state() from shared memory, against the same StateBlock.read() over private memory
              (the in-process robot's read); 5 interleaved rounds of 50 000 reads, median of the per-read means.
  polling     --pairs pairs of --seconds windows: no clients / --clients processes each calling
              client.state() in a tight loop (the order alternates between pairs). The loop's wake-up latency
              of every cycle of the window is read from the rt_raw ring (this process drains it every 0.5 s in
              both windows); p50/p99/p99.9/max per window and the ratio with clients over without, median over
              the pairs. Target: p99.9 <= 1.1x.
"""

from __future__ import annotations

import argparse
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from plem.bridge import connect
from plem.bridge.client import RobotClient
from plem.control.events import EventKind
from plem.control.state import StateBlock
from plem.fieldbus import MockBus
from plem.robot import Indy7V2, Robot

from launching import begin_run, drain_loop, first_sample, latency_figures, launch, read_line, stop_all, verdict

AMPLITUDE = 0.02


def move_latencies(move: Callable[[list[float]], object], started: Callable[[], tuple[int, int]],
                   cycle: Callable[[], int], dof: int, moves: int) -> tuple[list[int], list[float]]:
    """Cycles and µs from each move_joints call to its motion_started event."""
    cycles, micros = [], []
    for index in range(moves):
        target = [AMPLITUDE * (index % 2)] * dof
        before_cycle, before_ns = cycle(), time.monotonic_ns()
        move(target)
        event_cycle, event_ns = started()
        cycles.append(event_cycle + 1 - before_cycle)  # an event's cycle counts the cycles before its own
        micros.append((event_ns - before_ns) / 1e3)
    return cycles, micros


def remote_latencies(client: RobotClient, moves: int) -> tuple[list[int], list[float]]:
    events = client.events(timeout=5.0)

    def started() -> tuple[int, int]:
        event = next(e for e in events if e.kind is EventKind.MOTION_STARTED)
        return event.cycle, event.monotonic_ns

    return move_latencies(lambda target: client.move_joints(target).wait(30), started,
                          lambda: client.state().cycle, client.dof, moves)


def local_latencies(robot: Robot, moves: int) -> tuple[list[int], list[float]]:
    seen: list[tuple[int, int]] = []
    robot.events.subscribe(lambda e: seen.append((e.cycle, e.monotonic_ns)) if e.kind is EventKind.MOTION_STARTED
                           else None)

    def started() -> tuple[int, int]:
        return seen.pop(0)

    return move_latencies(lambda target: robot.move_joints(target).wait(30), started,
                          lambda: robot.state().cycle, robot.limits.dof, moves)


def read_cost(reads: Sequence[tuple[str, Callable[[], object]]], rounds: int = 5,
              count: int = 50_000) -> dict[str, float]:
    """Median over interleaved rounds of the mean µs per call."""
    samples: dict[str, list[float]] = {name: [] for name, _ in reads}
    for _ in range(rounds):
        for name, read in reads:
            start = time.perf_counter()
            for _ in range(count):
                read()
            samples[name].append((time.perf_counter() - start) / count * 1e6)
    return {name: statistics.median(values) for name, values in samples.items()}


POLLER = textwrap.dedent("""
    import signal, sys
    from plem.bridge import connect
    client = connect(sys.argv[1])
    reads = 0
    def report(*_):
        print(reads, flush=True)
        sys.exit(0)
    signal.signal(signal.SIGTERM, report)
    print("ready", flush=True)
    while True:
        client.state()
        reads += 1
""")


@dataclass
class Window:
    clients: int
    latency_us: np.ndarray
    dropped: int
    reads_per_s: float                     # of all pollers together, from their start to their stop


def window(client: RobotClient, robot_id: str, clients: int, seconds: float, env: dict[str, str],
           children: list[subprocess.Popen]) -> Window:
    """The loop latency of `seconds` with `clients` poller processes calling client.state(); their reads per s."""
    pollers = [subprocess.Popen([sys.executable, "-c", POLLER, robot_id], stdout=subprocess.PIPE, text=True, env=env,
                                start_new_session=True) for _ in range(clients)]
    children.extend(pollers)
    for poller in pollers:
        if read_line(poller, 30.0) != "ready":
            raise SystemExit("a polling client did not start")
    start = time.monotonic()
    latency, dropped = drain_loop(client, seconds)
    reads = 0
    for poller in pollers:
        poller.send_signal(signal.SIGTERM)
        reads += int(read_line(poller, 10.0) or 0)
        poller.wait()
        children.remove(poller)
    return Window(clients, latency, dropped, reads / (time.monotonic() - start))


def percentiles(values: Sequence[float]) -> str:
    p50, p99 = np.percentile(values, (50, 99))
    return f"p50 {p50:.0f}  p99 {p99:.0f}"


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--pairs", type=int, default=3)
    parser.add_argument("--clients", type=int, default=10)
    parser.add_argument("--moves", type=int, default=200)
    args = parser.parse_args(argv)
    print(f"machine: {begin_run()}")
    robot_id = f"bench_{os.getpid()}"
    env = dict(os.environ)
    children: list[subprocess.Popen] = []
    try:
        launch(robot_id, env, Path(tempfile.gettempdir()) / f"{robot_id}.log", children, bridge=False, record=False)
        client = connect(robot_id)
        first_sample(client, 0.0)
        print(f"\ncommand latency, {args.moves} move_joints each (cycles of 1 ms; µs)")
        remote_cycles, remote_us = remote_latencies(client, args.moves)
        block = StateBlock(client.dof)
        block.publish(np.zeros((6, client.dof)), 1, time.monotonic_ns(), 1, False, True)
        costs = read_cost([("client.state() over shared memory", client.state),
                           ("StateBlock.read() over private memory (baseline)", block.read)])
        config = Indy7V2()                 # the baseline robot runs only for its own moves
        config.custom_bus = MockBus(config.dof)
        local = Robot.builder(config).with_robot_id(f"local_{os.getpid()}").build()
        local.start()
        try:
            local.set_mode("hold")
            local_cycles, local_us = local_latencies(local, args.moves)
        finally:
            local.shutdown()
        print(f"  plem.bridge client (shared memory)  cycles {percentiles(remote_cycles)}   "
              f"µs {percentiles(remote_us)}")
        print(f"  in-process Robot (baseline)         cycles {percentiles(local_cycles)}   µs {percentiles(local_us)}")
        print(f"  ratio p50 (µs) {np.median(remote_us) / np.median(local_us):.2f}x")
        print("\none state read (µs, median of 5 rounds of 50 000)")
        for name, cost in costs.items():
            print(f"  {name:<52} {cost:.2f}")
        values = list(costs.values())
        print(f"  ratio {values[0] / values[1]:.2f}x")

        print(f"\nloop wake-up latency (µs) with {args.clients} clients polling state() vs none, "
              f"{args.pairs} pairs of {args.seconds:.0f} s (the order alternates between pairs)")
        print(f"  {'pair':<5}{'clients':>8}{'cycles':>8}{'p50':>7}{'p99':>7}{'p99.9':>7}{'max':>7}"
              f"{'dropped':>9}{'reads/s':>12}")
        ratios = []
        for pair in range(1, args.pairs + 1):
            order = (0, args.clients) if pair % 2 else (args.clients, 0)
            runs = {count: window(client, robot_id, count, args.seconds, env, children) for count in order}
            for count in order:
                run = runs[count]
                p50, p99, p999, top = latency_figures(run.latency_us)
                print(f"  {pair:<5}{run.clients:>8}{run.latency_us.size:>8}{p50:>7.0f}{p99:>7.0f}"
                      f"{p999:>7.0f}{top:>7.0f}{run.dropped:>9}{run.reads_per_s:>12.0f}")
            ratios.append(latency_figures(runs[args.clients].latency_us)[2] / latency_figures(runs[0].latency_us)[2])
        median = statistics.median(ratios)
        print(f"  p99.9 ratio per pair: {', '.join(f'{r:.2f}' for r in ratios)}; median {median:.2f}x "
              f"(target <= 1.1x: {verdict(median <= 1.1)})")
        client.close()
    finally:
        stop_all(children)


if __name__ == "__main__":
    try:
        main()
    except KeyboardInterrupt:
        raise SystemExit("interrupted; the launch and the polling clients were stopped") from None
