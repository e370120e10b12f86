"""Cartesian streaming on the in-process robot: servo_pose and speed_tool step the Cartesian servo and stream its
joint targets; the tool follows the asked line and the core keeps every limit.

The core's follower feeds forward the targets' velocity from the samples' stamps (the writer's clock), while a
stepped robot's cycles take no wall time: the samples are paced at 250 Hz of wall time and the robot steps the
cycles that passed. How closely the commanded tool keeps the line then depends on when the samples arrive, as on the
real-time loop, so here the streamed targets are judged against the line, and the commands against the limits and
the target they settle on; tests/e2e/test_cartesian_streaming_launched.py judges the commanded tool.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
import pinocchio as pin
import pytest

from plem.bridge.cartesian_streaming import CartesianStep
from plem.errors import CommandRejected
from plem.planning.poses import Pose
from plem.robot import Robot
from tests.integration.robot_fixtures import Trace, assert_within_limits, simulated_robot

SAMPLE_PERIOD_S = 0.004
#: An Indy7 pose with the elbow bent and the wrist turned down, far from singularities and limits.
START = [0.0, -0.4, -1.6, 0.0, -1.1, 0.0]
#: How far a streamed target's tool may leave the asked line (m, rad): the servo integrates the twist to first order,
#: 0.4 mm per sample at 0.1 m/s, which leaves the line by 0.24 mm over 8 cm on the Indy7 (measured): twice that.
LINE_TOLERANCE_M = 5e-4
ANGLE_TOLERANCE_RAD = 2e-3


@pytest.fixture
def robot() -> Robot:
    robot = simulated_robot()
    robot.set_mode("hold")
    robot.move_joints(START).wait(30.0)
    return robot


def paced(robot: Robot, calls: int, call: Callable[[int], CartesianStep],
          until: Callable[[list[CartesianStep]], bool] | None = None) -> list[CartesianStep]:
    """`calls` calls (fewer once `until(steps)`) at 250 Hz of wall time, the robot stepping as many cycles as wall
    time passed (4 a call on an idle machine): the loop's time keeps to the samples' stamps, as on the real-time
    loop."""
    steps: list[CartesianStep] = []
    began, cycles = time.monotonic(), 0
    for k in range(calls):
        steps.append(call(k))
        time.sleep(max(0.0, began + (k + 1) * SAMPLE_PERIOD_S - time.monotonic()))
        due = max(cycles + 1, round((time.monotonic() - began) / robot.runtime.dt))
        robot.step(due - cycles)
        cycles = due
        if until is not None and until(steps):
            break
    return steps


def tool_poses(robot: Robot, steps: list[CartesianStep]) -> list[pin.SE3]:
    """The tool's pose at each streamed target."""
    servo = robot._cartesian_streamer().servo
    return [servo.tool_pose(step.target) for step in steps]


def settled_on_last_target(robot: Robot, steps: list[CartesianStep], call: Callable[[int], CartesianStep]) -> None:
    """Calls that no longer move the target, held for 0.6 s: the arm settles on it; once they stop, the stream
    ends at rest there."""
    held = [call(k) for k in range(150) if robot.step(4) is None]
    assert np.allclose(held[-1].target, steps[-1].target, atol=1e-12)
    robot.step(300)
    state = robot.state()
    assert np.allclose(state.command_position, steps[-1].target, atol=1e-9)
    assert np.all(state.command_velocity == 0.0) and robot.fault_reason == ""


def off_line(poses: list[pin.SE3], start: pin.SE3, direction: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Each pose's distance along `direction` from `start`, its distance off that line, and the largest turn."""
    offsets = np.array([pose.translation - start.translation for pose in poses])
    along = offsets @ direction
    across = np.linalg.norm(offsets - np.outer(along, direction), axis=1)
    turn = max(float(np.linalg.norm(pin.log3(pose.rotation @ start.rotation.T))) for pose in poses)
    return along, across, turn


def test_a_base_frame_twist_moves_the_tool_along_its_line_within_every_limit(robot: Robot) -> None:
    start = robot._cartesian_streamer().servo.tool_pose(robot.state().command_position)
    trace = Trace.attach(robot)
    speed = 0.1
    still = [0.0] * 6
    steps = paced(robot, 300, lambda k: robot.speed_tool([speed, 0, 0, 0, 0, 0] if k < 200 else still))
    assert robot.servo_status().following and robot.servo_status().step is steps[-1]
    assert steps[100].scale == 1.0 and steps[100].reason == ""
    assert steps[0].reason == "acceleration" and steps[0].scale < 0.1   # the twist is reached gradually
    along, across, turn = off_line(tool_poses(robot, steps), start, np.array([1.0, 0.0, 0.0]))
    assert across.max() < LINE_TOLERANCE_M and turn < ANGLE_TOLERANCE_RAD
    distance = speed * sum(step.period_s for step in steps[:200])   # speeding up loses what slowing down adds
    assert 0.85 * distance < along[-1] < 1.15 * distance
    assert np.all(np.diff(along) > -1e-9)   # never backwards
    settled_on_last_target(robot, steps, lambda k: robot.speed_tool(still))
    assert_within_limits(robot, trace.commands())


def test_a_tool_frame_twist_moves_the_tool_along_its_own_axis(robot: Robot) -> None:
    start = robot._cartesian_streamer().servo.tool_pose(robot.state().command_position)
    trace = Trace.attach(robot)
    still = [0.0] * 6
    steps = paced(robot, 250, lambda k: robot.speed_tool([0, 0, 0.08, 0, 0, 0] if k < 175 else still, frame="tool"))
    along, across, turn = off_line(tool_poses(robot, steps), start, start.rotation[:, 2])
    assert across.max() < LINE_TOLERANCE_M and turn < ANGLE_TOLERANCE_RAD
    assert along[-1] > 0.04
    settled_on_last_target(robot, steps, lambda k: robot.speed_tool(still, frame="tool"))
    assert_within_limits(robot, trace.commands())


def test_servo_pose_brings_the_tool_to_the_pose(robot: Robot) -> None:
    servo = robot._cartesian_streamer().servo
    start = servo.tool_pose(robot.state().command_position)
    goal = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, 0.2) @ start.rotation, start.translation + [0.04, 0.03, -0.05])
    x, y, z, w = pin.Quaternion(goal.rotation).coeffs()
    pose = Pose(tuple(goal.translation), (x, y, z, w))
    trace = Trace.attach(robot)
    steps = paced(robot, 400, lambda k: robot.servo_pose(pose))
    settled_on_last_target(robot, steps, lambda k: robot.servo_pose(pose))
    reached = servo.tool_pose(robot.state().command_position)
    assert np.linalg.norm(reached.translation - goal.translation) < 1e-4
    assert np.linalg.norm(pin.log3(reached.rotation @ goal.rotation.T)) < 1e-3
    assert_within_limits(robot, trace.commands())


