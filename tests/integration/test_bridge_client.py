"""The bridge client and `plem state|reset` against an RT driver served in this process, whose bus a test can fault."""

from __future__ import annotations

import json
import time
import uuid
from collections.abc import Iterator

import numpy as np
import pytest

from plem.bridge import connect
from plem.bridge.client import RobotClient
from plem.control.events import EventKind
from plem.control.modes import Mode
from plem.control.trajectory import ErrorCode, TrajectoryOutcome
from plem.errors import CommandRejected
from plem.launch.plan import plan_robot
from plem.launch.rt_driver import driving
from plem.robot import Robot
from tests.e2e.cli import run_plem
from tests.e2e.launched import wait_until


@pytest.fixture
def driver() -> Iterator[tuple[str, Robot]]:
    """A simulated arm's RT driver, with its command service, holding."""
    robot_id = f"cli_{uuid.uuid4().hex[:8]}"
    plan = plan_robot({"bus": "mock", "robot_id": robot_id}, generate=False)
    with driving(plan) as running, connect(robot_id) as client:
        client.set_mode("hold")
        yield robot_id, running.robot


def fault_the_drive(robot: Robot, client: RobotClient, joint: int) -> None:
    """Fault a drive and wait for the arm's fault and its worded event (the event follows the state by a
    millisecond: the core reports a code, the driver's service thread words it)."""
    robot.bus.inject_drive_fault(joint, 0x7121)
    assert wait_until(lambda: client.state().faulted and client.last_fault() is not None, 10)


def plem_state(robot_id: str, *args: str) -> str:
    result = run_plem("state", "--robot-id", robot_id, *args)
    assert result.returncode == 0, result.stderr
    return result.stdout


def test_state_shows_the_fault_as_the_driver_reports_it_and_reset_says_what_it_did(driver):
    robot_id, robot = driver
    with connect(robot_id) as client:
        nothing = run_plem("reset", "--robot-id", robot_id)
        assert nothing.returncode == 0, nothing.stderr
        assert nothing.stdout.strip() == f"{robot_id}: no fault to clear; mode hold"
        assert "fault" not in plem_state(robot_id).replace("no fault", "")

        fault_the_drive(robot, client, 2)
        fault = client.last_fault()
        assert fault is not None and fault == robot.events.last_fault()
        assert fault.kind is EventKind.FAULT and fault.cause == "drive_fault" and "0x7121 motor blocked" in fault.reason
        assert f"fault at cycle {fault.cycle} (drive_fault): {fault.reason}" in plem_state(robot_id)
        shown = json.loads(plem_state(robot_id, "--format", "json"))
        assert shown["mode"] == "fault" and shown["faulted"]
        assert shown["last_fault"] == {"active": True, "cycle": fault.cycle, "cause": "drive_fault",
                                       "reason": fault.reason, "wall_time": fault.wall_time}

        cleared = run_plem("reset", "--robot-id", robot_id)
        assert cleared.returncode == 0, cleared.stderr
        assert cleared.stdout.strip() == f"{robot_id}: fault cleared (drive_fault: {fault.reason}), mode hold"
        assert f"last fault (cleared) at cycle {fault.cycle} (drive_fault): {fault.reason}" in plem_state(robot_id)
        assert [event.kind for event in client.faults()] == [EventKind.FAULT, EventKind.FAULT_CLEARED]
        assert json.loads(plem_state(robot_id, "--format", "json"))["last_fault"]["active"] is False


def test_the_newest_fault_outlives_a_flood_of_other_events(driver):
    robot_id, robot = driver
    with connect(robot_id) as client:
        fault_the_drive(robot, client, 1)
        fault = client.last_fault()
        slots = client.channels.rings["events"].slots
        refused = [robot.request_mode(Mode.HOLD) for _ in range(slots + 10)]  # each one a command_rejected event
        for handle in refused:
            with pytest.raises(CommandRejected):
                handle.wait(10)
        kept = list(client.events(timeout=0, from_oldest=True))
        assert len(kept) == slots and {event.kind for event in kept} == {EventKind.COMMAND_REJECTED}
        assert client.last_fault() == fault
        assert f"fault at cycle {fault.cycle} (drive_fault): {fault.reason}" in plem_state(robot_id)


def test_results_have_the_types_the_in_process_robot_returns(driver):
    robot_id, robot = driver
    with connect(robot_id) as client:
        start = client.state().position
        away = start.copy()
        away[0] += 0.3 if away[0] < 0 else -0.3
        slow = client.move_joints(away, speed_scale=0.1)
        back = client.move_joints(start, speed_scale=1.0)
        preempted = slow.wait(30)
        assert preempted.outcome is TrajectoryOutcome.PREEMPTED and preempted.error_code is ErrorCode.INVALID_GOAL
        reached = back.wait(30)
        assert reached.outcome is TrajectoryOutcome.SUCCEEDED and reached.error_code is ErrorCode.SUCCESSFUL
        in_process = robot.move_joints(start).wait(30)
        assert type(reached.error_code) is type(in_process.error_code) is ErrorCode
        assert client.set_mode("hold") is Mode.HOLD


def test_mode_prints_its_name_as_the_in_process_robot_shows_it(driver):
    robot_id, robot = driver
    with connect(robot_id) as client:
        remote, local = client.state().mode, robot.state().mode
        assert remote is local is Mode.HOLD
        assert str(remote) == f"{remote}" == str(local) == "hold"


def test_a_stream_with_a_duration_ends_after_the_cycles_of_that_time(driver):
    robot_id, _ = driver
    with connect(robot_id) as client:
        before = time.monotonic_ns()
        stream = client.stream(duration=0.3)
        after = time.monotonic_ns()
        samples = list(stream)
        ended = time.monotonic_ns()
        stamps = np.array([sample.monotonic_ns for sample in samples])
        assert len(samples) > 1 and stream.dropped == 0
        assert np.all(np.diff([sample.cycle for sample in samples]) == 1)
        assert stamps[0] >= before and stamps[-1] <= after + 300_000_000
        assert ended >= before + 300_000_000, "the stream ran for its whole duration"
        assert list(client.events(duration=0.2)) == []  # nothing happens while holding: it ends all the same
