"""The motion API's per-cycle figures: servo_joints command-to-motion latency, reaction latency from a simulated
contact, and the core's compute time with reactions and a stream, each against a baseline from the same run.

Usage: python benchmarks/motion_api.py [--pairs 15] [--quick] [--only latency,reaction,compute] [--unpinned]
Needs root for SCHED_FIFO (as `plem launch` on a real machine). Windows alternate which side goes first.

latency   One `plem launch bus:=mock robot_id:=bench_api_<hex> bridge:=false record:=false` (Indy7 v2, 1 kHz,
          SCHED_FIFO 98), driven from this process through `plem.bridge.connect`. A stream window writes 200
          `servo_joints` samples about 1 ms apart (a small sine on every joint) and, after each, waits until the core
          reports it used it: the core's own figure is the time from the sample's stamp (taken as it is written) to
          the cycle that first used it. The baseline window sends 20 small `move_joints` through the command
          service, the way plem took commands before streaming, and times each from the call to its acceptance
          (the cycle that started it). Figures in cycles of 1 ms; per pair the stream's p99 and the ratio of medians,
          stream / baseline. Target: stream p99 <= 2 cycles (the median over the pairs).
reaction  An in-process Indy7 v2 on MockBus with dynamics, its core on its own thread at 1 kHz, SCHED_FIFO 98, during
          a slow motion. The simulator pushes the flange with 40 N along x; a reaction FORCE_X > 20 → Stop() ends
          the motion from the core. The baseline is the same condition in a Python thread that polls the core's
          estimate as fast as it can and calls stop(). On both sides a Record reaction on the same condition marks
          the cycle that first measured it; the figure is the cycles from there to the cycle that ended the motion
          (the motion-finished event's). Also printed: cycles from the push to that measurement, the physical
          delay while the simulated servo takes up the force. Target: in-core <= 1 cycle.
compute   The same in-process robot. The measured window: 8 standing reactions of 3 comparisons each (none fires)
          and a `servo_joints` stream at 500 Hz; the baseline window: the arm holding with no reaction and no
          stream, while the calling thread does the same Python work (it checks the same samples and writes them
          into a stream block no core reads), so both windows share what a busy caller does to the core's caches
          on two CPUs. As a real-time setup has it (docs/ethercat.md), the core's thread runs on the last CPU and
          this process's threads on the others (--unpinned: any CPU, as the scheduler moves them). The core's own
          compute time per cycle, each cycle's exact figure in ns (from the core's window of raw samples: its 1 µs
          histogram cannot resolve a ratio of a few-µs cycle), the simulated arm's dynamics included on both sides;
          p99 per window. Target: median ratio <= 1.2.
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from plem.bridge import connect
from plem.control.events import EventKind
from plem.control.modes import Mode
from plem.control.reactions import Measure, Record, Stop
from plem.control.streaming import StreamBlock
from plem.fieldbus.mock import MockBus
from plem.robot import Indy7V2, Robot

import launching

PRIORITY = 98
CYCLE_NS = 1_000_000


def spread(values: list[float]) -> str:
    return f"{statistics.median(values):.2f} ({min(values):.2f}-{max(values):.2f})"


# -- latency -----------------------------------------------------------------------------------------------------------
def stream_window(client, start: np.ndarray, samples: int) -> list[float]:
    """Core-reported latency (cycles) of each of `samples` servo_joints samples."""
    cycles = []
    for k in range(samples):
        target = start + 0.02 * np.sin(k * 0.03)
        count = client.servo_joints(target, timeout=0.2)
        deadline = time.monotonic() + 0.05
        while (status := client.stream_status()).used_count < count and time.monotonic() < deadline:
            time.sleep(0.0001)
        if status.used_count >= count:
            cycles.append(status.latency_ns / CYCLE_NS)
        time.sleep(0.001)
    client.stop().wait(5.0)
    while client.live_state().mode is Mode.TRAJECTORY:
        time.sleep(0.01)
    return cycles


def command_window(client, start: np.ndarray, moves: int) -> list[float]:
    """Time (cycles) from a move_joints call to its acceptance by the core."""
    cycles = []
    for k in range(moves):
        began = time.monotonic_ns()
        handle = client.move_joints(start + (0.01 if k % 2 else 0.0), speed_scale=1.0)
        cycles.append((time.monotonic_ns() - began) / CYCLE_NS)
        handle.wait(10.0)
    return cycles


def measure_latency(pairs: int, samples: int, moves: int) -> bool:
    robot_id = f"bench_api_{os.urandom(3).hex()}"
    children: list = []
    env = dict(os.environ)
    rows = []
    with tempfile.TemporaryDirectory() as directory:
        try:
            launching.launch(robot_id, env, Path(directory) / "launch.log", children, bridge=False, record=False)
            client = connect(robot_id)
            launching.first_sample(client, 1.0)
            client.set_mode("hold")
            start = client.live_state().command_position.copy()
            for pair in range(pairs):
                order = ("stream", "command") if pair % 2 == 0 else ("command", "stream")
                got = {side: (stream_window(client, start, samples) if side == "stream"
                              else command_window(client, start, moves)) for side in order}
                rows.append(got)
                print(f"pair {pair + 1:2d}: stream p50 {np.median(got['stream']):.2f} p99 "
                      f"{np.percentile(got['stream'], 99):.2f} max {max(got['stream']):.2f} cycles | move_joints p50 "
                      f"{np.median(got['command']):.2f} p99 {np.percentile(got['command'], 99):.2f} cycles", flush=True)
            client.close()
        finally:
            launching.stop_all(children)
    stream = np.concatenate([r["stream"] for r in rows])
    command = np.concatenate([r["command"] for r in rows])
    ratios = [float(np.median(r["stream"]) / np.median(r["command"])) for r in rows]
    p99 = [float(np.percentile(r["stream"], 99)) for r in rows]
    met = statistics.median(p99) <= 2.0
    print(f"\nservo_joints command-to-motion p99 per pair: median {spread(p99)} cycles of 1 ms")
    print(f"all {len(stream)} samples pooled: p50 {np.median(stream):.2f}, p99 {np.percentile(stream, 99):.2f}, "
          f"max {stream.max():.2f} cycles")
    print(f"baseline move_joints call-to-acceptance, {len(command)} commands: p50 {np.median(command):.2f}, p99 "
          f"{np.percentile(command, 99):.2f} cycles")
    print(f"ratio of medians stream / baseline per pair: {spread(ratios)}")
    print(f"target (stream p99 <= 2 cycles, median over the pairs): {launching.verdict(met)}")
    return met


# -- an in-process robot on its real-time thread -----------------------------------------------------------------------
def started_robot(cpus: tuple[int, ...] | None = None) -> Robot:
    """The in-process Indy7 v2 on MockBus, holding; its core thread on `cpus` when given."""
    config = Indy7V2(rt_priority=PRIORITY)
    config.custom_bus = MockBus(config.dof)
    robot = Robot.builder(config).with_loop_settings(cpus=cpus).build()
    robot.start()
    robot.set_mode("hold")
    return robot


def first_event(robot: Robot, kind: EventKind, after_cycle: int, timeout: float):
    """The first event of `kind` at or after `after_cycle`, waiting up to `timeout`."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        found = [event for event in robot.events.recent({kind}) if event.cycle >= after_cycle]
        if found:
            return found[0]
        time.sleep(0.001)
    return None


