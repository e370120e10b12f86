"""Cartesian streaming (`servo_pose`, `speed_tool`): each call runs one Cartesian servo step from the joint
reference and streams its joint target, so the core's follower keeps every limit.

The reference is the last position target streamed while the core follows that stream (successive steps integrate
on the targets, not on the arm lagging behind them), else the arm's command position. A call covers the time since
the previous Cartesian call of the same stream, at most the stream's timeout, on the monotonic clock that stamps
the samples: the core's follower feeds forward the targets' velocity from those stamps, so the targets advance at
the twist on that clock (a late call covers its whole delay, a call right after it only what passed since). The
first call of a stream, or the first after a joint sample, covers one cycle.

The targets change speed smoothly, because the core's follower is jerk-limited per joint: a twist that jumps would
leave each joint lagging by its own amount and the tool off its line while they catch up. Each call moves the
tool's twist from its last one toward the one asked (for a pose, the servo's approach twist) only as far as keeps
every joint's target velocity changing by at most half its acceleration limit (the follower smooths the jerk);
the twist in between stays on the line between the two, so a tool speeding up,
slowing or stopping keeps its path (a pose's approach twist, which slows by itself toward the pose, is limited
only while speeding up, so it does not overshoot). A twist stream also aims each step at the pose its twists
integrate to from where it last was not slowed, so the steps' first-order errors do not add up along the way.
The servo's own slowing near singularities and joint limits is applied to the twist reached, never delayed; and
a step that lowers the Jacobian's smallest singular value is cut so every joint can still brake, at that half of
its acceleration limit, before it reaches the servo's stop (joint speeds grow without bound toward a
singularity, faster than the servo's slowing in σ alone can stop them).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import pinocchio as pin

from plem.control.cartesian_servo import CartesianServo, ServoStep, SlowReason, TwistFrame
from plem.control.kinematics import ArmDynamics
from plem.control.limits import ArmLimits
from plem.control.state import JointState
from plem.control.streaming import StreamStatus
from plem.core import arguments
from plem.errors import CommandRejected, PlanningError
from plem.planning.poses import Pose

#: The twist's six values, as messages name them.
TWIST_VALUES = "vx, vy, vz in m/s, then wx, wy, wz in rad/s"
#: Why a Cartesian step is slower than asked: the servo's reasons, or its targets changing speed ('acceleration').
StepReason = SlowReason | Literal["acceleration"]
#: The share of each joint's acceleration limit the targets change speed with (the rest is the follower's).
RAMP_SHARE = 0.5
#: The base-frame tool twist a call asks for, from the joint reference (arm order) over the period it covers (s).
TwistFunction = Callable[[CartesianServo, np.ndarray, float], np.ndarray]


@dataclass(frozen=True)
class CartesianStep:
    """What one Cartesian streaming call streamed: the sample's number and stream session, the joint target, the
    period it covers (s; 0 when it repeats the previous target), the fraction of the asked speed it moves at, why
    that is below 1 ('' when it is not: 'singularity', 'joint limit', 'velocity limit', or 'acceleration' while
    the targets change speed), the smallest singular value of the tool Jacobian where it started, and when it was
    computed (CLOCK_MONOTONIC, ns)."""

    sample: int
    session: int
    target: np.ndarray
    period_s: float
    scale: float
    reason: StepReason
    singular_value: float
    monotonic_ns: int


@dataclass(frozen=True)
class ServoStatus:
    """The core's stream status, and the last Cartesian step streamed (None before the first)."""

    stream: StreamStatus
    step: CartesianStep | None

    @property
    def following(self) -> bool:
        """Whether the core follows the stream the last step went to (not ended, not coming to rest)."""
        return (self.step is not None and self.stream.session == self.step.session
                and self.stream.state == "following")


