"""Time parameterisation of a planned joint-space path within the position, velocity, acceleration and jerk limits.

A path is a list of states without times. A planner's path is followed along its straight joint-space lines,
which are what the planner checked for collisions: each line is run with ruckig's time-optimal jerk-limited
profile, at rest at every corner (a corner cannot be passed at speed without leaving the lines). A smooth
dense path, such as a Cartesian straight line, is given the fastest times its velocity limits allow and
handed to `fit_to_limits`, the re-timing every trajectory sent to plem gets, which smooths and slows it.
Either result, written out as a trajectory with positions, velocities and accelerations at every knot, is
the same piecewise polynomial again when plem reads it back: it runs as sent.

Plans keep LIMIT_SHARE of each limit, so the same trajectory read back from a ROS message (times rounded to
nanoseconds) still runs as sent rather than being re-timed.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from ruckig import InputParameter, Ruckig, Trajectory

from plem.control.limits import ArmLimits
from plem.control.ruckig_results import calculate
from plem.control.spline import Spline
from plem.control.trajectory import JointTrajectory, TrajectoryPoint
from plem.planning.retiming import along_straight_lines, fit_to_limits

#: Share of each velocity, acceleration and jerk limit a plan may use.
LIMIT_SHARE = 0.99
#: Shortest time given to a step between two states (s), so that no two points share a time.
MINIMUM_STEP_S = 1e-3


def planning_limits(limits: ArmLimits, velocity_scale: float = 1.0, acceleration_scale: float = 1.0) -> ArmLimits:
    """The limits a plan keeps: LIMIT_SHARE of the arm's, scaled as MoveIt's max_velocity_scaling_factor and
    max_acceleration_scaling_factor scale them (the acceleration factor scales jerk too)."""
    return replace(limits, max_velocity=limits.max_velocity * velocity_scale * LIMIT_SHARE,
                   max_acceleration=limits.max_acceleration * acceleration_scale * LIMIT_SHARE,
                   max_jerk=limits.max_jerk * acceleration_scale * LIMIT_SHARE)


def parameterise(states: np.ndarray, limits: ArmLimits, cycle_time_s: float, *, straight: bool = False) -> Spline:
    """A motion from rest at states[0] through every state to rest at the last, within `limits`: smooth through
    the states, or with `straight` exactly along the straight lines between them, at rest at each state."""
    steps = np.abs(np.diff(states, axis=0)) / limits.max_velocity
    times = np.concatenate([[0.0], np.cumsum(np.maximum(steps.max(axis=1), MINIMUM_STEP_S))])
    trajectory = JointTrajectory(limits.joint_names, tuple(
        TrajectoryPoint(tuple(map(float, positions)), float(t)) for positions, t in zip(states, times, strict=True)))
    start = (states[0].copy(), np.zeros(limits.dof), np.zeros(limits.dof))
    if straight:
        return along_straight_lines(trajectory, limits, start, cycle_time_s)
    return fit_to_limits(trajectory, limits, start, cycle_time_s).motion


def to_trajectory(motion: Spline) -> JointTrajectory:
    """The motion as trajectory points at every knot, with positions, velocities and accelerations."""
    points = []
    for t in motion.knots:
        positions, velocities, accelerations = motion.state_at(float(t))
        points.append(TrajectoryPoint(tuple(map(float, positions)), float(t), tuple(map(float, velocities)),
                                      tuple(map(float, accelerations))))
    return JointTrajectory(motion.joint_names, tuple(points))


def duration_bound(states: np.ndarray, limits: ArmLimits) -> float:
    """A lower bound on any rest-to-rest motion through `states` in order: each joint must travel at least the sum
    of its steps, and the fastest it can from rest to rest is ruckig's time-optimal profile over that distance."""
    travel = np.abs(np.diff(states, axis=0)).sum(axis=0)
    bound = 0.0
    for distance, velocity, acceleration, jerk in zip(travel, limits.max_velocity, limits.max_acceleration,
                                                       limits.max_jerk, strict=True):
        if distance <= 0.0:
            continue
        parameters = InputParameter(1)
        parameters.current_position, parameters.target_position = [0.0], [float(distance)]
        parameters.max_velocity, parameters.max_acceleration = [float(velocity)], [float(acceleration)]
        parameters.max_jerk = [float(jerk)]
        profile = Trajectory(1)
        calculate(Ruckig(1), parameters, profile, "the bound on the path's duration")
        bound = max(bound, float(profile.duration))
    return bound
