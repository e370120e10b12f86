"""The compiled core's own real-time thread: it cycles without the interpreter, and stops and restarts cleanly."""

from __future__ import annotations

import ctypes
import threading

import numpy as np

from plem.control.commands import CommandHandle
from plem.control.compiled import CONSTANTS as C
from plem.control.core_thread import CoreThread
from plem.control.events import EventKind
from plem.control.modes import Mode
from plem.control.runtime import MAX_UNANSWERED
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


def test_every_request_is_answered_when_answers_are_read_late():
    """The core drops answers that find its outcome ring full: while the answers wait unread (a busy machine
    delays the thread that reads them), requests beyond what the ring holds wait to be sent instead of losing
    their answers."""
    robot = simulated_robot()
    requests = C["PLEM_OUTCOME_SLOTS"] + 2 * C["PLEM_COMMAND_SLOTS"]
    with robot:
        robot.set_mode(Mode.HOLD)
        runtime = robot.runtime
        reading, drain = threading.Event(), runtime.drain
        runtime.drain = lambda: reading.wait() and drain()   # type: ignore[method-assign]  # answers held unread
        handles: list[CommandHandle] = []
        sender = threading.Thread(target=lambda: handles.extend(robot.request_mode(Mode.HOLD)
                                                                for _ in range(requests)))
        sender.start()
        commands, _ = runtime._rings["commands"]
        while not (len(handles) == requests or runtime._pending and len(runtime._pending) >= MAX_UNANSWERED):
            reading.wait(0.001)
        while int(commands["tail"]) != int(commands["head"]):   # the core has taken every request sent so far
            reading.wait(0.001)
        reading.set()
        sender.join()
        assert [handle.wait(10) for handle in handles] == [Mode.HOLD] * requests
