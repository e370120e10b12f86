"""The RT driver's shared memory, served in this process: rt_raw every cycle, events, statistics, replies."""

from __future__ import annotations

import json
import subprocess
import sys
import threading
import uuid

import numpy as np
import pytest

from plem.bridge import connect
from plem.control.events import EventKind
from plem.control.modes import Mode
from plem.ipc.channels import channel_names
from plem.ipc.segment import segment_path
from plem.launch.driver_service import DriverService
from plem.launch.plan import plan_robot
from plem.launch.rt_driver import serve


@pytest.fixture
def served():
    """A driver serving a simulated arm from a thread (the loop without real-time priority)."""
    robot_id = f"drv_{uuid.uuid4().hex[:8]}"
    plan = plan_robot({"bus": "mock", "robot_id": robot_id}, generate=False)
    stop, ready = threading.Event(), threading.Event()
    announced: list[dict] = []
    thread = threading.Thread(target=serve, args=(plan, stop, lambda a: (announced.append(a), ready.set())))
    thread.start()
    assert ready.wait(30), "the driver did not announce itself"
    yield robot_id, announced[0]
    stop.set()
    thread.join(30)
    assert not thread.is_alive()
    for name in channel_names(robot_id).values():
        assert not segment_path(name).exists(), f"{name} left behind"


def test_every_cycle_reaches_the_stream_in_order(served):
    robot_id, announcement = served
    assert announcement["ready"] and announcement["shared_memory"]["state"] == f"/{robot_id}_joint_actual_values"
    with connect(robot_id, expected_dof=6) as client:
        stream = client.stream(timeout=2.0)
        samples = [next(stream) for _ in range(500)]
        cycles = np.array([s.cycle for s in samples])
        assert np.array_equal(np.diff(cycles), np.ones(499)), "a cycle is missing or out of order"
        assert stream.dropped == 0
        assert all(s.latency_ns >= 0 for s in samples) and any(s.compute_ns > 0 for s in samples)
        state = client.state()
        assert state.cycle >= samples[-1].cycle and state.mode is Mode.HOLD  # bus:=mock starts enabled


def test_a_motion_is_answered_and_shows_in_events_and_stats(served):
    robot_id, _ = served
    with connect(robot_id) as client:
        events = client.events(timeout=0.5)
        assert client.set_mode("hold") is Mode.HOLD
        target = [0.1, -0.1, 0.2, 0.0, 0.1, 0.0]
        result = client.move_joints(target).wait(20)
        assert result.outcome.value == "succeeded"
        assert np.allclose(client.state().position, target, atol=1e-3)
        kinds = [event.kind for event in events]
        assert EventKind.MOTION_STARTED in kinds and EventKind.MOTION_FINISHED in kinds
        client.wait_for_state(1.0, after_cycle=client.state().cycle + 150)  # the next statistics record
        stats = client.stats()
        # the arm holds already: the command service answers the mode request itself, the motion reaches the driver
        commands = stats["commands"]
        assert commands["answered_here"] >= 1 and commands["accepted"] >= 1 and commands["rejected"] == 0
        assert stats["latency_interval"]["samples"] > 0 and stats["cycles"] > 0


def test_a_second_driver_process_for_the_same_robot_is_refused(served):
    robot_id, _ = served
    result = subprocess.run([sys.executable, "-m", "plem.launch.rt_driver",
                             json.dumps({"bus": "mock", "robot_id": robot_id})],
                            capture_output=True, text=True, timeout=60)
    announcement = json.loads(result.stdout.splitlines()[-1])
    assert result.returncode == 1 and announcement["ready"] is False
    assert "already has a running RT driver" in announcement["error"]["summary"]
    with connect(robot_id) as client:  # the first one is untouched
        assert client.wait_for_state(1.0, after_cycle=client.state().cycle + 10) is not None


@pytest.mark.filterwarnings("ignore::pytest.PytestUnhandledThreadExceptionWarning")
def test_a_dead_service_thread_stops_the_arm_smoothly_and_ends_the_driver(monkeypatch):
    """The driver must not run on deaf: if its service thread dies, it stops the arm and says why."""
    robot_id = f"drv_{uuid.uuid4().hex[:8]}"
    plan = plan_robot({"bus": "mock", "robot_id": robot_id}, generate=False)
    stop, ready = threading.Event(), threading.Event()
    outcome: list[BaseException] = []

    def serving() -> None:
        try:
            serve(plan, stop, lambda _: ready.set())
        except BaseException as error:  # noqa: BLE001 - the test inspects what serve() ended with
            outcome.append(error)

    def dying(self, command, token):
        if command["op"] == "stop":
            raise SystemExit("service thread ends")   # not an Exception: it escapes the per-record guard
        return original(self, command, token)

    original = DriverService._dispatch
    monkeypatch.setattr(DriverService, "_dispatch", dying)
    thread = threading.Thread(target=serving)
    thread.start()
    try:
        assert ready.wait(30)
        with connect(robot_id) as client:
            events = client.events(timeout=0)
            client.set_mode("hold")
            target = client.state().position + 0.3
            client.move_joints(target, speed_scale=0.1)
            client.stop()
            thread.join(30)
            seen = list(events)
    finally:
        stop.set()
        thread.join(30)
    assert outcome and "service thread stopped" in str(outcome[0].summary)
    modes = [(event.previous_mode, event.mode) for event in seen if event.kind is EventKind.MODE_CHANGED]
    assert modes[-1] == (Mode.HOLD, Mode.IDLE), modes
    assert not [event for event in seen if event.kind is EventKind.FAULT]
    for name in channel_names(robot_id).values():
        assert not segment_path(name).exists(), f"{name} left behind"
