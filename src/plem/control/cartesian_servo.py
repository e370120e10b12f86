"""One step of Cartesian servoing: the next joint target for a tool twist or pose, slowed near singularities and
joint limits, as moveit_servo does.

Each step solves the tool Jacobian by damped least squares (the damping grows smoothly as its smallest singular
value σ falls below `ServoSettings.slowdown_singular_value`), then scales the whole step by one factor so the
tool keeps its direction: toward a singularity it slows as σ falls and stops at `stop_singular_value`; a joint
heading toward a position limit slows within `joint_limit_margin` and stops `joint_limit_stop` before it; no
joint exceeds its velocity limit. The factor and the reason for the smallest one come back with the target.

A pose target becomes the twist that brings the tool to it along a straight line (orientation along the
geodesic), at most `max_linear_speed` and `max_angular_speed`, slowing near it as a constant deceleration
would, so successive steps approach it monotonically and land on it.

σ mixes metres and radians (the Jacobian's linear rows are m/rad, its angular rows rad/rad), as moveit_servo's
condition number does; the thresholds are set for arms of about a metre's reach. Whether a step moves toward a
singularity is the sign of dσ/dt along it, from the analytic derivative of σ (no second Jacobian).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
import pinocchio as pin

from plem.control.kinematics import ArmDynamics, link_frame
from plem.control.limits import ArmLimits
from plem.errors import CommandRejected, ConfigError

#: Why a step was slowed: nothing, the tool's approach to a singularity, a joint near its position limit, or a
#: joint at its velocity limit.
SlowReason = Literal["", "singularity", "joint limit", "velocity limit"]
#: The frame of a twist: the arm's base, or the tool (its linear part is the tool point's velocity either way).
TwistFrame = Literal["base", "tool"]


@dataclass(frozen=True)
class ServoSettings:
    """Thresholds and speeds of Cartesian servoing (SI units)."""

    #: Smallest singular value of the tool Jacobian below which steps toward a singularity slow and the least
    #: squares are damped (moveit_servo's lower_singularity_threshold, as a singular value).
    slowdown_singular_value: float = 0.08
    #: Smallest singular value at which steps toward a singularity stop (moveit_servo's
    #: hard_stop_singularity_threshold): the Indy7's elbow or wrist stops about 0.15 rad (9°) before straight.
    stop_singular_value: float = 0.04
    #: Damping λ of the least squares at σ = 0, falling smoothly to none at `slowdown_singular_value`.
    damping: float = 0.04
    #: Distance (rad, or m for a prismatic joint) from a position limit inside which a joint moving toward it
    #: slows (moveit_servo's joint_limit_margins).
    joint_limit_margin: float = 0.1
    #: Distance from a position limit at which a joint moving toward it stops.
    joint_limit_stop: float = 0.01
    #: Fastest tool speed toward a pose target (m/s, rad/s).
    max_linear_speed: float = 0.25
    max_angular_speed: float = 1.0
    #: Deceleration of the tool as it comes to a pose target (m/s², rad/s²).
    linear_deceleration: float = 1.0
    angular_deceleration: float = 2.0

    def __post_init__(self) -> None:
        problems = [f"{name} = {value!r} is not a positive number" for name, value in vars(self).items()
                    if not (isinstance(value, int | float) and math.isfinite(value) and value > 0)]
        if not problems and self.stop_singular_value >= self.slowdown_singular_value:
            problems.append(f"stop_singular_value {self.stop_singular_value:g} is not below slowdown_singular_value "
                            f"{self.slowdown_singular_value:g}")
        if not problems and self.joint_limit_stop >= self.joint_limit_margin:
            problems.append(f"joint_limit_stop {self.joint_limit_stop:g} is not below joint_limit_margin "
                            f"{self.joint_limit_margin:g}")
        if problems:
            raise ConfigError("invalid Cartesian servo settings",
                              what="positive, finite thresholds, speeds and decelerations; each stop below where "
                                   "its slowing starts",
                              why="; ".join(problems),
                              how="pass ServoSettings(...) with those values corrected, or leave them at their "
                                  "defaults")


@dataclass(frozen=True)
class ServoStep:
    """The next joint target (the arm's joint order), the fraction of the asked speed it moves at, why it is
    slower ('' when it is not), and the smallest singular value of the tool Jacobian where it started."""

    q: np.ndarray
    scale: float
    reason: SlowReason
    singular_value: float


def _ramp(remaining: float, width: float) -> float:
    """The speed fraction `remaining` before a stop, slowing over `width`: the square root of the remaining
    fraction, as a constant deceleration gives, so a stop is reached in finite time rather than crept toward."""
    return math.sqrt(min(max(remaining / width, 0.0), 1.0))


def _braking_speed(room: float, deceleration: float, dt: float) -> float:
    """The fastest speed that can still stop within `room` slowing by `deceleration`·dt each step of `dt`: k steps
    of k·a·dt, (k-1)·a·dt, ... cover a·dt²·k(k+1)/2, solved for k (about √(2·a·room) when room is large)."""
    if math.isinf(deceleration):
        return math.inf
    step = deceleration * dt
    return step * (math.sqrt(0.25 + 2.0 * room / (step * dt)) - 0.5)


class CartesianServo:
    """Steps of Cartesian servoing of one arm's tool link; one instance per thread (it keeps pinocchio data)."""

    def __init__(self, dynamics: ArmDynamics, limits: ArmLimits, settings: ServoSettings | None = None,
                 tool_link: str | None = None) -> None:
        self.settings = settings or ServoSettings()
        self.model = dynamics.model
        self.data = self.model.createData()
        self.space = dynamics.space
        self.frame = link_frame(self.model, tool_link or dynamics.tip_frame)
        #: Indices that gather arm-order values into pinocchio's order (chain order, parents first), and back.
        self._to_model = np.argsort(dynamics.model_indices)
        self._to_arm = dynamics.model_indices
        self._limits = limits
        self._lower = limits.min_position[self._to_model].tolist()
        self._upper = limits.max_position[self._to_model].tolist()
        self._max_velocity = limits.max_velocity[self._to_model].tolist()
        self._max_acceleration = limits.max_acceleration[self._to_model].tolist()
        #: 1 where joint k comes after joint i in the chain (k > i), for the derivative of the Jacobian.
        self._later = np.triu(np.ones((dynamics.dof, dynamics.dof)), 1)

    def tool_pose(self, q: np.ndarray) -> pin.SE3:
        """The tool link's pose in the base frame at positions `q` (arm order), a copy."""
        pin.forwardKinematics(self.model, self.data, self.space.configuration(self._model_order(q)))
        return pin.updateFramePlacement(self.model, self.data, self.frame).copy()

    def twist_step(self, q: np.ndarray, twist: np.ndarray, dt: float, frame: TwistFrame = "base") -> ServoStep:
        """The target `dt` seconds on from positions `q` (arm order) moving the tool at `twist` (vx, vy, vz in
        m/s, then ωx, ωy, ωz in rad/s) in the base or tool frame's axes, slowed as the module says."""
        positions = self._model_order(q)
        jacobian, placement = self._jacobian(positions)
        velocity = np.asarray(twist, dtype=float)
        if frame == "tool":
            rotation = placement.rotation
            velocity = np.concatenate([rotation @ velocity[:3], rotation @ velocity[3:]])
        return self._step(positions, jacobian, velocity, dt)

    def pose_step(self, q: np.ndarray, target: pin.SE3, dt: float) -> ServoStep:
        """The target `dt` seconds on from positions `q` (arm order) bringing the tool to `target` (a pose in the
        base frame) along a straight line, within the tool speeds and decelerations of the settings."""
        positions = self._model_order(q)
        jacobian, placement = self._jacobian(positions)
        return self._step(positions, jacobian, self.approach_twist(placement, target, dt), dt)

    def approach_twist(self, current: pin.SE3, target: pin.SE3, dt: float) -> np.ndarray:
        """The base-frame twist from tool pose `current` toward `target`: the whole way in `dt` when that is within
        the speeds, else at the top speed or the speed that still stops at the target, whichever is lower; linear
        and angular parts scaled together so both arrive at once."""
        settings = self.settings
        error = np.concatenate([target.translation - current.translation,
                                pin.log3(target.rotation @ current.rotation.T)])
        distance, angle = float(np.linalg.norm(error[:3])), float(np.linalg.norm(error[3:]))
        rate = 1.0 / dt    # 1/s: the fraction of the error covered per second
        if distance > 0.0:
            rate = min(rate, settings.max_linear_speed / distance,
                       math.sqrt(2.0 * settings.linear_deceleration / distance))
        if angle > 0.0:
            rate = min(rate, settings.max_angular_speed / angle,
                       math.sqrt(2.0 * settings.angular_deceleration / angle))
        twist: np.ndarray = rate * error
        return twist

    def _model_order(self, q: np.ndarray) -> np.ndarray:
        """Positions `q` (arm order: one finite number per joint, else CommandRejected) in pinocchio's order."""
        positions = np.asarray(q, dtype=float)
        if positions.shape != (self._limits.dof,) or not np.isfinite(positions).all():
            positions = self._limits.check_vector(q, "the servo's joint positions")   # raises, naming the fault
        ordered: np.ndarray = positions[self._to_model]
        return ordered

    def _jacobian(self, positions: np.ndarray) -> tuple[np.ndarray, pin.SE3]:
        """The tool's Jacobian in the base frame's axes at the tool point (columns in pinocchio's order), and the
        tool's pose, from one pass of pinocchio's kinematics."""
        pin.computeJointJacobians(self.model, self.data, self.space.configuration(positions))
        placement = pin.updateFramePlacement(self.model, self.data, self.frame)
        jacobian = pin.getFrameJacobian(self.model, self.data, self.frame, pin.LOCAL_WORLD_ALIGNED)
        return jacobian, placement

    def _step(self, positions: np.ndarray, jacobian: np.ndarray, velocity: np.ndarray, dt: float) -> ServoStep:
        """The scaled damped-least-squares step for base-frame tool `velocity` (positions in pinocchio's order)."""
        if velocity.shape != (6,) or not np.isfinite(velocity).all() or not (dt > 0.0 and math.isfinite(dt)):
            raise self._refused(velocity, dt)
        settings = self.settings
        u, singular, vt = np.linalg.svd(jacobian, full_matrices=False)
        sigma = float(singular[-1])
        slow, stop = settings.slowdown_singular_value, settings.stop_singular_value
        damping = settings.damping ** 2 * max(0.0, 1.0 - (sigma / slow) ** 2)
        rates = vt.T @ (singular / (singular ** 2 + damping) * (u.T @ velocity))
        scales: list[tuple[float, SlowReason]] = [(1.0, "")]
        if sigma < slow:
            approach = float(self._singular_value_gradient(jacobian, u[:, -1], vt[-1]) @ rates)
            if approach < 0.0:   # the step lowers σ: slow toward the stop, and never step past it
                scales.append((min(_ramp(sigma - stop, slow - stop), max(sigma - stop, 0.0) / (-approach * dt)),
                               "singularity"))
        scales.append(self._limit_scale(positions.tolist(), rates.tolist(), dt))
        scale, reason = min(scales, key=lambda item: item[0])
        next_positions = positions + rates * (scale * dt)
        return ServoStep(next_positions[self._to_arm], scale, reason, sigma)

    @staticmethod
    def _refused(velocity: np.ndarray, dt: float) -> CommandRejected:
        """The refusal of a step whose twist, target or period is not finite or not of its shape."""
        if not (dt > 0.0 and math.isfinite(dt)):
            found = f"the period is {dt!r} s"
        elif velocity.shape != (6,):
            found = f"the twist has {velocity.size} values"
        else:
            found = "the twist (or the pose target it comes from) is not all finite"
        return CommandRejected("Cartesian servo step refused", what="a twist of 6 finite numbers (vx, vy, vz in m/s, "
                               "then wx, wy, wz in rad/s) or a finite pose target, and a positive period",
                               why=found, how="send finite values of that shape")

    def _limit_scale(self, positions: list[float], rates: list[float], dt: float) -> tuple[float, SlowReason]:
        """The largest fraction of joint `rates` (and why it is below 1) that keeps every joint within its velocity
        limit and every joint heading toward a position limit slowing within the margin, able to stop at its
        acceleration limit, and short of the stop distance after this step (Python floats: faster than numpy
        for a handful of joints)."""
        settings = self.settings
        width = settings.joint_limit_margin - settings.joint_limit_stop
        scale: float = 1.0
        reason: SlowReason = ""
        for rate, position, low, high, top, brake in zip(rates, positions, self._lower, self._upper,
                                                          self._max_velocity, self._max_acceleration, strict=True):
            speed = abs(rate)
            if speed == 0.0:
                continue
            if top < speed * scale:
                scale, reason = top / speed, "velocity limit"
            room = (high - position if rate > 0.0 else position - low) - settings.joint_limit_stop
            if room < width or room < 0.5 * rate * rate / brake:
                limited = 0.0 if room <= 0.0 else min(_ramp(room, width), _braking_speed(room, brake, dt) / speed,
                                                      room / (speed * dt))
                if limited < scale:
                    scale, reason = limited, "joint limit"
        return scale, reason

    def _singular_value_gradient(self, jacobian: np.ndarray, left: np.ndarray, right: np.ndarray) -> np.ndarray:
        """dσ/dq of the smallest singular value σ (left and right singular vectors `left`, `right`) of the tool's
        Jacobian, per degree of freedom in pinocchio's order.

        The tool-frame Jacobian's columns change only with later joints: ∂J_i/∂q_k = J_i × J_k (the motion cross
        product) for k > i. Turning every row by the tool's rotation changes neither σ nor a cross product, so
        in the base frame's axes too ∂σ/∂q_k = Σ_{i<k} right_i · leftᵀ (J_i × J_k), where
        leftᵀ (a × b) = P(a) · b with P(a) = (l_v × a_ω, l_v × a_v + l_ω × a_ω).
        """
        linear, angular = jacobian[:3], jacobian[3:]
        cross_v, cross_w = pin.skew(left[:3]), pin.skew(left[3:])
        products = (cross_v @ angular).T @ linear + (cross_v @ linear + cross_w @ angular).T @ angular
        gradient: np.ndarray = right @ (products * self._later)
        return gradient
