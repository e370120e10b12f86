"""Streaming and the speed override on ROS 2: moveit_servo's command topics and UR's speed scaling interfaces.

- `/{robot_id}/servo_node/delta_joint_cmds` (control_msgs/msg/JointJog), as moveit_servo's `~/delta_joint_cmds`:
  each message is one sample of a joint velocity stream (`RobotClient.speed_joints`). `velocities` are rad/s;
  without them, `displacements` over `duration` s give the velocity, and the stream then lasts `duration` after
  the message instead of the stream's 0.1 s timeout. Joints not named stay at rest. A velocity above a joint's
  limit scales the whole command down to it (moveit_servo does the same), with a warning.
- `/{robot_id}/servo_node/delta_twist_cmds` (geometry_msgs/msg/TwistStamped), as moveit_servo's
  `~/delta_twist_cmds`: each message is one sample of a tool twist stream (`RobotClient.speed_tool`), in m/s and
  rad/s, in the axes of `header.frame_id`: the arm's base (its root link, or empty) or its tool (the last frame
  of the URDF, the one `speed_tool`'s tool frame is), each with or without the frame prefix.
- `/{robot_id}/servo_node/status` (std_msgs/msg/Int8), as moveit_servo's `~/status`: after each twist sample, its
  StatusCode: 0 no warning, 1 slowing for an approaching singularity, 2 halted at it, 6 held at a joint limit.
- `/{robot_id}/speed_scaling_state_broadcaster/speed_scaling` (std_msgs/msg/Float64): the speed override in
  force, in percent, as UR's speed_scaling_state_broadcaster publishes it.
- `/{robot_id}/io_and_status_controller/set_speed_slider` (ur_msgs/srv/SetSpeedSliderFraction): sets the speed
  override, from 0 to 1 (UR's takes 0.01 to 1; plem's 0 stops every motion on its path).
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Sequence
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from plem.bridge.cartesian_streaming import CartesianStep
from plem.bridge.client import RobotClient
from plem.control.streaming import DEFAULT_TIMEOUT_S, MAX_TIMEOUT_S
from plem.errors import CommandRejected, PlemError
from plem.middleware.node import Node, Publisher, ServiceServer, Subscription
from plem.middleware.qos import DEFAULT

_log = logging.getLogger("plem.bridge.servo_node")

JOINT_JOG = "control_msgs/msg/JointJog"
TWIST = "geometry_msgs/msg/TwistStamped"
SPEED_SLIDER = "ur_msgs/srv/SetSpeedSliderFraction"
SERVO_STATUS = "std_msgs/msg/Int8"
#: moveit_servo's StatusCode values (moveit_servo/utils/datatype.hpp) that a Cartesian step can have.
NO_WARNING, DECELERATE_FOR_APPROACHING_SINGULARITY, HALT_FOR_SINGULARITY, JOINT_BOUND = 0, 1, 2, 6
#: A step at less than this share of the asked speed has halted.
HALTED_SCALE = 0.01
#: The nodes these endpoints belong to, named as moveit_servo and UR's ROS 2 driver name theirs.
SERVO_NODE = "servo_node"
SCALING_NODE = "speed_scaling_state_broadcaster"
SLIDER_NODE = "io_and_status_controller"
#: How often a repeated refusal or warning of a stream is logged (a stream repeats it every sample).
REPORT_PERIOD_S = 1.0


class Reports:
    """Refusals and warnings of one stream, each said again at most every REPORT_PERIOD_S unless it changed."""

    def __init__(self, refuse: Callable[[str, str], None]) -> None:
        self._refuse = refuse
        self._last: tuple[str, float] = ("", -math.inf)

    def refused(self, source: str, error: PlemError) -> None:
        """Report a refused sample (on /rosout and rt_events)."""
        if self._due(error.render()):
            self._refuse(source, error.render())

    def warn(self, text: str) -> None:
        """A WARNING on /rosout under the servo node."""
        if self._due(text):
            _log.warning("%s", text)

    def _due(self, text: str) -> bool:
        now = time.monotonic()
        if text == self._last[0] and now - self._last[1] < REPORT_PERIOD_S:
            return False
        self._last = (text, now)
        return True


def jog_velocities(message: Any, joint_names: tuple[str, ...]) -> tuple[np.ndarray, float]:
    """A JointJog as joint velocities in the robot's joint order (rad/s) and the stream's timeout (s)."""
    names = list(message.joint_names)
    unknown = [name for name in names if name not in joint_names]
    if unknown or len(set(names)) != len(names) or not names:
        raise CommandRejected("the JointJog names no joint of this robot once each",
                              what=f"joint_names from {', '.join(joint_names)}, each at most once",
                              why=f"got {names}", how="name the joints as the robot's joint_states does")
    given = list(message.velocities) or list(message.displacements)
    field = "velocities" if message.velocities else "displacements"
    if len(given) != len(names):
        raise CommandRejected(f"the JointJog's {field} do not match its joint_names",
                              what=f"one value in {field} per name in joint_names ({len(names)})",
                              why=f"got {len(given)}", how="fill velocities (rad/s), or displacements (rad) with "
                                                           "a duration (s), one per joint named")
    timeout = DEFAULT_TIMEOUT_S
    values = np.array(given, dtype=float)
    if field == "displacements":
        duration = float(message.duration)
        if not 0.0 < duration <= MAX_TIMEOUT_S:
            raise CommandRejected("a JointJog of displacements needs a duration",
                                  what=f"duration from above 0 to {MAX_TIMEOUT_S:g} s",
                                  why=f"duration {duration:g}", how="set duration, or send velocities instead")
        values, timeout = values / duration, max(DEFAULT_TIMEOUT_S, duration)
    if not np.all(np.isfinite(values)):
        raise CommandRejected(f"the JointJog's {field} are not all finite", what="finite numbers",
                              why=f"got {given}", how=f"send finite {field}")
    velocities = np.zeros(len(joint_names))
    velocities[[joint_names.index(name) for name in names]] = values
    return velocities, timeout


class TwistFrames:
    """The frames a TwistStamped may be given in: the arm's base and its tool, with or without the frame prefix."""

    def __init__(self, urdf: str, joint_names: Sequence[str], frame_prefix: str) -> None:
        self._urdf = urdf
        self._joint_names = tuple(joint_names)
        self._prefix = frame_prefix

    @cached_property
    def _names(self) -> tuple[str, str]:
        """The root link and the tool frame (the kinematics are loaded on the first twist, as the client loads them)."""
        from plem.control.kinematics import ArmDynamics
        from plem.description.model import parse_urdf

        roots = parse_urdf(self._urdf, Path("robot_description")).roots()
        return (roots[0] if roots else ""), ArmDynamics(self._urdf, self._joint_names).tip_frame

    def load(self) -> None:
        """Load the kinematics now (about a second on a busy machine), so that the first twist is not late."""
        _ = self._names

    def axes(self, frame_id: str) -> str:
        """'base' or 'tool', for `speed_tool`, from a header's frame_id."""
        base, tool = self._names
        plain = frame_id.removeprefix(self._prefix) if self._prefix else frame_id
        if plain in ("", base):
            return "base"
        if plain == tool:
            return "tool"
        prefix = self._prefix
        raise CommandRejected(f"a twist in frame {frame_id!r} cannot be followed",
                              what=f"header.frame_id {prefix}{base} (the base; empty too) or {prefix}{tool} (the tool)",
                              why=f"got {frame_id!r}", how="express the twist in the base or the tool frame")


