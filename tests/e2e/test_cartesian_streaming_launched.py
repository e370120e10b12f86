"""Cartesian streaming through the process client against `plem launch bus:=mock`: the commanded tool (forward
kinematics of the rt_raw command positions the RT driver wrote, cycle by cycle) follows the asked line or pose,
stops short of the elbow's singularity, and every limit holds."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator

import numpy as np
import pinocchio as pin
import pytest

from plem.bridge.cartesian_streaming import CartesianStep
from plem.bridge.client import RobotClient
from plem.control.cartesian_servo import CartesianServo
from plem.planning.poses import Pose
from tests.e2e.launched import Launch, launched_robot
from tests.e2e.test_streaming_launched import SAMPLE_PERIOD_S, Recorder, within_limits

#: An Indy7 pose with the elbow bent and the wrist turned down, far from singularities and limits.
START = [0.0, -0.4, -1.6, 0.0, -1.1, 0.0]
#: How far the commanded tool may leave the asked line (m, rad): each joint's jerk-limited follower lags its
#: targets by its own amount while the twist changes speed and as samples arrive unevenly; measured 0.8 to 1.5 mm
#: and 3 to 6 mrad at 0.1 m/s on a loaded two-core machine (the targets themselves within 0.25 mm): twice that.
LINE_TOLERANCE_M = 0.003
ANGLE_TOLERANCE_RAD = 0.012


@pytest.fixture(scope="module")
def robot(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Launch]:
    with launched_robot(tmp_path_factory, "bridge:=false", "record:=false") as launch:
        yield launch


@pytest.fixture
def arm(client: RobotClient) -> RobotClient:
    """The client, its arm at START and at rest."""
    client.set_mode("hold")
    client.move_joints(START).wait(30.0)
    return client


def paced(client: RobotClient, calls: int, call: Callable[[int], CartesianStep]) -> list[CartesianStep]:
    """`calls` calls at 250 Hz."""
    steps = []
    began = time.monotonic()
    for k in range(calls):
        steps.append(call(k))
        time.sleep(max(0.0, began + (k + 1) * SAMPLE_PERIOD_S - time.monotonic()))
    return steps


def servo_of(client: RobotClient) -> CartesianServo:
    return client._cartesian_streamer().servo


def commanded_poses(client: RobotClient, commands: np.ndarray) -> list[pin.SE3]:
    servo = servo_of(client)
    return [servo.tool_pose(q) for q in commands[:, 0]]


def within_position_limits(client: RobotClient, commands: np.ndarray) -> None:
    assert np.all(commands[:, 0] >= client.limits.min_position) and np.all(commands[:, 0] <= client.limits.max_position)


def follow_line(client: RobotClient, twist: list[float], frame: str,
                direction: Callable[[pin.SE3], np.ndarray]) -> None:
    """Stream `twist` for 200 calls then a stop for 100; the commanded tool stays on the line from where it was at
    rest and covers about the twist's distance over the time its calls covered (speeding up loses about what
    slowing down adds)."""
    recorder = Recorder(client)
    stop = [0.0] * 6
    steps = paced(client, 300, lambda k: client.speed_tool(twist if k < 200 else stop, frame=frame))
    commands = recorder.stop()
    start = servo_of(client).tool_pose(commands[0, 0])
    axis = direction(start)
    poses = commanded_poses(client, commands)
    offsets = np.array([pose.translation - start.translation for pose in poses])
    along = offsets @ axis
    across = np.linalg.norm(offsets - np.outer(along, axis), axis=1)
    turn = max(float(np.linalg.norm(pin.log3(pose.rotation @ start.rotation.T))) for pose in poses)
    assert across.max() < LINE_TOLERANCE_M and turn < ANGLE_TOLERANCE_RAD, (across.max(), turn)
    distance = float(np.linalg.norm(twist[:3])) * sum(step.period_s for step in steps[:200])
    assert 0.85 * distance < along[-1] < 1.15 * distance, (along[-1], distance)
    within_limits(client, commands)
    within_position_limits(client, commands)
    assert client.last_fault() is None


def test_a_base_frame_twist_moves_the_commanded_tool_along_x(arm: RobotClient) -> None:
    follow_line(arm, [0.1, 0, 0, 0, 0, 0], "base", lambda start: np.array([1.0, 0.0, 0.0]))


def test_a_tool_frame_twist_moves_the_commanded_tool_along_its_own_z(arm: RobotClient) -> None:
    follow_line(arm, [0, 0, 0.08, 0, 0, 0], "tool", lambda start: start.rotation[:, 2])


def test_servo_pose_brings_the_commanded_tool_to_the_pose(arm: RobotClient) -> None:
    arm.speed_tool([0.0] * 6)   # builds the kinematics from the launch's URDF
    servo = servo_of(arm)
    start = servo.tool_pose(arm.live_state().command_position)
    goal = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, 0.2) @ start.rotation, start.translation + [0.04, 0.03, -0.05])
    x, y, z, w = pin.Quaternion(goal.rotation).coeffs()
    pose = Pose(tuple(goal.translation), (x, y, z, w))
    recorder = Recorder(arm)
    paced(arm, 400, lambda k: arm.servo_pose(pose))
    time.sleep(0.3)   # the stream times out; the arm is at rest
    commands = recorder.stop()
    reached = servo.tool_pose(commands[-1, 0])
    assert np.linalg.norm(reached.translation - goal.translation) < 1e-4
    assert np.linalg.norm(pin.log3(reached.rotation @ goal.rotation.T)) < 1e-3
    within_limits(arm, commands)
    within_position_limits(arm, commands)


def test_streaming_toward_the_elbow_singularity_slows_to_a_stop_and_says_so(arm: RobotClient) -> None:
    recorder = Recorder(arm)
    steps = paced(arm, 700, lambda k: arm.speed_tool([0.15, 0, 0, 0, 0, 0]))   # outward: the elbow straightens
    status = arm.servo_status()
    commands = recorder.stop()
    assert status.following and status.step is steps[-1]
    assert all(step.reason == "singularity" and step.scale < 0.01 for step in steps[-100:]), [
        (step.reason, step.scale, step.singular_value) for step in steps[-100::10]]
    servo = servo_of(arm)
    crawled = servo.tool_pose(steps[-1].target).translation - servo.tool_pose(steps[-100].target).translation
    assert np.linalg.norm(crawled) < 1e-3
    sigma = [servo.twist_step(q, np.zeros(6), 0.001).singular_value for q in commands[::10, 0]]
    assert min(sigma) > 0.75 * servo.settings.stop_singular_value   # the follower overshoots stopped targets a little
    within_limits(arm, commands)
    within_position_limits(arm, commands)
    assert arm.last_fault() is None