def reaction_trial(robot: Robot, in_core: bool) -> tuple[float, float]:
    """Cycles from the cycle that first measured FORCE_X > 20 N (a Record reaction marks it) to the cycle that ended
    the motion, by an in-core Stop reaction or by a Python thread that polls and stops; and cycles from the push to
    that first measurement (the physical delay, the same on both sides)."""
    start = robot.state().position.copy()
    armed = [robot.on(Measure.FORCE_X > 20.0, Record(), once=True)]
    if in_core:
        armed.append(robot.on(Measure.FORCE_X > 20.0, Stop(), once=True))
    handle = robot.move_joints(start + np.where(start > 0, -0.6, 0.6), speed_scale=0.2)
    time.sleep(0.3)
    stop = threading.Event()
    poller = None if in_core else threading.Thread(target=poll_and_stop, args=(robot, stop), daemon=True)
    if poller is not None:
        poller.start()
    cycle = robot.runtime.cycle_count
    robot.simulator.push("link6", force=(40.0, 0.0, 0.0))
    measured = first_event(robot, EventKind.REACTION, cycle, 5.0)
    ended = first_event(robot, EventKind.MOTION_FINISHED, cycle, 5.0)
    robot.simulator.release()
    stop.set()
    if poller is not None:
        poller.join()
    if not handle.done:
        handle.wait(10.0)
    for reaction in armed:
        reaction.remove()
    time.sleep(0.5)
    robot.move_joints(start.tolist()).wait(30.0)
    if measured is None or ended is None:
        return float("nan"), float("nan")
    return float(ended.cycle - measured.cycle), float(measured.cycle - cycle)