def twist_values(message: Any) -> list[float]:
    """A TwistStamped as speed_tool's six values: linear (m/s), then angular (rad/s)."""
    linear, angular = message.twist.linear, message.twist.angular
    return [linear.x, linear.y, linear.z, angular.x, angular.y, angular.z]


def status_code(step: CartesianStep) -> int:
    """moveit_servo's status of one Cartesian servo step: slowing for (or halted at) a singularity, held at a joint
    limit, or no warning (a step slowed by the velocity or acceleration limits has no code of its own there)."""
    if step.reason == "singularity":
        return HALT_FOR_SINGULARITY if step.scale < HALTED_SCALE else DECELERATE_FOR_APPROACHING_SINGULARITY
    return JOINT_BOUND if step.reason == "joint limit" else NO_WARNING


class ServoEndpoints:
    """The joint jog topic and the speed slider service of one robot, for a bridge that takes commands."""

    def __init__(self, node: Node, namespace: str, client: RobotClient, refuse: Callable[[str, str], None],
                 accepts: Callable[[], PlemError | None], frames: TwistFrames) -> None:
        self.node = node
        self.client = client
        self.accepts = accepts
        self.frames = frames
        self.joint_jog: Subscription[Any] = node.subscription(f"{namespace}/{SERVO_NODE}/delta_joint_cmds",
                                                              JOINT_JOG, DEFAULT)
        self.twist: Subscription[Any] = node.subscription(f"{namespace}/{SERVO_NODE}/delta_twist_cmds", TWIST, DEFAULT)
        self.speed_slider = ServiceServer(node, f"{namespace}/{SLIDER_NODE}/set_speed_slider", SPEED_SLIDER)
        self.status: Publisher[Any] = node.publisher(f"{namespace}/{SERVO_NODE}/status", SERVO_STATUS, DEFAULT)
        self._reports = Reports(refuse)

    @property
    def waitables(self) -> tuple[Subscription[Any] | ServiceServer, ...]:
        """What the bridge's command thread waits on."""
        return self.joint_jog, self.twist, self.speed_slider

    def prepare(self) -> None:
        """What the first twist would otherwise wait for: the kinematics of its frames."""
        self.frames.load()

    def spin_once(self) -> None:
        """Take the newest joint jog and twist (older ones waiting are superseded) and answer speed slider
        requests."""
        messages = self.joint_jog.take()
        if messages:
            self._jog(messages[-1])
        twists = self.twist.take()
        if twists:
            self._twist(twists[-1])
        for request in self.speed_slider.take():
            self._set_speed_slider(request)
        self.speed_slider.flush()

    def _jog(self, message: Any) -> None:
        try:
            refused = self.accepts()
            if refused is not None:
                raise refused
            velocities, timeout = jog_velocities(message, self.client.joint_names)
            limit = self.client.limits.maximum("velocity")
            scale = float(np.max(np.abs(velocities) / limit))
            if scale > 1.0:
                joint = self.client.joint_names[int(np.argmax(np.abs(velocities) / limit))]
                self._reports.warn(f"delta_joint_cmds: the command exceeds {joint}'s velocity limit; all its "
                                   f"velocities were scaled by {1 / scale:.3g} to keep the direction")
                velocities = velocities / scale
            self.client.speed_joints(velocities, timeout)
        except PlemError as error:
            self._reports.refused("delta_joint_cmds", error)

    def _twist(self, message: Any) -> None:
        try:
            refused = self.accepts()
            if refused is not None:
                raise refused
            step = self.client.speed_tool(twist_values(message), self.frames.axes(message.header.frame_id))
            self.status.publish(self.status.message(data=status_code(step)))
        except PlemError as error:
            self._reports.refused("delta_twist_cmds", error)

    def _set_speed_slider(self, request: Any) -> None:
        try:
            self.client.set_speed_override(request.speed_slider_fraction)
        except PlemError as error:
            self._reports.refused("set_speed_slider", error)
            self.speed_slider.reply(request, success=False)
            return
        self.speed_slider.reply(request, success=True)


class SpeedScalingPublisher:
    """UR's speed_scaling topic: the speed override in force, in percent."""

    def __init__(self, node: Node, namespace: str, client: RobotClient) -> None:
        self.client = client
        self.publisher: Publisher[Any] = node.publisher(f"{namespace}/{SCALING_NODE}/speed_scaling",
                                                        "std_msgs/msg/Float64", DEFAULT)

    def factor(self) -> float:
        """The speed override in force, from 0 to 1."""
        return self.client.speed_override

    def publish(self, factor: float) -> None:
        """Publish `factor` (0 to 1) in percent."""
        self.publisher.publish(self.publisher.message(data=100.0 * factor))
