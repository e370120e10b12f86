"""Cartesian streaming (`servo_pose`, `speed_tool`): each call runs one Cartesian servo step from the joint
reference and streams its joint target, so the core's follower keeps every limit.

The reference is the last position target streamed while the core follows that stream (successive steps integrate
on the targets, not on the arm lagging behind them), else the arm's command position. A call covers the time since
the previous Cartesian call of the same stream on the loop's own clock (its cycle count), at most the stream's
timeout; the first call of a stream, or the first after a joint sample, covers one cycle, and a call in the same
cycle as the previous one streams the previous target again (a caller faster than the loop adds no speed).

The targets change speed smoothly, because the core's follower is jerk-limited per joint: a twist that jumps would
leave each joint lagging by its own amount and the tool off its line while they catch up. Each call moves the
tool's twist from its last one toward the one asked (for a pose, the servo's approach twist) only as far as keeps
every joint's target velocity changing by at most half its acceleration limit, that acceleration itself growing
by at most half the jerk limit; the twist in between stays on the line between the two, so a tool speeding up,
slowing or stopping keeps its path (a pose's approach twist, which slows by itself toward the pose, is limited
only while speeding up, so it does not overshoot). The servo's own slowing near singularities and joint limits is
applied to the twist reached, never delayed; and a step that lowers the Jacobian's smallest singular value is cut
so every joint can still brake, at that half of its acceleration limit, before it reaches the servo's stop (joint
speeds grow without bound toward a singularity, faster than the servo's slowing in σ alone can stop them).
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
#: The share of each joint's acceleration and jerk limits the targets change speed with (the rest is the
#: follower's).
RAMP_SHARE = 0.5
#: The base-frame tool twist a call asks for, from the joint reference (arm order) over the period it covers (s).
TwistFunction = Callable[[CartesianServo, np.ndarray, float], np.ndarray]


@dataclass(frozen=True)
class CartesianStep:
    """What one Cartesian streaming call streamed: the sample's number and stream session, the joint target, the
    period it covers (s; 0 when it repeats the previous target), the fraction of the asked speed it moves at, why
    that is below 1 ('' when it is not: 'singularity', 'joint limit', 'velocity limit', or 'acceleration' while
    the targets change speed), the smallest singular value of the tool Jacobian where it started, and the loop
    cycle it was computed at."""

    sample: int
    session: int
    target: np.ndarray
    period_s: float
    scale: float
    reason: StepReason
    singular_value: float
    cycle: int


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
        self._jerk_limit = RAMP_SHARE * limits.max_jerk
        self._velocity = np.zeros(limits.dof)       # of the targets, per joint, over the last step
        self._twist = np.zeros(6)                   # of the tool (base frame), over the last step
        self._speeding_up = np.zeros(limits.dof)    # how fast each joint's target speed grew in the last step

    def step(self, state: JointState, followed: tuple[int, np.ndarray] | None, timeout_s: float,
             asked: TwistFunction, ramp_down: bool = True) -> tuple[ServoStep, StepReason, float]:
        """The next target from the reference (`followed`: the session and last position target of the stream the
        core follows, else the command position of `state`), why it is slower than asked, and the period it
        covers, as the module says; without `ramp_down` only speeding up is limited (a pose's approach twist
        slows by itself, and must not overshoot)."""
        last = self.last
        if (followed is not None and last is not None and last.session == followed[0]
                and np.array_equal(last.target, followed[1])):
            cycles = state.cycle - last.cycle
            if cycles <= 0:
                return ServoStep(last.target, last.scale, "", last.singular_value), last.reason, 0.0
            period = min(cycles * self.cycle_time_s, timeout_s)
        else:   # a new stream, or one a joint sample led: start from the arm's commanded motion
            period = self.cycle_time_s
            self._velocity, self._speeding_up = state.command_velocity.copy(), np.zeros_like(self._speeding_up)
            position = state.command_position
            self._twist = self._tool_twist(position, position + self._velocity * period, period)
        reference = followed[1] if followed is not None else state.command_position
        wanted = asked(self.servo, reference, period)
        full = self.servo.twist_step(reference, wanted, period)
        share = self._reachable_share((full.q - reference) / period, period, ramp_down)
        twist = wanted if share >= 1.0 else self._twist + share * (wanted - self._twist)
        step = full if share >= 1.0 else self.servo.twist_step(reference, twist, period)
        velocity = (step.q - reference) / period
        braking = self._braking_share(step, velocity, period)
        velocity *= braking
        target = reference + velocity * period
        self._speeding_up = np.abs(velocity - self._velocity) / period
        self._velocity = velocity
        self._twist = self._tool_twist(reference, target, period)
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
        every joint's change (only speeding up without `ramp_down`) within the ramp's acceleration, itself grown
        within the ramp's jerk."""
        acceleration = np.minimum(self._acceleration_limit, self._speeding_up + self._jerk_limit * period)
        allowed = acceleration * period
        change = (np.abs(velocity - self._velocity) if ramp_down
                  else np.maximum(np.abs(velocity) - np.abs(self._velocity), 0.0))
        over = change > allowed
        return float(np.min(allowed[over] / change[over])) if over.any() else 1.0

    def _tool_twist(self, start: np.ndarray, end: np.ndarray, period: float) -> np.ndarray:
        """The tool's base-frame twist moving from joint positions `start` to `end` in `period`."""
        before, after = self.servo.tool_pose(start), self.servo.tool_pose(end)
        twist: np.ndarray = np.concatenate([after.translation - before.translation,
                                            pin.log3(after.rotation @ before.rotation.T)]) / period
        return twist

    def streamed(self, sample: int, session: int, step: ServoStep, reason: StepReason, period_s: float,
                 cycle: int) -> CartesianStep:
        """Keep (and return) what a call streamed."""
        self.last = CartesianStep(sample, session, step.q, period_s, step.scale, reason, step.singular_value, cycle)
        return self.last