def poll_and_stop(robot: Robot, stop: threading.Event) -> None:
    """What a user does without in-core reactions: watch the estimate from Python and stop."""
    while not stop.is_set():
        if robot.stream_status().wrench[0] > 20.0:
            robot.stop()
            return


def measure_reaction(pairs: int) -> bool:
    robot = started_robot()
    rows = []
    try:
        for pair in range(pairs):
            order = (True, False) if pair % 2 == 0 else (False, True)
            got = {side: reaction_trial(robot, side) for side in order}
            rows.append(got)
            print(f"pair {pair + 1:2d}: condition to action, in-core {got[True][0]:.0f} cycles | Python poller "
                  f"{got[False][0]:.0f} cycles | push to condition {got[True][1]:.0f} / {got[False][1]:.0f} cycles",
                  flush=True)
    finally:
        robot.shutdown()
    core = [r[True][0] for r in rows]
    python = [r[False][0] for r in rows]
    physical = [r[side][1] for r in rows for side in (True, False)]
    print(f"\nfrom the cycle that measured the condition to the cycle that ended the motion: in-core median "
          f"{spread(core)} cycles, Python poller median {spread(python)} cycles")
    print(f"from the push to the cycle that measured it (the servo taking up the force): median {spread(physical)}")
    met = max(core) <= 1.0
    print(f"target (in-core reaction <= 1 cycle, every trial): {launching.verdict(met)}")
    return met


# -- compute -----------------------------------------------------------------------------------------------------------
def compute_window(robot: Robot, seconds: float, busy: bool) -> np.ndarray:
    """The core's compute time (µs) of each cycle of a window, with 8 reactions and a stream when `busy`."""
    reactions = []
    if busy:
        for joint in range(6):
            reactions.append(robot.on((Measure.external_torque(joint) > 1000.0) | (Measure.position(joint) > 100.0)
                                      | (Measure.following_error(joint) > 10.0), Record()))
        reactions.append(robot.on((Measure.FORCE_Z > 1e4) & (Measure.MOTION_TIME > 0.0), Record()))
        reactions.append(robot.on((Measure.TORQUE_X > 1e4) | ~(Measure.velocity(0) < 100.0), Record()))
    start = robot.state().position.copy()
    series = robot.loop.stats.compute
    began = series.count
    end = time.monotonic() + seconds
    k = 0
    idle = StreamBlock.private(robot.limits.dof)   # the baseline writes the same samples where no core reads them
    while time.monotonic() < end:
        target = start + 0.01 * np.sin(k * 0.02)
        if busy:
            robot.servo_joints(target, timeout=0.2)
        else:
            robot._joint_values(target, "positions")
            idle.write(1, "position", target)
        k += 1
        time.sleep(0.002)
    finished = series.count
    samples = series.window[np.arange(began, finished) % series.window.size] / 1e3
    for reaction in reactions:
        reaction.remove()
    if busy:
        robot.stop().wait(5.0)
        wait_until(lambda: robot.mode is Mode.HOLD, 5.0)
    if finished - began > series.window.size:
        raise SystemExit(f"a window of {finished - began} cycles outgrew the core's {series.window.size} raw samples")
    return samples


