"""Streaming and the speed override, as the in-process `Robot` and the process client `RobotClient` both offer them.

`servo_joints`, `speed_joints` and `jog` write samples straight into the robot's stream block, which the core
reads every cycle, so a sample reaches the loop within a cycle of being written, whatever runs in the caller's
process. The first sample of a stream (and the first after one ended) asks the robot to follow the block; the
stream ends when its samples stop for its timeout (the arm comes to rest), on `stop()`, or on a fault.
`servo_pose` and `speed_tool` stream the joint targets of Cartesian servo steps (see cartesian_streaming).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from plem.control.limits import ArmLimits
from plem.control.state import JointState
from plem.control.streaming import DEFAULT_TIMEOUT_S, StreamBlock, StreamStatus, override_factor, stream_timeout
from plem.core import arguments
from plem.errors import CommandRejected

if TYPE_CHECKING:   # pinocchio is imported by the first Cartesian call, not by every client
    from plem.bridge.cartesian_streaming import CartesianStep, CartesianStreamer, ServoStatus, TwistFunction
    from plem.control.kinematics import ArmDynamics
    from plem.planning.poses import Pose


class StreamHandle(Protocol):
    """What streaming needs of a request's handle: whether it ended, and its end."""

    @property
    def done(self) -> bool:
        """The stream ended."""

    def wait(self, timeout: float | None = None) -> Any:
        """How the stream ended."""