def twist_values(twist: Sequence[float] | np.ndarray) -> np.ndarray:
    """A twist as six finite numbers; CommandRejected (WHAT/WHY/HOW) otherwise."""
    values = np.array(arguments.reals(twist, "twist", 6), dtype=float)
    if not np.isfinite(values).all():
        raise CommandRejected("the twist must be finite numbers", what=f"6 finite numbers: {TWIST_VALUES}",
                              why=f"got {values.tolist()}", how="pass one finite number per component")
    return values


def twist_frame(frame: object) -> TwistFrame:
    """'base' or 'tool'; CommandRejected otherwise."""
    if frame == "base":
        return "base"
    if frame == "tool":
        return "tool"
    raise CommandRejected("unknown twist frame", what="frame='base' (the arm's base axes) or 'tool' (the tool's)",
                          why=f"got {frame!r}", how="pass frame='base' or frame='tool'")


def pose_placement(pose: Pose | Sequence[float] | Any) -> pin.SE3:
    """A target pose in the base frame: a `Pose` (as `move_to` takes) or x y z [qx qy qz qw]; CommandRejected
    otherwise."""
    try:
        if not isinstance(pose, Pose):
            pose = Pose.of(arguments.reals(pose, "pose"))
    except PlanningError as error:
        raise CommandRejected(error.summary, what=error.what, why=error.why, how=error.how) from None
    x, y, z, w = pose.orientation
    return pin.SE3(pin.Quaternion(w, x, y, z).toRotationMatrix(), np.array(pose.position))


def _difference(start: pin.SE3, end: pin.SE3) -> np.ndarray:
    """The base-frame motion (translation, then rotation vector) from tool pose `start` to `end`."""
    return np.concatenate([end.translation - start.translation, pin.log3(end.rotation @ start.rotation.T)])


def _advanced(pose: pin.SE3, twist: np.ndarray, period: float) -> pin.SE3:
    """Tool pose `pose` moved by base-frame `twist` for `period`."""
    return pin.SE3(pin.exp3(twist[3:] * period) @ pose.rotation, pose.translation + twist[:3] * period)


def base_twist(servo: CartesianServo, q: np.ndarray, twist: np.ndarray, frame: TwistFrame) -> np.ndarray:
    """`twist` (in `frame`'s axes) in the base frame's axes, the tool at joint positions `q`."""
    if frame == "base":
        return twist
    rotation = servo.tool_pose(q).rotation
    return np.concatenate([rotation @ twist[:3], rotation @ twist[3:]])