def test_streaming_toward_the_elbow_singularity_slows_to_a_stop_and_says_so(robot: Robot) -> None:
    trace = Trace.attach(robot)
    outward = [0.15, 0, 0, 0, 0, 0]   # the elbow straightens
    def stopped(steps: list[CartesianStep]) -> bool:   # the last 100 calls (0.4 s) stopped by the singularity
        return len(steps) > 200 and all(step.reason == "singularity" and step.scale < 0.01 for step in steps[-100:])

    # however much wall time each call takes on a busy machine (each moves the target by the time since the last)
    steps = paced(robot, 3000, lambda k: robot.speed_tool(outward), until=stopped)
    assert steps[100].scale > 0.95 and steps[100].singular_value > 0.1
    assert stopped(steps), [(step.reason, step.scale) for step in steps[-100:]]
    last = steps[-100:]
    servo = robot._cartesian_streamer().servo
    crawled = servo.tool_pose(last[-1].target).translation - servo.tool_pose(last[0].target).translation
    assert np.linalg.norm(crawled) < 1e-3   # under 1 mm in the last 0.4 s: stopped, short of straight
    assert min(step.singular_value for step in steps) >= 0.04 - 1e-3
    assert robot.servo_status().step is last[-1]
    servo = robot._cartesian_streamer().servo
    commanded = [servo.twist_step(q, np.zeros(6), 0.001).singular_value for q in trace.commands()[::10, 0]]
    assert min(commanded) > 0.03   # the commanded arm, following the targets, stopped near the servo's stop too
    robot.step(300)   # the stream ends: the arm comes to rest by the crawling target
    assert np.all(robot.state().command_velocity == 0.0) and robot.fault_reason == ""
    assert np.allclose(robot.state().command_position, steps[-1].target, atol=1e-3)
    assert_within_limits(robot, trace.commands())


def test_bad_twists_frames_and_poses_are_refused_before_anything_is_streamed(robot: Robot) -> None:
    with pytest.raises(CommandRejected, match="twist has 5 values"):
        robot.speed_tool([0.1, 0, 0, 0, 0])
    with pytest.raises(CommandRejected, match="finite"):
        robot.speed_tool([float("nan"), 0, 0, 0, 0, 0])
    with pytest.raises(CommandRejected, match="twist frame") as refused:
        robot.speed_tool([0.1, 0, 0, 0, 0, 0], frame="world")
    assert "frame='base'" in refused.value.how
    with pytest.raises(CommandRejected, match="x y z"):
        robot.servo_pose([0.3, 0.1])
    with pytest.raises(CommandRejected, match="stream timeout"):
        robot.speed_tool([0.1, 0, 0, 0, 0, 0], timeout=0.0)
    assert robot._stream is None and robot.servo_status().step is None


def test_a_cartesian_step_starts_from_the_last_target_streamed_while_the_stream_runs(robot: Robot) -> None:
    target = np.array(START) + [0.2, 0.0, 0.0, 0.0, 0.0, 0.0]
    robot.servo_joints(target)
    robot.step(4)
    lagging = robot.state().command_position
    assert np.abs(lagging - target).max() > 0.1   # the arm is far from the joint target still
    step = robot.speed_tool([0.05, 0, 0, 0, 0, 0])
    assert np.abs(step.target - target).max() < 1e-3   # one cycle's step from the joint target, not from the arm
    robot.step(300)   # the stream ends: the next step starts from the arm, at rest where it stopped
    at_rest = robot.state().command_position
    step = robot.speed_tool([0.05, 0, 0, 0, 0, 0])
    assert np.abs(step.target - at_rest).max() < 1e-3 and step.period_s == robot.runtime.dt
