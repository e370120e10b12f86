"""The spline a JointTrajectory describes, interpolated per segment as ros2_control's joint_trajectory_controller does.

A segment is linear in position when either end has positions only, a cubic Hermite when both ends carry
velocities, and a quintic when both ends carry velocities and accelerations. When the first point lies
after t = 0, a first segment runs from the state at activation; that state always has all three, so the
first point alone decides the first segment's kind (a positions-only first point interpolates linearly
from the start positions and ignores the start velocity, a jump `check_limits` judges). A point with
accelerations but no velocities is rejected: the controller would interpolate nothing sensible for it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.polynomial import polynomial

from plem.control.limits import KINDS, ArmLimits, limit_exceeded
from plem.control.polynomial import ORDER, PolynomialMotion, derivative_stack, hermite_coefficients, segment_ranges
from plem.description.limits import UNITS
from plem.errors import CommandRejected

if TYPE_CHECKING:
    from plem.control.trajectory import JointTrajectory, TrajectoryPoint

#: A first point at time 0 must sit this close to the start positions (rad): the current state a client read
#: from joint_states differs from the command by the tracking error and the encoder's resolution. MoveIt's
#: trajectory execution allows the same by default (allowed_start_tolerance).
START_TOLERANCE = 0.01
#: The last point's velocities and accelerations must be this close to zero.
AT_REST = 1e-6
#: Relative slack on every limit, for rounding in the polynomial evaluation.
SLACK = 1e-9

FIELDS_HOW = ("send positions for every point; velocities and accelerations are optional but, when given, "
              "need one value per joint")
SMOOTH_HOW = ("add velocities and accelerations to the points so the spline is smooth at every point (quintic), "
              "give the motion more time (later time_from_start), or use move_joints for point-to-point motion")
SLOWER_HOW = "give the motion more time (later time_from_start), or use move_joints for point-to-point motion"


class JointNamesRejected(CommandRejected):
    """The trajectory's joint names are not exactly the arm's joints (FollowJointTrajectory INVALID_JOINTS)."""


def beyond(value: np.ndarray | float, limit: np.ndarray | float) -> np.ndarray | bool:
    """Whether `value` exceeds the upper bound `limit` by more than the rounding slack (elementwise)."""
    return value > limit + SLACK * np.maximum(1.0, np.abs(limit))


def _joint_order(joint_names: Sequence[str], limits: ArmLimits) -> np.ndarray:
    """For each arm joint, its column in the trajectory; every arm joint exactly once, nothing else."""
    names = list(joint_names)
    found = {"listed more than once": sorted({name for name in names if names.count(name) > 1}),
             "not joints of this arm": [name for name in names if name not in limits.joint_names],
             "missing": [name for name in limits.joint_names if name not in names]}
    problems = [f"{problem}: {', '.join(joints)}" for problem, joints in found.items() if joints]
    if problems:
        raise JointNamesRejected(
            "the trajectory's joint_names do not match the arm's joints",
            what=f"each of {', '.join(limits.joint_names)} exactly once, in any order",
            why="; ".join(problems),
            how="send one column per arm joint (partial trajectories are not accepted), named as in the URDF")
    return np.array([names.index(name) for name in limits.joint_names])


def _field(values: Sequence[float], index: int, field: str, joint_names: Sequence[str],
           order: np.ndarray) -> np.ndarray:
    """One point's positions, velocities or accelerations: finite, one per joint, in the arm's order."""
    dof = len(joint_names)
    try:
        array = np.asarray(values, dtype=float)
    except (TypeError, ValueError) as error:
        raise CommandRejected(f"point {index} {field} are not numbers", what=f"{dof} numbers",
                              why=str(error), how=FIELDS_HOW) from error
    if array.shape != (dof,):
        raise CommandRejected(f"point {index} has {array.size} {field} for {dof} joints",
                              what=f"one value per joint ({', '.join(joint_names)})",
                              why=f"point {index} {field} has shape {array.shape}", how=FIELDS_HOW)
    bad = [joint_names[int(j)] for j in np.flatnonzero(~np.isfinite(array))]
    if bad:
        raise CommandRejected(f"point {index} {field} contain NaN or infinity", what="finite numbers only",
                              why=f"point {index} {field} not finite for {', '.join(bad)}",
                              how="send finite values")
    in_arm_order: np.ndarray = array[order]
    return in_arm_order


def _time(point: TrajectoryPoint, index: int, previous: float) -> float:
    """A point's time_from_start: finite, not negative, after the previous point's."""
    try:
        time = float(point.time_from_start)
    except (TypeError, ValueError):
        why = f"point {index} has time_from_start {point.time_from_start!r}"
    else:
        if not (math.isfinite(time) and time >= 0.0):
            why = f"point {index} has time_from_start {time:.9g} s"
        elif time <= previous:
            why = f"point {index - 1} is at {previous:.9g} s, point {index} at {time:.9g} s"
        else:
            return time
    raise CommandRejected(f"point {index} has an invalid time_from_start",
                          what="times_from_start in seconds: finite, >= 0 and strictly increasing from point to point",
                          why=why, how="give each point a later time_from_start than the one before it")


def _coefficients(times: np.ndarray, p: np.ndarray, v: np.ndarray, a: np.ndarray,
                  has_v: np.ndarray, has_a: np.ndarray) -> tuple[np.ndarray, tuple[str, ...]]:
    """Per-segment coefficients (segments, ORDER, dof) in time since the segment's start, and each segment's kind."""
    cubic = has_v[:-1] & has_v[1:]
    quintic = cubic & has_a[:-1] & has_a[1:]
    degree = np.where(quintic, 5, np.where(cubic, 3, 1))
    c = hermite_coefficients(np.diff(times)[:, None], p[:-1], p[1:], v[:-1], v[1:], a[:-1], a[1:], degree)
    kinds = tuple({5: "quintic", 3: "cubic", 1: "linear"}[int(d)] for d in degree)
    return c, kinds


def _extrema(coefficients: np.ndarray, duration: float) -> tuple[float, float, float, float]:
    """(min, time of min, max, time of max) of a polynomial on [0, duration], from its stationary points."""
    scaled = coefficients * duration ** np.arange(coefficients.size)  # in s = t / duration, s in [0, 1]
    slope = polynomial.polyder(scaled)
    candidates = [0.0, 1.0]
    significant = np.flatnonzero(np.abs(slope) > 1e-12 * np.abs(slope).max(initial=0.0))
    if significant.size:
        roots = polynomial.polyroots(slope[: significant[-1] + 1])
        real = roots.real[(np.abs(roots.imag) < 1e-6) & (roots.real > 0.0) & (roots.real < 1.0)]
        candidates.extend(real)
    s = np.array(candidates)
    values = polynomial.polyval(s, scaled)
    low, high = int(values.argmin()), int(values.argmax())
    return float(values[low]), float(s[low] * duration), float(values[high]), float(s[high] * duration)


def _near_beyond(value: np.ndarray, limit: np.ndarray) -> np.ndarray:
    """`beyond` with a little less slack, so that the exact check sees every case that might fail it."""
    finite = np.isfinite(limit)
    return value > np.where(finite, limit - SLACK * np.maximum(1.0, np.abs(np.where(finite, limit, 0.0))), limit)


def _suspect_jumps(limits: ArmLimits, steps: np.ndarray, cycle_time_s: float) -> np.ndarray:
    """Per knot, whether the velocity or acceleration steps within a cycle from it may exceed the next limit."""
    suspect = np.zeros(steps.shape[1], dtype=bool)
    for k in (1, 2):
        suspect |= _near_beyond(steps[k] / cycle_time_s, limits.maximum(KINDS[k + 1])).any(axis=1)
    return suspect


def _check_ends(states: np.ndarray, first_time: float, start: np.ndarray, joint_names: tuple[str, ...]) -> None:
    """A first point at time 0 must be where the arm is; the last point must be at rest."""
    if first_time == 0.0:
        offset = np.abs(states[0, 0] - start[0])
        if offset.max() > START_TOLERANCE:
            j = int(offset.argmax())
            raise CommandRejected(
                "point 0 has time_from_start 0 but is not where the arm is",
                what=f"a point at time 0 at the current positions (within {START_TOLERANCE:g} rad)",
                why=f"{joint_names[j]} is at {start[0, j]:.9g} rad, point 0 asks for {states[0, 0, j]:.9g} rad",
                how="give point 0 a time_from_start > 0 so the arm can get there, or start at the current positions")
    for k, field in ((1, "velocities"), (2, "accelerations")):
        moving = np.abs(states[-1, k]) > AT_REST
        if moving.any():
            j = int(np.flatnonzero(moving)[0])
            raise CommandRejected(
                f"the last point has non-zero {field}: the arm would have to stop abruptly",
                what=f"{field} of the last point zero (within {AT_REST:g})",
                why=f"point {len(states) - 1} has {field} {states[-1, k, j]:.6g} for {joint_names[j]}",
                how=f"end the trajectory at rest: set the last point's {field} to 0 (or leave them out)")


@dataclass(frozen=True, eq=False)
class Waypoints:
    """A validated trajectory in the arm's joint order, its knots as the spline runs through them.

    Knot 0 is the arm's state at activation when the first point lies after t = 0 (then `first_point` is 1);
    `states` holds position, velocity and acceleration per knot, zero where the point gives none.
    """

    joint_names: tuple[str, ...]
    times: np.ndarray
    states: np.ndarray
    has_velocities: np.ndarray
    has_accelerations: np.ndarray
    start: np.ndarray
    first_point: int

    @property
    def point_knots(self) -> np.ndarray:
        """The knot index of each trajectory point."""
        return np.arange(self.first_point, len(self.times))


def read_waypoints(trajectory: JointTrajectory, limits: ArmLimits, start_positions: Sequence[float] | np.ndarray,
                   start_velocities: Sequence[float] | np.ndarray,
                   start_accelerations: Sequence[float] | np.ndarray) -> Waypoints:
    """Validate `trajectory` against the arm and its state at activation; the knots in the arm's order."""
    order = _joint_order(trajectory.joint_names, limits)
    start = np.stack([limits.check_vector(start_positions, "the start positions"),
                      limits.check_vector(start_velocities, "the start velocities"),
                      limits.check_vector(start_accelerations, "the start accelerations")])
    if not trajectory.points:
        raise CommandRejected("the trajectory has no points", what="at least one point",
                              why="points is empty", how="add the points to move through")
    names = tuple(trajectory.joint_names)
    times: list[float] = []
    rows, has_v, has_a = [], [], []
    for index, point in enumerate(trajectory.points):
        if point.accelerations is not None and point.velocities is None:
            raise CommandRejected(f"point {index} has accelerations but no velocities",
                                  what="velocities wherever accelerations are given",
                                  why=f"point {index} carries positions and accelerations only",
                                  how="add velocities to the point, or drop its accelerations")
        times.append(_time(point, index, times[-1] if times else -math.inf))
        rows.append([np.zeros(limits.dof) if values is None else _field(values, index, field, names, order)
                     for field, values in (("positions", point.positions), ("velocities", point.velocities),
                                           ("accelerations", point.accelerations))])
        has_v.append(point.velocities is not None)
        has_a.append(point.accelerations is not None)
    states = np.array(rows)  # (points, 3, dof): positions, velocities, accelerations in arm order
    _check_ends(states, times[0], start, limits.joint_names)
    if times[0] == 0.0:
        states[0, 0] = start[0]  # the arm starts where it is, not a jump of up to START_TOLERANCE away
    else:
        times, states = [0.0, *times], np.concatenate([start[None], states])
        has_v, has_a = [True, *has_v], [True, *has_a]
    return Waypoints(limits.joint_names, np.array(times), states, np.array(has_v), np.array(has_a), start,
                     first_point=len(times) - len(trajectory.points))


