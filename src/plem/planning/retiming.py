"""Time parameterisation: any trajectory within the position limits, made to run within every other limit.

A trajectory that already keeps its limits runs exactly as sent. Otherwise plem keeps its points and
changes how it moves between them, in this order of preference:

1. **Smoothed and slowed where needed.** Velocities and accelerations the points lack are filled in (a
   monotone estimate from the neighbouring points, so the arm does not swing past a point), making the
   spline smooth (quintic) at every point. Segments whose peaks exceed a limit get more time, tapered
   into their neighbours, until none does; if that does not settle, the whole trajectory is slowed
   uniformly, which changes no shape. The path passes through every point. When the velocities a
   trajectory carries would swing a joint past its position limit, they are estimated from the
   positions instead.
2. **Stopping at every point.** When smoothing would swing a joint past its position limit, the arm
   moves along the straight line between consecutive points (as joint_trajectory_controller interpolates
   a positions-only trajectory) and comes to rest at each point: this never leaves the box the points
   span, so it always fits.

Whatever is chosen passes the same exact limit check as a trajectory sent as it should be.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from ruckig import InputParameter, Ruckig, Trajectory

from plem.control.limits import KINDS, ArmLimits
from plem.control.motion import INSIDE, StartState, plan_point_to_point
from plem.control.polynomial import ORDER, derivative_stack, from_ruckig, hermite_coefficients, segment_ranges
from plem.control.spline import AT_REST, Spline, Waypoints, beyond, read_waypoints
from plem.control.trajectory import JointTrajectory
from plem.errors import CommandRejected

#: Rounds of per-segment slowing before the whole trajectory is slowed uniformly.
SEGMENT_ROUNDS = 24
#: Rounds of uniform slowing: exact scaling settles in one, the rest absorb rounding.
UNIFORM_ROUNDS = 3
#: Every slowdown asks for this much more than the peaks need, so no segment ends just above a limit.
MARGIN = 1.002
#: A joint that moves less than this between two points (rad) is taken to stand still there.
STILL = 1e-12
#: Bound on the straight-line profile's limits: a joint without limits would otherwise give ruckig infinities.
PROFILE_BOUND = 1e9
#: Neighbouring segments differ in slowdown by at most this factor, so the arm changes pace gradually.
TAPER = 1.5


@dataclass(frozen=True)
class Timed:
    """The motion to run for a trajectory, and how it differs from what was sent ('' when it does not)."""

    motion: Spline
    requested_s: float
    change: str = ""

    @property
    def slowdown(self) -> float:
        """The motion's duration over the one asked for (1.0 when on time)."""
        return self.motion.duration / self.requested_s if self.requested_s > 0.0 else 1.0

    def note(self) -> str:
        """One sentence for the result and the event log: what was changed, the timing, and why."""
        if not self.change:
            return ""
        timing = (f"{self.motion.duration:.3f} s instead of {self.requested_s:.3f} s ({self.slowdown:.2f}x as long)"
                  if self.slowdown > 1.0 + 1e-6 else f"{self.motion.duration:.3f} s as asked")
        return f"{self.change}; {timing}"


def fit_to_limits(trajectory: JointTrajectory, limits: ArmLimits, start: StartState, cycle_time_s: float) -> Timed:
    """The motion for `trajectory` from `start` (position, velocity, acceleration), within every limit.

    Refused (CommandRejected) only for what no timing can fix: malformed points, unknown joints, a point
    outside the position limits, or an arm moving so that it cannot reach the first point within them.
    """
    waypoints = read_waypoints(trajectory, limits, *start)
    for index, knot in enumerate(waypoints.point_knots):
        limits.check_positions(waypoints.states[knot, 0], f"point {index}")
    requested = float(waypoints.times[-1])
    as_sent = Spline.through(waypoints)
    try:
        as_sent.check_limits(limits, cycle_time_s)
        return Timed(as_sent, requested)
    except CommandRejected as refusal:
        reason = refusal.summary
    complete = bool(waypoints.has_velocities.all() and waypoints.has_accelerations.all())
    carried = bool(waypoints.has_velocities[waypoints.first_point:].any())
    for keep_given in (True, False) if carried else (False,):
        motion = _smoothed(waypoints, limits, cycle_time_s, keep_given)
        if motion is None:
            continue
        slowed = motion.duration > requested * (1.0 + 1e-6)
        smoothed = ("" if keep_given and complete else "smoothed at the points" if keep_given or not carried
                    else "smoothed with velocities and accelerations estimated from the positions")
        what = " and ".join(filter(None, [smoothed, "slowed" if slowed else ""])) or "re-timed"
        return Timed(motion, requested, f"{what} to stay within the limits (as sent, {reason})")
    return Timed(_stopping_at_points(waypoints, limits, cycle_time_s), requested,
                 f"stopped at every point to stay on the path within the limits (as sent, {reason})")