class CartesianStreamer:
    """The Cartesian servo of one arm's tool and the last step streamed; one per robot handle, used from one
    thread (the servo keeps pinocchio data)."""

    def __init__(self, dynamics: ArmDynamics, limits: ArmLimits, cycle_time_s: float) -> None:
        self.servo = CartesianServo(dynamics, limits)
        self.cycle_time_s = cycle_time_s
        self.last: CartesianStep | None = None
        self._acceleration_limit = RAMP_SHARE * limits.max_acceleration
        self._velocity = np.zeros(limits.dof)       # of the targets, per joint, over the last step
        self._twist = np.zeros(6)                   # the tool's (base frame) asked of the servo in the last step
        self._line: pin.SE3 | None = None           # where a twist stream's twists integrate to, while not slowed

    def step(self, state: JointState, followed: tuple[int, np.ndarray] | None, timeout_s: float, now_ns: int,
             asked: TwistFunction, twist_stream: bool = True) -> tuple[ServoStep, StepReason, float]:
        """The next target from the reference (`followed`: the session and last position target of the stream the
        core follows, else the command position of `state`) at `now_ns`, why it is slower than asked, and the
        period it covers (0: the last target, nothing new), as the module says. A twist stream keeps to the line
        its twists integrate to; a pose stream (`twist_stream` False) only ramps speeding up."""
        last = self.last
        if (followed is not None and last is not None and last.session == followed[0]
                and np.array_equal(last.target, followed[1])):
            period = min((now_ns - last.monotonic_ns) * 1e-9, timeout_s)
            if period <= 0.0:   # the clock has not moved: the same target
                return ServoStep(last.target, last.scale, "", last.singular_value), last.reason, 0.0
        else:   # a new stream, or one a joint sample led: start from the arm's commanded motion
            period = self.cycle_time_s
            self._velocity = state.command_velocity.copy()
            position = state.command_position
            self._twist = _difference(self.servo.tool_pose(position),
                                      self.servo.tool_pose(position + self._velocity * period)) / period
            self._line = None
        reference = followed[1] if followed is not None else state.command_position
        here = self.servo.tool_pose(reference)
        wanted = asked(self.servo, reference, period)
        correction = np.zeros(6) if self._line is None else _difference(here, self._line) / period
        step = self.servo.twist_step(reference, wanted + correction, period)
        share = self._reachable_share((step.q - reference) / period, period, twist_stream)
        twist = wanted if share >= 1.0 else self._twist + share * (wanted - self._twist)
        if share < 1.0:
            step = self.servo.twist_step(reference, twist + correction, period)
        velocity = (step.q - reference) / period
        braking = self._braking_share(step, velocity, period)
        velocity *= braking
        target = reference + velocity * period
        self._velocity = velocity
        self._twist = twist   # as asked of the servo: its slowing, a function of where the arm is, applies once
        slowed = braking < 1.0 or step.scale < 1.0
        self._line = _advanced(self._line or here, twist, period) if twist_stream and not slowed else None
        size = float(np.linalg.norm(wanted))
        ramped = min(1.0, float(np.linalg.norm(twist)) / size) if size > 0.0 else 1.0
        scale = ramped * step.scale * braking
        reason: StepReason = step.reason
        if braking < 1.0:
            reason = "singularity"
        elif ramped < 1.0 and step.scale >= 1.0:   # the servo's own slowing, when there is any, causes it
            reason = "acceleration"
        return ServoStep(target, scale, step.reason, step.singular_value), reason, period

    def _braking_share(self, step: ServoStep, velocity: np.ndarray, period: float) -> float:
        """The share of a step that lowers σ (the tool Jacobian's smallest singular value) that can still brake,
        at the ramp's deceleration, before σ reaches the servo's stop: σ falls about σ̇·t/2 while every joint
        brakes within t = max |q̇ᵢ| / aᵢ, and both σ̇ and t scale with the share, so the share is the square root
        of the room over that fall. Joint speeds grow as σ falls, and the servo's own slowing near the stop would
        leave the joints too fast to stop on their targets."""
        after = self.servo.twist_step(step.q, np.zeros(6), period).singular_value   # σ where the step ends
        falling = (step.singular_value - after) / period
        if falling <= 0.0:
            return 1.0
        brake_time = float(np.max(np.abs(velocity) / self._acceleration_limit))
        room = after - self.servo.settings.stop_singular_value
        return 0.0 if room <= 0.0 else min(1.0, float(np.sqrt(2.0 * room / (falling * brake_time))))

    def _reachable_share(self, velocity: np.ndarray, period: float, ramp_down: bool) -> float:
        """The largest share (at most 1) of the way from the last step's joint velocities to `velocity` that keeps
        every joint's change (only speeding up without `ramp_down`) within the ramp's acceleration."""
        allowed = self._acceleration_limit * period
        change = (np.abs(velocity - self._velocity) if ramp_down
                  else np.maximum(np.abs(velocity) - np.abs(self._velocity), 0.0))
        over = change > allowed
        return float(np.min(allowed[over] / change[over])) if over.any() else 1.0

    def streamed(self, sample: int, session: int, step: ServoStep, reason: StepReason, period_s: float,
                 monotonic_ns: int) -> CartesianStep:
        """Keep (and return) what a call streamed."""
        self.last = CartesianStep(sample, session, step.q, period_s, step.scale, reason, step.singular_value,
                                  monotonic_ns)
        return self.last