class StreamingCalls:
    """Streamed targets and the speed override; subclasses provide the block, the limits and the two requests."""

    _stream: tuple[int, StreamHandle, float] | None = None   # the open stream: session, handle, timeout
    _last_sample: tuple[int, int, str, np.ndarray] | None = None   # the last sample: session, number, kind, values
    _cartesian: CartesianStreamer | None = None

    # -- what a subclass provides --------------------------------------------------------------------
    def _stream_arm(self) -> tuple[ArmLimits, tuple[str, ...]]:
        """The arm's limits and joint names."""
        raise NotImplementedError

    def _stream_block(self) -> StreamBlock:
        raise NotImplementedError

    def _stream_dynamics(self) -> ArmDynamics:
        """The arm's kinematics (built when Cartesian streaming first needs them)."""
        raise NotImplementedError

    def _stream_cycle_time(self) -> float:
        """The loop's cycle time (s)."""
        raise NotImplementedError

    def live_state(self) -> JointState:
        """The latest cycle's state."""
        raise NotImplementedError

    def _open_stream(self, timeout_s: float) -> tuple[int, StreamHandle]:
        """Ask the robot to follow the stream block; the session its samples carry, and the stream's handle."""
        raise NotImplementedError

    def _request_speed_override(self, factor: float) -> StreamHandle:
        raise NotImplementedError

    # -- streaming -----------------------------------------------------------------------------------
    def servo_joints(self, positions: Sequence[float] | np.ndarray, timeout: float = DEFAULT_TIMEOUT_S) -> int:
        """Stream a joint position target (rad), at any rate up to the loop's; returns the sample's number.

        The arm follows the newest target as fast as its limits allow (a target past a position limit is followed
        to the limit); without a new sample for `timeout` s it comes to rest and the stream ends.
        """
        return self._sample("position", self._joint_values(positions, "positions"), timeout)

    def speed_joints(self, velocities: Sequence[float] | np.ndarray, timeout: float = DEFAULT_TIMEOUT_S) -> int:
        """Stream joint velocities (rad/s), reached within the acceleration and jerk limits; see `servo_joints`."""
        values = self._joint_values(velocities, "velocities")
        limits, names = self._stream_arm()
        limit = limits.maximum("velocity")
        over = np.flatnonzero(np.abs(values) > limit)
        if over.size:
            i = int(over[0])
            raise CommandRejected("a streamed velocity is above its joint's limit",
                                  what=f"|velocity| ≤ {limit[i]:g} rad/s for {names[i]}",
                                  why=f"got {values[i]:g} rad/s", how="stream a velocity within the joint's limit")
        return self._sample("velocity", values, timeout)

    def jog(self, joint: int | str, velocity: float, timeout: float = DEFAULT_TIMEOUT_S) -> int:
        """Stream one joint's velocity (rad/s), the others at rest: call it again within `timeout` to keep going."""
        values = np.zeros(self._stream_arm()[0].dof)
        values[self._joint_index(joint)] = arguments.real(velocity, "velocity")
        return self.speed_joints(values, timeout)

    def stream_status(self) -> StreamStatus:
        """The core's report on streaming and the speed override, as of its last cycle (see StreamStatus)."""
        return self._stream_block().status()

    def _sample(self, kind: str, values: np.ndarray, timeout: float) -> int:
        return self._write_sample(kind, values, timeout)[1]

    def _write_sample(self, kind: str, values: np.ndarray, timeout: float,
                      stamp_ns: int | None = None) -> tuple[int, int]:
        """Write one sample (stamped now, or at `stamp_ns`), opening a stream first when none is open (or its
        timeout differs): its session and number."""
        timeout = stream_timeout(timeout)
        opened = self._stream
        if opened is None or opened[1].done or opened[2] != timeout:
            session, handle = self._open_stream(timeout)
            opened = self._stream = (session, handle, timeout)
        count = self._stream_block().write(opened[0], kind, values, stamp_ns)
        self._last_sample = (opened[0], count, kind, values)
        return opened[0], count

    # -- Cartesian streaming ---------------------------------------------------------------------------
    def speed_tool(self, twist: Sequence[float] | np.ndarray, frame: str = "base",
                   timeout: float = DEFAULT_TIMEOUT_S) -> CartesianStep:
        """Stream a tool twist (vx, vy, vz in m/s, then wx, wy, wz in rad/s) in the base or the tool frame's axes.

        Each call moves the joint target by one Cartesian servo step over the time since the previous call (at most
        `timeout`), slowed near singularities and joint limits; the step's scale and reason come back and
        `servo_status()` keeps them. Without a new call for `timeout` s the arm comes to rest (docs/motion.md).
        """
        from plem.bridge.cartesian_streaming import base_twist, twist_frame, twist_values
        velocity, axes = twist_values(twist), twist_frame(frame)
        return self._cartesian_sample(lambda servo, q, dt: base_twist(servo, q, velocity, axes), timeout)

    def servo_pose(self, pose: Pose | Sequence[float], timeout: float = DEFAULT_TIMEOUT_S) -> CartesianStep:
        """Stream a tool pose target in the base frame (a `Pose`, as `move_to` takes, or x y z [qx qy qz qw]).

        Each call moves the joint target one Cartesian servo step toward it, at most the servo's tool speeds over
        the time since the previous call, along a straight line, slowed as `speed_tool` is; call it again (with
        the same or a new pose) until the tool is there.
        """
        from plem.bridge.cartesian_streaming import pose_placement
        target = pose_placement(pose)
        return self._cartesian_sample(lambda servo, q, dt: servo.approach_twist(servo.tool_pose(q), target, dt),
                                      timeout, twist_stream=False)

    def servo_status(self) -> ServoStatus:
        """The core's stream status with the last Cartesian step's target, scale, reason and singular value."""
        from plem.bridge.cartesian_streaming import ServoStatus
        return ServoStatus(self.stream_status(), None if self._cartesian is None else self._cartesian.last)

    def _cartesian_sample(self, asked: TwistFunction, timeout: float, twist_stream: bool = True) -> CartesianStep:
        """Run one servo step from the reference and stream its joint target."""
        timeout = stream_timeout(timeout)
        streamer = self._cartesian_streamer()
        state, now_ns = self.live_state(), time.monotonic_ns()
        servo_step, reason, period = streamer.step(state, self._followed_target(), timeout, now_ns, asked,
                                                     twist_stream)
        if period == 0.0 and streamer.last is not None:   # called again at the same instant: nothing new to send
            return streamer.last
        # stamped with the instant the target is for, from which the core's follower takes the targets' velocity
        session, sample = self._write_sample("position", servo_step.q, timeout, now_ns)
        return streamer.streamed(sample, session, servo_step, reason, period, now_ns)

    def _cartesian_streamer(self) -> CartesianStreamer:
        if self._cartesian is None:
            from plem.bridge.cartesian_streaming import CartesianStreamer
            self._cartesian = CartesianStreamer(self._stream_dynamics(), self._stream_arm()[0],
                                                self._stream_cycle_time())
        return self._cartesian

    def _followed_target(self) -> tuple[int, np.ndarray] | None:
        """The session and last position target of the open stream, while the core follows it or is yet to take
        its first sample; None when the stream ended, comes to rest, or its last sample was a velocity."""
        last, opened = self._last_sample, self._stream
        if last is None or opened is None or opened[1].done or last[0] != opened[0] or last[2] != "position":
            return None
        status = self.stream_status()
        if status.session == last[0] and status.state != "following":
            return None
        return last[0], last[3]

    def _joint_values(self, values: Sequence[float] | np.ndarray, name: str) -> np.ndarray:
        limits, names = self._stream_arm()
        checked = np.asarray(arguments.reals(values, name), dtype=float)
        if checked.shape != (limits.dof,):
            raise CommandRejected(f"wrong number of {name}", what=f"one value per joint ({limits.dof})",
                                  why=f"got {checked.size}", how=f"pass {limits.dof} values in joint order: "
                                                                 f"{', '.join(names)}")
        if not np.all(np.isfinite(checked)):
            raise CommandRejected(f"{name} must be finite numbers", what=f"finite {name}",
                                  why=f"got {checked.tolist()}", how="pass one finite number per joint")
        return checked

    def _joint_index(self, joint: int | str) -> int:
        limits, names = self._stream_arm()
        if isinstance(joint, str) and joint in names:
            return names.index(joint)
        if isinstance(joint, int) and not isinstance(joint, bool) and 0 <= joint < limits.dof:
            return joint
        raise CommandRejected("no such joint", what=f"a joint name ({', '.join(names)}) or an index from "
                                                    f"0 to {limits.dof - 1}",
                              why=f"got {joint!r}", how="name the joint as the robot's joint_names do")

    # -- the speed override --------------------------------------------------------------------------
    def set_speed_override(self, factor: float, timeout: float = 5.0) -> None:
        """Scale the speed of every motion from now on along its own path: 1 as planned, 0 stopped on the path.

        Position, velocity and acceleration follow the same path at the new speed, and the change itself keeps
        every limit, so it takes effect as fast as the running motion leaves room (see docs/motion.md); raising
        it again resumes. Streams are capped at this share of each joint's velocity limit. Returns once the core
        took the factor; `speed_override` tells the factor in force.
        """
        self._request_speed_override(override_factor(factor)).wait(arguments.seconds(timeout, "timeout"))

    @property
    def speed_override(self) -> float:
        """The speed override in force now (it moves toward the one set as fast as the limits allow)."""
        return self._stream_block().status().speed_override