# -- smoothing and slowing ------------------------------------------------------------------------------------
def _filled_velocities(times: np.ndarray, positions: np.ndarray, given: np.ndarray, values: np.ndarray) -> np.ndarray:
    """The given velocities, and where a point has none a monotone estimate (Fritsch-Butland): zero where the
    joint turns, else a weighted harmonic mean of the neighbouring slopes; zero at the last point."""
    durations = np.diff(times)[:, None]
    slopes = np.diff(positions, axis=0) / durations
    before, after, t_before, t_after = slopes[:-1], slopes[1:], durations[:-1], durations[1:]
    w_before, w_after = 2 * t_after + t_before, t_after + 2 * t_before
    same_sign = before * after > 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        mean = (w_before + w_after) / (w_before / before + w_after / after)
    estimate = np.zeros_like(positions)
    estimate[1:-1] = np.where(same_sign, mean, 0.0)
    return np.where(given[:, None], values, estimate)


def _filled_accelerations(times: np.ndarray, velocities: np.ndarray, given: np.ndarray, values: np.ndarray
                          ) -> np.ndarray:
    """The given accelerations, and where a point has none the central difference of the velocities."""
    estimate = np.zeros_like(velocities)
    estimate[1:-1] = (velocities[2:] - velocities[:-2]) / (times[2:] - times[:-2])[:, None]
    return np.where(given[:, None], values, estimate)


def _needed_slowdown(coefficients: np.ndarray, durations: np.ndarray, limits: ArmLimits) -> np.ndarray | None:
    """Per segment, how much longer it must take for its velocity, acceleration and jerk peaks to fit;
    None when a joint leaves its position range, which slowing cannot fix."""
    low, high = segment_ranges(derivative_stack(coefficients), durations)
    if np.any(beyond(-low[0], -limits.min_position)) or np.any(beyond(high[0], limits.max_position)):
        return None
    need = np.ones(len(durations))
    for k in (1, 2, 3):
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.nan_to_num(np.maximum(-low[k], high[k]) / limits.maximum(KINDS[k]), nan=0.0)
        need = np.maximum(need, ratio.max(axis=1) ** (1.0 / k))
    return need


def _tapered(pace: np.ndarray) -> np.ndarray:
    """`pace` lowered where needed so neighbouring points differ by at most TAPER."""
    result = pace.copy()
    for i in range(1, len(result)):
        result[i] = min(result[i], result[i - 1] * TAPER)
    for i in range(len(result) - 2, -1, -1):
        result[i] = min(result[i], result[i + 1] * TAPER)
    return result


def _smoothed(waypoints: Waypoints, limits: ArmLimits, cycle_time_s: float, keep_given: bool) -> Spline | None:
    """The quintic through the points, re-timed until it fits; None when it would leave the position limits.

    With `keep_given`, the velocities and accelerations the points carry are kept and only missing ones filled;
    without, all are estimated from the positions (the shape the points alone suggest).

    Re-timing runs the original spline at a pace r(t) ≤ 1, linear between the points: a segment then takes
    its duration over the logarithmic mean of its end paces, a point's velocity becomes v·r and its
    acceleration a·r² + v·r·dr/dt. A segment whose peaks exceed a limit slows the pace at both its ends.
    The start keeps the arm's own state.
    """
    times, states = waypoints.times, waypoints.states
    positions = states[:, 0].copy()
    positions[0] = waypoints.start[0]
    given_v = waypoints.has_velocities & keep_given
    given_a = waypoints.has_accelerations & keep_given
    given_v[0] = given_a[0] = True  # the start state
    velocities = _filled_velocities(times, positions, given_v, states[:, 1])
    accelerations = _filled_accelerations(times, velocities, given_a, states[:, 2])
    velocities[0], accelerations[0] = waypoints.start[1], waypoints.start[2]
    durations = np.diff(times)
    pace = np.ones(len(times))
    quintic = np.full(len(durations), 5)
    for round_ in range(SEGMENT_ROUNDS + UNIFORM_ROUNDS):
        if round_ >= SEGMENT_ROUNDS:
            pace[:] = pace.min()
        early, late = pace[:-1], pace[1:]
        with np.errstate(divide="ignore", invalid="ignore"):
            mean = np.where(np.isclose(early, late), early, (early - late) / (np.log(early) - np.log(late)))
        stretched = durations / mean
        v = velocities * pace[:, None]
        a = accelerations * pace[:, None] ** 2 + v * np.gradient(pace, times)[:, None]
        v[0], a[0] = waypoints.start[1], waypoints.start[2]
        coefficients = hermite_coefficients(stretched[:, None], positions[:-1], positions[1:], v[:-1], v[1:],
                                            a[:-1], a[1:], quintic)
        need = _needed_slowdown(coefficients, stretched, limits)
        if need is None:
            return None
        if need.max() <= 1.0:
            knots = np.concatenate([[0.0], np.cumsum(stretched)])
            spline = Spline(waypoints.joint_names, knots, coefficients, ("quintic",) * len(durations),
                            waypoints.start, np.stack([positions[-1], v[-1], a[-1]]), waypoints.point_knots)
            try:
                spline.check_limits(limits, cycle_time_s)
            except CommandRejected:
                return None
            return spline
        factor = np.where(need > 1.0, need * MARGIN, 1.0)
        slower = pace.copy()
        slower[:-1] = np.minimum(slower[:-1], early / factor)
        slower[1:] = np.minimum(slower[1:], late / factor)
        pace = _tapered(slower)
    return None


