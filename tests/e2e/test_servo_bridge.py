"""Jogging and the speed override over ROS 2, against `plem launch bus:=mock`: moveit_servo's delta_joint_cmds and UR's
speed_scaling and set_speed_slider, reached over Cyclone DDS from this process (another than the launch's); what the
arm did is read from shared memory."""

from __future__ import annotations

import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from plem.bridge.client import RobotClient
from plem.control.events import EventKind
from plem.control.kinematics import ArmDynamics
from plem.control.modes import Mode
from plem.ipc.robot_description import read_description
from plem.middleware.discovery import DiscoverySettings
from plem.middleware.qos import DEFAULT
from plem.middleware.servo import JOINT_JOG, SPEED_SLIDER, TWIST
from tests.e2e.launched import Launch, launched_robot, wait_until
from tests.e2e.ros_peer import JOINT_NAMES, TRAJECTORY, RosPeer, wait_for

PERIOD_S = 0.01   # a jog stream at 100 Hz


@pytest.fixture(scope="module")
def robot(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Launch]:
    with launched_robot(tmp_path_factory, "record:=false", ros=True) as running:
        yield running


class Servo:
    """A ROS 2 user of the robot's servo and speed scaling endpoints."""

    def __init__(self, peer: RosPeer) -> None:
        ns = f"/{peer.robot_id}"
        self.peer = peer
        self.jog = peer.node.publisher(f"{ns}/servo_node/delta_joint_cmds", JOINT_JOG, DEFAULT)
        self.twist = peer.node.publisher(f"{ns}/servo_node/delta_twist_cmds", TWIST, DEFAULT)
        self.slider = peer.node.client(f"{ns}/io_and_status_controller/set_speed_slider", SPEED_SLIDER)
        self.scaling = peer.subscribe("speed_scaling_state_broadcaster/speed_scaling", "std_msgs/msg/Float64")
        self.status = peer.subscribe("servo_node/status", "std_msgs/msg/Int8")
        self.controller_state = peer.subscribe(f"{TRAJECTORY}/controller_state",
                                               "control_msgs/msg/JointTrajectoryControllerState")
        self.events = peer.rt_events()

    def message(self, names: list[str], **fields: Any) -> Any:
        return self.peer.library.new(JOINT_JOG, joint_names=names, **fields)

    def stream(self, message: Any, seconds: float) -> None:
        """Publish `message` (a JointJog or a TwistStamped) every PERIOD_S for `seconds`, as a teleoperation node
        does."""
        publisher = self.twist if type(message).__name__ == "TwistStamped" else self.jog
        began = time.monotonic()
        for tick in range(round(seconds / PERIOD_S)):
            publisher.publish(message)
            time.sleep(max(0.0, began + (tick + 1) * PERIOD_S - time.monotonic()))

    def rejected(self, cause: str, timeout: float = 5.0) -> Any:
        """The first command_rejected entry on rt_events from `cause`."""
        def found() -> Any:
            return next((m for m in self.events.take() if m.kind == EventKind.COMMAND_REJECTED.value
                         and m.cause == cause), None)
        return wait_for(found, timeout)


@pytest.fixture(scope="module")
def servo(robot: Launch) -> Iterator[Servo]:
    peer = RosPeer(robot.robot_id, DiscoverySettings.from_environment(robot.env))
    try:
        endpoints = Servo(peer)
        assert wait_for(lambda: endpoints.jog.subscribers > 0 and endpoints.twist.subscribers > 0
                        and endpoints.slider.ready, 15), "the servo topics and set_speed_slider were not discovered"
        yield endpoints
    finally:
        peer.close()


def at_rest(client: RobotClient) -> bool:
    state = client.live_state()
    return state.mode is Mode.HOLD and bool(np.all(np.abs(state.command_velocity) < 1e-9))


def held(client: RobotClient) -> np.ndarray:
    assert client.last_fault() is None, client.last_fault()
    client.set_mode("hold")
    assert wait_until(lambda: at_rest(client), 10)
    return client.live_state().command_position.copy()


def test_a_joint_jog_stream_moves_the_named_joint_and_comes_to_rest_after_its_timeout(
        servo: Servo, client: RobotClient) -> None:
    start = held(client)
    velocity = -0.25 if start[2] > 0 else 0.25
    peak = []
    message = servo.message([JOINT_NAMES[2]], velocities=[velocity])
    began = time.monotonic()
    for tick in range(50):
        servo.jog.publish(message)
        peak.append(client.live_state().command_velocity[2])
        time.sleep(max(0.0, began + (tick + 1) * PERIOD_S - time.monotonic()))
    assert client.stream_status().state == "following"
    assert max(abs(v) for v in peak) == pytest.approx(abs(velocity), rel=1e-3), "the joint reached the jog's velocity"
    assert wait_until(lambda: at_rest(client), 5), "the stream ends once the messages stop"
    moved = client.live_state().command_position - start
    assert np.all(np.delete(moved, 2) == 0.0), "the joints not named stay where they are"
    assert moved[2] / velocity > 0.2, moved
    assert client.stream_status().state != "following"
    assert client.last_fault() is None