class Spline(PolynomialMotion):
    """Piecewise polynomial through a validated trajectory, in the arm's joint order, sampled every cycle.

    `point_knots` holds the knot index of each trajectory point, so that a problem is reported at the point
    the user knows; other knots (the start state, or where a re-timed motion changes phase) go by their time.
    """

    def __init__(self, joint_names: tuple[str, ...], times: np.ndarray, coefficients: np.ndarray,
                 kinds: tuple[str, ...], start: np.ndarray, final: np.ndarray, point_knots: np.ndarray) -> None:
        super().__init__(times, coefficients, final)
        self.joint_names = joint_names
        self.segment_kinds = kinds
        self.segment_starts = times[:-1]
        self._start = start
        self._point_knots = point_knots
        self._derivatives = derivative_stack(coefficients)

    @classmethod
    def build(cls, trajectory: JointTrajectory, limits: ArmLimits, start_positions: Sequence[float],
              start_velocities: Sequence[float], start_accelerations: Sequence[float]) -> Spline:
        """Validate `trajectory` against the arm and its state at activation, and fit the segments."""
        return cls.through(read_waypoints(trajectory, limits, start_positions, start_velocities, start_accelerations))

    @classmethod
    def through(cls, waypoints: Waypoints) -> Spline:
        """The spline joint_trajectory_controller interpolates through `waypoints`."""
        states = waypoints.states
        coefficients, kinds = _coefficients(waypoints.times, states[:, 0], states[:, 1], states[:, 2],
                                            waypoints.has_velocities, waypoints.has_accelerations)
        return cls(waypoints.joint_names, waypoints.times, coefficients, kinds, waypoints.start, states[-1],
                   waypoints.point_knots)

    def check_limits(self, limits: ArmLimits, cycle_time_s: float) -> None:
        """Reject the spline if a joint leaves its range or exceeds a derivative limit anywhere along it."""
        if not cycle_time_s > 0.0:
            raise ValueError(f"cycle_time_s must be positive, got {cycle_time_s}")
        durations = np.diff(self.knots)
        ends = np.einsum("sp,kspj->ksj", durations[:, None] ** np.arange(ORDER), self._derivatives[:3])
        before = np.concatenate([self._start[:, None], ends], axis=1)  # (3, knots, dof): value just before knot
        after = np.concatenate([self._derivatives[:3, :, 0], self._final[:, None]], axis=1)
        # Steps at knots closer together than a cycle are commanded within the same cycle: add them up.
        totals = np.concatenate([np.zeros((3, 1, limits.dof)), np.cumsum(np.abs(after - before), axis=1)], axis=1)
        window_end = np.searchsorted(self.knots, self.knots + cycle_time_s * (1 - 1e-9), side="left")
        steps = totals[:, window_end] - totals[:, :-1]
        counts = window_end - np.arange(len(self.knots))
        # Find the knots and segments that may break a limit all at once, then let the exact per-knot and
        # per-segment checks judge those in order (the first one they reject is the one reported).
        suspects = sorted([(int(q), 0) for q in np.flatnonzero(_suspect_jumps(limits, steps, cycle_time_s))]
                          + [(int(s), 1) for s in np.flatnonzero(self._suspect_segments(limits, durations))])
        for q, kind in suspects:
            if kind == 0:
                self._check_jumps(limits, steps[:, q], int(counts[q]), q, cycle_time_s)
            else:
                self._check_segment(limits, q, float(durations[q]))
        for j, position in enumerate(self.final_positions):
            self._check_position(limits, j, float(position), self.duration, self._knot_name(len(durations)))

    def _suspect_segments(self, limits: ArmLimits, durations: np.ndarray) -> np.ndarray:
        """Per segment, whether some joint may leave its range or exceed a derivative limit inside it."""
        low, high = segment_ranges(self._derivatives, durations)
        suspect = (_near_beyond(-low[0], -limits.min_position) | _near_beyond(high[0], limits.max_position)).any(1)
        for k in (1, 2, 3):
            suspect |= _near_beyond(np.maximum(-low[k], high[k]), limits.maximum(KINDS[k])).any(1)
        result: np.ndarray = suspect
        return result

    def _knot_name(self, q: int) -> str:
        """The knot as the user knows it: a point index, the start state, or its time."""
        points = np.flatnonzero(self._point_knots == q)
        if points.size:
            return f"point {int(points[0])}"
        return "the start state" if q == 0 else f"t = {self.knots[q]:.6g} s"

    def _check_jumps(self, limits: ArmLimits, steps: np.ndarray, count: int, q: int, cycle_time_s: float) -> None:
        """Velocity or acceleration steps from a knot on (`count` knots within one cycle, `steps` their summed
        sizes) are commanded within one cycle: judge them as such."""
        for k in (1, 2):
            limit = limits.maximum(KINDS[k + 1])
            level = steps[k] / cycle_time_s
            for j in np.flatnonzero(beyond(level, limit)):
                unit = UNITS[f"max_{KINDS[k]}"]
                name = self._knot_name(q)
                at = name if name.startswith("t =") else f"{name} (t = {self.knots[q]:.6g} s)"
                what = (f"the {KINDS[k]} step of {steps[k, j]:.6g} {unit} at {at}" if count == 1 else
                        f"the {KINDS[k]} steps adding up to {steps[k, j]:.6g} {unit} at {at} and the {count - 1} "
                        f"points after it")
                where = f"{what}, made within one {cycle_time_s * 1e3:.6g} ms cycle,"
                error = limit_exceeded(KINDS[k + 1], self.joint_names[j], level[j], limit[j], where)
                error.how = SMOOTH_HOW
                raise error

    def _check_segment(self, limits: ArmLimits, s: int, duration: float) -> None:
        """Exact extrema of position, velocity, acceleration and jerk inside segment `s`, against the limits."""
        between = f"between {self._knot_name(s)} and {self._knot_name(s + 1)}"
        for j, joint in enumerate(self.joint_names):
            low, t_low, high, t_high = _extrema(self._derivatives[0, s, :, j], duration)
            self._check_position(limits, j, low, float(self.knots[s]) + t_low, between)
            self._check_position(limits, j, high, float(self.knots[s]) + t_high, between)
            for k in (1, 2, 3):
                limit = float(limits.maximum(KINDS[k])[j])
                if math.isinf(limit):
                    continue
                low, t_low, high, t_high = _extrema(self._derivatives[k, s, :, j], duration)
                value, t = (low, t_low) if -low > high else (high, t_high)
                if beyond(abs(value), limit):
                    where = f"the trajectory at t = {float(self.knots[s]) + t:.6g} s ({between})"
                    error = limit_exceeded(KINDS[k], joint, value, limit, where)
                    error.how = SMOOTH_HOW if k == 3 and self.segment_kinds[s] != "quintic" else SLOWER_HOW
                    raise error

    def _check_position(self, limits: ArmLimits, j: int, position: float, t: float, where: str) -> None:
        """Reject one joint's position outside [min_position, max_position], saying when along the trajectory."""
        low, high = float(limits.min_position[j]), float(limits.max_position[j])
        if not (beyond(-position, -low) or beyond(position, high)):
            return
        joint = self.joint_names[j]
        side, bound = ("min", low) if position < low else ("max", high)
        raise CommandRejected(
            f"the trajectory leaves the position limits of {joint}",
            what=f"{joint} within [{low:.6g}, {high:.6g}] rad all along the trajectory",
            why=f"at t = {t:.6g} s ({where}) {joint} = {position:.6g} rad is beyond its "
                f"{side}_position {bound:.6g} rad",
            how="keep every point inside the joint's range (config/joint_limits.yaml); between points a cubic or "
                "quintic overshoots when the velocities are large, so lower them or add points, or use move_joints "
                "for point-to-point motion")