# -- stopping at every point ----------------------------------------------------------------------------------
def _line(limits: ArmLimits, begin: np.ndarray, end: np.ndarray, minimum_duration: float
          ) -> tuple[np.ndarray, np.ndarray]:
    """Knots and coefficients of a rest-to-rest motion along the straight line from `begin` to `end`.

    One jerk-limited profile s(t) from 0 to 1 (ruckig) carries every joint, so the motion stays on the line;
    its limits are the tightest of the joints' limits divided by their share of the distance.
    """
    delta = end - begin
    moving = np.abs(delta) > STILL
    if not moving.any():
        coefficients = np.zeros((1, ORDER, len(begin)))
        coefficients[0, 0] = end
        return np.array([0.0, minimum_duration]), coefficients
    share = np.abs(delta[moving])
    parameters = InputParameter(1)
    parameters.current_position, parameters.target_position = [0.0], [1.0]
    bounds = [min(float(np.min(limits.maximum(kind)[moving] / share)) * INSIDE, PROFILE_BOUND) for kind in KINDS[1:4]]
    parameters.max_velocity, parameters.max_acceleration, parameters.max_jerk = ([b] for b in bounds)
    parameters.minimum_duration = minimum_duration
    profile = Trajectory(1)
    Ruckig(1).calculate(parameters, profile)
    along = from_ruckig(profile, 1)
    coefficients = along.coefficients * delta
    coefficients[:, 0] += begin
    return along.knots, coefficients


def _stopping_at_points(waypoints: Waypoints, limits: ArmLimits, cycle_time_s: float) -> Spline:
    """Straight lines between consecutive points, at rest at each; from a moving start, a jerk-limited
    motion to the first point."""
    times, positions = waypoints.times, waypoints.states[:, 0]
    start = waypoints.start
    legs: list[tuple[np.ndarray, np.ndarray]] = []
    first = 0
    if np.abs(start[1:]).max() > AT_REST:
        toward = plan_point_to_point(limits, (start[0], start[1], start[2]), positions[1],
                                     minimum_duration=float(times[1])).polynomial()
        legs.append((toward.knots, toward.coefficients))
        first = 1
    legs.extend(_line(limits, start[0] if s == 0 else positions[s], positions[s + 1], float(times[s + 1] - times[s]))
                for s in range(first, len(times) - 1))
    knots, blocks, point_knots, offset = [np.zeros(1)], [], [0], 0.0
    for leg_knots, coefficients in legs:
        knots.append(offset + leg_knots[1:])
        blocks.append(coefficients)
        offset += float(leg_knots[-1])
        point_knots.append(point_knots[-1] + len(leg_knots) - 1)
    final = np.zeros((3, limits.dof))
    final[0] = positions[-1]
    spline = Spline(waypoints.joint_names, np.concatenate(knots), np.concatenate(blocks),
                    ("quintic",) * sum(len(block) for block in blocks), start, final,
                    np.array(point_knots[waypoints.first_point:]))
    spline.check_limits(limits, cycle_time_s)
    return spline