def test_displacements_over_a_duration_move_the_joint_about_that_far(servo: Servo, client: RobotClient) -> None:
    start = held(client)
    distance = -0.05 if start[3] > 0 else 0.05
    servo.jog.publish(servo.message([JOINT_NAMES[3]], displacements=[distance], duration=0.5))   # one message
    assert wait_until(lambda: client.live_state().mode is Mode.TRAJECTORY, 5)
    assert wait_until(lambda: at_rest(client), 5)
    moved = client.live_state().command_position - start
    assert np.all(np.delete(moved, 3) == 0.0)
    assert 0.9 < moved[3] / distance < 1.3, moved   # the last velocity runs out its ramp to rest


def test_a_velocity_above_the_limit_is_scaled_down_to_it_in_the_same_direction(servo: Servo,
                                                                               client: RobotClient) -> None:
    start = held(client)
    limit = client.limits.maximum("velocity")
    sign = -1.0 if start[4] > 0 else 1.0
    servo.stream(servo.message([JOINT_NAMES[4], JOINT_NAMES[5]], velocities=[sign * 2 * limit[4], 0.0]), 0.2)
    assert wait_until(lambda: at_rest(client), 5)
    moved = client.live_state().command_position - start
    assert moved[4] * sign > 0 and np.all(np.delete(moved, 4) == 0.0)
    assert client.last_fault() is None


def test_a_bad_joint_jog_is_refused_with_the_reason_and_nothing_moves(servo: Servo, client: RobotClient) -> None:
    start = held(client)
    servo.events.take()
    servo.stream(servo.message(["no_such_joint"], velocities=[0.2]), 0.1)
    event = servo.rejected("delta_joint_cmds")
    assert event is not None and "no joint of this robot" in event.reason
    servo.jog.publish(servo.message([JOINT_NAMES[0]], displacements=[0.1], duration=0.0))
    event = servo.rejected("delta_joint_cmds")
    assert event is not None and "needs a duration" in event.reason
    assert np.array_equal(client.live_state().command_position, start)


def test_the_speed_slider_sets_the_override_and_speed_scaling_publishes_it_in_percent(
        servo: Servo, client: RobotClient) -> None:
    try:
        assert servo.slider.call(5.0, speed_slider_fraction=0.4).success
        assert client.stream_status().override_target == 0.4
        assert wait_for(lambda: any(m.data == pytest.approx(40.0, abs=1e-4) for m in servo.scaling.take()), 10)
        assert wait_for(lambda: any(m.speed_scaling_factor == pytest.approx(0.4, abs=1e-6)
                                    for m in servo.controller_state.take()), 10)
        servo.events.take()
        assert not servo.slider.call(5.0, speed_slider_fraction=1.5).success
        event = servo.rejected("set_speed_slider")
        assert event is not None and "speed override is out of range" in event.reason
        assert client.stream_status().override_target == 0.4
    finally:
        client.set_speed_override(1.0)
    assert wait_for(lambda: any(m.data == pytest.approx(100.0, abs=1e-4) for m in servo.scaling.take()), 10)


def tool_position(arm: ArmDynamics, client: RobotClient) -> np.ndarray:
    return np.array(arm.forward_kinematics(client.live_state().command_position).translation)


def test_a_twist_stream_moves_the_tool_along_the_base_axis_it_names(servo: Servo, client: RobotClient) -> None:
    held(client)
    client.move_joints(client.channels.state.poses["home"], speed_scale=1.0).wait(30)   # away from singularities
    assert wait_until(lambda: at_rest(client), 10)
    arm = ArmDynamics(read_description(client.robot_id).urdf, client.joint_names)
    start = tool_position(arm, client)
    twist = servo.peer.library.new(TWIST, header=servo.peer.library.new("std_msgs/msg/Header", frame_id=""))
    twist.twist.linear.z = -0.05
    servo.status.take()
    began = time.monotonic()
    while tool_position(arm, client)[2] > start[2] - 0.02 and time.monotonic() - began < 10:
        servo.stream(twist, 0.1)
    assert wait_until(lambda: at_rest(client), 5), "the stream ends once the messages stop"
    moved = tool_position(arm, client) - start
    assert moved[2] < -0.02 and np.all(np.abs(moved[:2]) < 0.1 * abs(moved[2])), moved
    assert client.last_fault() is None
    codes = [m.data for m in servo.status.take()]   # moveit_servo's StatusCode after each sample: no warning
    assert codes and set(codes) == {0}, codes


def test_a_twist_in_a_frame_other_than_the_base_or_the_tool_is_refused(servo: Servo, client: RobotClient) -> None:
    start = held(client)
    servo.events.take()
    twist = servo.peer.library.new(TWIST, header=servo.peer.library.new("std_msgs/msg/Header", frame_id="camera"))
    twist.twist.linear.x = 0.05
    servo.stream(twist, 0.1)
    event = servo.rejected("delta_twist_cmds")
    assert event is not None and "a twist in frame 'camera' cannot be followed" in event.reason
    assert np.array_equal(client.live_state().command_position, start)