def wait_until(condition: Callable[[], bool], timeout: float) -> None:
    deadline = time.monotonic() + timeout
    while not condition() and time.monotonic() < deadline:
        time.sleep(0.005)


def measure_compute(pairs: int, seconds: float, pinned: bool) -> bool:
    everywhere = os.sched_getaffinity(0)
    core_cpu = max(everywhere)
    pinned = pinned and len(everywhere) > 1
    if pinned:   # the real-time setup (docs/ethercat.md): the core on a CPU of its own, the rest elsewhere
        os.sched_setaffinity(0, everywhere - {core_cpu})   # this thread, and the robot's threads it starts
    print(f"core thread on CPU {core_cpu}, this process's other threads on {sorted(everywhere - {core_cpu})}"
          if pinned else "core thread and this process on any CPU")
    robot = started_robot((core_cpu,) if pinned else None)
    rows = []
    try:
        for pair in range(pairs):
            order = (True, False) if pair % 2 == 0 else (False, True)
            got = {busy: compute_window(robot, seconds, busy) for busy in order}
            rows.append({busy: (float(np.percentile(v, 99)), float(v.mean())) for busy, v in got.items()})
            print(f"pair {pair + 1:2d}: compute p99 with 8 reactions and a stream {rows[-1][True][0]:.2f} µs (mean "
                  f"{rows[-1][True][1]:.2f}) | holding {rows[-1][False][0]:.2f} µs (mean {rows[-1][False][1]:.2f}) | "
                  f"ratio {rows[-1][True][0] / rows[-1][False][0]:.2f}", flush=True)
    finally:
        robot.shutdown()
        os.sched_setaffinity(0, everywhere)
    ratios = [r[True][0] / r[False][0] for r in rows]
    met = statistics.median(ratios) <= 1.2
    print(f"\ncompute p99 with 8 reactions and a stream / holding: median {spread(ratios)}; µs medians "
          f"{statistics.median(r[True][0] for r in rows):.2f} / {statistics.median(r[False][0] for r in rows):.2f}; "
          f"mean µs medians {statistics.median(r[True][1] for r in rows):.2f} / "
          f"{statistics.median(r[False][1] for r in rows):.2f}")
    print(f"target (median ratio <= 1.2): {launching.verdict(met)}")
    return met


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=15)
    parser.add_argument("--quick", action="store_true", help="3 pairs, shorter windows")
    parser.add_argument("--only", default="latency,reaction,compute")
    parser.add_argument("--unpinned", action="store_true",
                        help="compute: leave the core thread and this process on any CPU (the scheduler moves them)")
    options = parser.parse_args()
    pairs = 3 if options.quick else options.pairs
    print(f"# motion API: {launching.begin_run()}")
    parts = options.only.split(",")
    met = True
    if "latency" in parts:
        print("\n## servo_joints command-to-motion latency")
        met &= measure_latency(pairs, 60 if options.quick else 200, 6 if options.quick else 20)
    if "reaction" in parts:
        print("\n## reaction latency from a simulated contact")
        met &= measure_reaction(pairs)
    if "compute" in parts:
        print("\n## core compute with 8 standing reactions and a stream")
        met &= measure_compute(pairs, 1.0 if options.quick else 2.0, not options.unpinned)
    return 0 if met else 1


if __name__ == "__main__":
    raise SystemExit(main())
