"""The compiled core's own real-time thread: it cycles without the interpreter, and stops and restarts cleanly."""

from __future__ import annotations

import ctypes
import threading

import numpy as np

from plem.control.core_thread import CoreThread
from plem.control.events import EventKind
from plem.control.modes import Mode
from plem.control.trajectory import TrajectoryOutcome
from tests.integration.robot_fixtures import simulated_robot

HOLD_LOCK_US = 300_000


def test_the_loop_cycles_on_while_one_c_call_holds_the_interpreter_lock():
    robot = simulated_robot()
    assert isinstance(robot.loop, CoreThread)
    with robot:
        robot.set_mode(Mode.HOLD)
        before = robot.state()
        ctypes.PyDLL(None).usleep(HOLD_LOCK_US)   # a PyDLL call keeps the interpreter lock for its whole length
        after = robot.state()
        held_ns = after.monotonic_ns - before.monotonic_ns          # the loop's own clock
        due = held_ns / (robot.runtime.dt * 1e9)
        assert held_ns >= HOLD_LOCK_US * 1e3 * 0.9
        assert after.cycle - before.cycle >= due / 2, (after.cycle - before.cycle, due)
        assert robot.mode is Mode.HOLD
        assert not [e for e in robot.events.recent() if e.kind is EventKind.FAULT]


def test_a_busy_python_thread_beside_the_loop_costs_it_no_cycle():
    robot = simulated_robot()
    stop = threading.Event()

    def busy() -> None:
        while not stop.is_set():
            sum(range(10_000))

    with robot:
        robot.set_mode(Mode.HOLD)
        worker = threading.Thread(target=busy)
        worker.start()
        try:
            before = robot.state()
            result = robot.move_joints(np.array([0.3, -0.3, 0.3, 0.2, -0.2, 0.2]), speed_scale=0.5).wait(30)
            after = robot.state()
        finally:
            stop.set()
            worker.join()
        assert result.outcome is TrajectoryOutcome.SUCCEEDED
        due = (after.monotonic_ns - before.monotonic_ns) / (robot.runtime.dt * 1e9)
        assert after.cycle - before.cycle >= due / 2, (after.cycle - before.cycle, due)
        assert not [e for e in robot.events.recent() if e.kind is EventKind.FAULT]


def test_the_thread_stops_on_shutdown_and_the_arm_ends_disabled():
    robot = simulated_robot()
    robot.start()
    robot.set_mode(Mode.HOLD)
    assert robot.running and robot.runtime.thread_running
    robot.shutdown()
    assert not robot.running and not robot.runtime.thread_running
    assert robot.mode is Mode.IDLE
