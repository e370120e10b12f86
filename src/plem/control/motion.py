"""Jerk-limited motions: point-to-point moves planned with ruckig, smooth stops planned by the compiled core.

Both are planned once (time-optimal within the velocity, acceleration and jerk limits) and then sampled
each cycle. A motion is anything with `sample(t, out) -> done`
and `duration`; the trajectory controller's splines have the same shape.
"""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np
from ruckig import InputParameter, Ruckig, Trajectory

from plem.control import compiled, ruckig_results
from plem.control.limits import ArmLimits
from plem.control.polynomial import ORDER, PolynomialMotion, from_ruckig
from plem.errors import CommandRejected
from plem.ipc.request_bounds import MIN_SPEED_SCALE

#: Where a motion starts: position, velocity and acceleration per joint.
StartState = tuple[np.ndarray, np.ndarray, np.ndarray]


class Motion(Protocol):
    """A planned motion sampled by the loop; `t` is seconds since the motion became active."""

    duration: float
    final_positions: np.ndarray

    def state_at(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity and acceleration at `t` as new arrays; safe to call from any thread."""
        ...

    def sample(self, t: float, out: np.ndarray) -> bool:
        """Write position, velocity and acceleration at `t` into the rows of `out` (3, dof); True once `t` is at
        or past the end."""
        ...


class RuckigMotion:
    """A ruckig trajectory; sampling copies ruckig's state into the loop's arrays."""

    def __init__(self, trajectory: Trajectory) -> None:
        self._trajectory = trajectory
        self.duration = float(trajectory.duration)
        self.final_positions = np.array(trajectory.at_time(self.duration)[0])

    def state_at(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity and acceleration at `t` (clamped to the motion) as new arrays."""
        p, v, a = self._trajectory.at_time(min(max(t, 0.0), self.duration))
        return np.array(p), np.array(v), np.array(a)

    def sample(self, t: float, out: np.ndarray) -> bool:
        """Write the state at `t` into the rows of `out` (3, dof); True once the motion is over."""
        done = t >= self.duration
        out[0], out[1], out[2] = self._trajectory.at_time(self.duration if done else t)
        return done

    def polynomial(self) -> PolynomialMotion:
        """The same motion as a piecewise polynomial, the form in which motions travel to an RT driver."""
        return from_ruckig(self._trajectory, len(self.final_positions))

    def position_range(self) -> tuple[np.ndarray, np.ndarray]:
        """Lowest and highest position each joint passes through."""
        extrema = self._trajectory.position_extrema
        return np.array([e.min for e in extrema]), np.array([e.max for e in extrema])


#: ruckig plans this far inside the limits, so that rounding in the piecewise-polynomial form never crosses them.
INSIDE = 1.0 - 1e-6
#: The share of the acceleration and jerk limits a point-to-point motion uses: the rest is the room the speed override
#: needs to slow the motion down at any moment of it (see plem_override in the core).
OVERRIDE_ROOM = 0.9
#: How far past a position limit ruckig's extrema may lie from rounding alone (rad).
POSITION_ROUNDING = 1e-9


def _input(limits: ArmLimits, position: np.ndarray, velocity: np.ndarray, acceleration: np.ndarray,
           scale: float) -> InputParameter:
    parameters = InputParameter(limits.dof)
    parameters.current_position = position.tolist()
    parameters.current_velocity = velocity.tolist()
    parameters.current_acceleration = acceleration.tolist()
    parameters.max_velocity = (limits.max_velocity * scale * INSIDE).tolist()
    parameters.max_acceleration = (limits.max_acceleration * scale**2 * OVERRIDE_ROOM).tolist()
    parameters.max_jerk = (limits.max_jerk * scale**3 * OVERRIDE_ROOM).tolist()
    return parameters


def _calculate(parameters: InputParameter, dof: int, what: str) -> RuckigMotion:
    trajectory = Trajectory(dof)
    ruckig_results.calculate(Ruckig(dof), parameters, trajectory, what)
    return RuckigMotion(trajectory)


def plan_point_to_point(limits: ArmLimits, start: StartState, target: np.ndarray,
                        speed_scale: float = 1.0, minimum_duration: float = 0.0) -> RuckigMotion:
    """Time-optimal motion from `start` (position, velocity, acceleration) to rest at `target`.

    `speed_scale` in [MIN_SPEED_SCALE, 1] scales time: velocity, acceleration and jerk limits by s, s² and s³, so
    the motion follows the same path and takes 1/s as long; the motion takes at least `minimum_duration` s.
    The target must lie within the position limits, and so must every position the motion passes through; a joint
    that starts outside its range may end anywhere between there and its range (`ArmLimits.reaching`).
    """
    limits = limits.reaching(start[0])
    if not (isinstance(speed_scale, (int, float)) and not isinstance(speed_scale, bool)
            and math.isfinite(speed_scale) and MIN_SPEED_SCALE <= speed_scale <= 1):
        raise CommandRejected("speed_scale is out of range", what=f"{MIN_SPEED_SCALE:g} <= speed_scale <= 1",
                              why=f"got {speed_scale!r}",
                              how=f"pass e.g. speed_scale=0.5 for half speed; {MIN_SPEED_SCALE:g} is the slowest "
                                  f"({1 / MIN_SPEED_SCALE:g} times as long as at full speed)")
    if not np.all(np.isfinite(limits.max_velocity)):
        unlimited = [n for n, v in zip(limits.joint_names, limits.max_velocity, strict=True) if not math.isfinite(v)]
        raise CommandRejected("move_joints needs a velocity limit for every joint",
                              what="max_velocity for each joint in config/joint_limits.yaml",
                              why=f"no velocity limit for {', '.join(unlimited)}",
                              how="add has_velocity_limits: true and max_velocity to those joints")
    limits.check_positions(target, "the target")
    parameters = _input(limits, *start, scale=float(speed_scale))
    parameters.target_position = target.tolist()
    if minimum_duration > 0.0:
        parameters.minimum_duration = minimum_duration
    motion = _calculate(parameters, limits.dof, "the point-to-point motion")
    low, high = motion.position_range()
    limits.check_positions(np.where(low < limits.min_position, low, high), "the motion toward the target",
                           tolerance=POSITION_ROUNDING)
    return motion


def plan_stop(limits: ArmLimits, start: StartState) -> PolynomialMotion:
    """The quickest jerk-limited motion from `start` to standstill (used for cancels and faults): the core's stop,
    each joint braking on its own within its acceleration and jerk limits."""
    position, velocity, acceleration = (np.ascontiguousarray(value, dtype=float) for value in start)
    dof = limits.dof
    knots = np.zeros(compiled.STOP_SEGMENTS + 1)
    coefficients = np.zeros((compiled.STOP_SEGMENTS, ORDER, dof))
    final = np.zeros((3, dof))
    segments = compiled.core.plan_stop(position, velocity, acceleration, limits.max_acceleration * INSIDE,
                                       limits.max_jerk * INSIDE, knots, coefficients, final)
    return PolynomialMotion(knots[:segments + 1], coefficients[:segments], final)
