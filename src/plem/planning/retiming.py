"""Time parameterisation: any trajectory within the position limits, made to run within every other limit.

A trajectory that already keeps its limits runs exactly as sent. Otherwise plem keeps its points and
changes how it moves between them, in this order of preference:

1. **Smoothed and slowed where needed.** Velocities and accelerations the points lack are filled in from
   the cubic spline through the points, making the motion smooth (quintic) at every point. It is then
   slowed just enough: uniformly (an exact time scaling, which changes no shape), or segment by segment
   with the pace changing gradually; the shorter wins. The path passes through every point. When the
   velocities a trajectory carries, or the spline's, would swing a joint past its position limit, they
   are estimated from the positions (the spline's, then a monotone estimate with zero accelerations).
2. **From a moving start**, when that cannot be smoothed: a jerk-limited motion to rest at the first
   point, then the rest smoothed from there.
3. **Stopping at every point.** When smoothing would swing a joint past its position limit, the arm
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
from plem.control.polynomial import (
    ORDER,
    PolynomialMotion,
    derivative_stack,
    from_ruckig,
    hermite_coefficients,
    segment_ranges,
)
from plem.control.ruckig_results import calculate
from plem.control.spline import AT_REST, Spline, Waypoints, beyond, read_waypoints
from plem.control.trajectory import JointTrajectory
from plem.errors import CommandRejected

#: Rounds of slowing segment by segment before giving up on that pace.
SEGMENT_ROUNDS = 48
#: The pacings tried, the shorter result wins: uniform (False) and segment by segment (True).
PACINGS = (False, True)
#: Segments times rounds that pacing segment by segment may spend, which bounds its cost for long
#: trajectories (about a second on a 2-core machine); at least UNIFORM_ROUNDS rounds are always tried.
SEGMENT_WORK = 48_000
#: Rounds of uniform slowing: exact scaling settles in one, the rest absorb rounding (and a moving start).
UNIFORM_ROUNDS = 4
#: Every slowdown asks for this much more than the peaks need, so no segment ends just above a limit.
MARGIN = 1.002
#: A joint that moves less than this between two points (rad) is taken to stand still there.
STILL = 1e-12
#: Bound on the straight-line profile's limits: a joint without limits would otherwise give ruckig infinities.
PROFILE_BOUND = 1e9
#: The share of a joint's acceleration limit that a change of pace may take.
PACE_SHARE = 0.1


@dataclass(frozen=True)
class Timed:
    """The motion to run for a trajectory, how it differs from what was sent ('' when it does not) and why."""

    motion: Spline
    requested_s: float
    change: str = ""
    reason: str = ""  # the first limit the trajectory broke as sent

    @property
    def slowdown(self) -> float:
        """The motion's duration over the one asked for (1.0 when on time)."""
        return self.motion.duration / self.requested_s if self.requested_s > 0.0 else 1.0

    def note(self) -> str:
        """One sentence for the result and the event log: what was changed and the timing; why, when the motion
        took longer than asked (a trajectory only smoothed keeps its timing, and the reason is a detail)."""
        if not self.change:
            return ""
        if self.slowdown <= 1.0 + 1e-6:
            return f"{self.change}; {self.motion.duration:.3f} s as asked"
        return (f"{self.change}; {self.motion.duration:.3f} s instead of {self.requested_s:.3f} s "
                f"({self.slowdown:.2f}x as long): as sent, {self.reason}")


def fit_to_limits(trajectory: JointTrajectory, limits: ArmLimits, start: StartState, cycle_time_s: float) -> Timed:
    """The motion for `trajectory` from `start` (position, velocity, acceleration), within every limit.

    Refused (CommandRejected) only for what no timing can fix: malformed points, unknown joints, a point
    outside the position limits, or an arm moving so that it cannot reach the first point within them.
    """
    waypoints = _checked_waypoints(trajectory, limits, start)
    requested = float(waypoints.times[-1])
    try:
        return Timed(_as_sent(waypoints, limits, cycle_time_s), requested)
    except CommandRejected as refusal:
        reason = refusal.summary
    smooth = _smoothest(waypoints, limits, cycle_time_s)
    if smooth is not None:
        motion, how = smooth
        return Timed(motion, requested, f"{how} to stay within the limits", reason)
    if _moving(waypoints.start) and len(waypoints.times) > 2:
        rest = _from_rest_at_first_point(waypoints)
        smooth = _smoothest(rest, limits, cycle_time_s)
        if smooth is not None:
            toward = _toward_first_point(waypoints, limits)
            joined = _joined(waypoints, [(toward.knots, toward.coefficients, [len(toward.knots) - 1]),
                                         (smooth[0].knots, smooth[0].coefficients, list(range(1, len(rest.times))))],
                             _final_state(smooth[0]), limits, cycle_time_s)
            return Timed(joined, requested, f"brought to rest at the first point, then {smooth[1]}, to stay within "
                                            "the limits", reason)
    return Timed(_stopping_at_points(waypoints, limits, cycle_time_s), requested,
                 "stopped at every point to stay on the path within the limits", reason)


def as_sent(trajectory: JointTrajectory, limits: ArmLimits, start: StartState, cycle_time_s: float) -> Spline:
    """The motion `trajectory` gives from `start` exactly as sent: what `fit_to_limits` runs unchanged. Raises
    CommandRejected, naming the first limit it breaks, when it does not keep every limit (it would be re-timed)."""
    return _as_sent(_checked_waypoints(trajectory, limits, start), limits, cycle_time_s)


def _as_sent(waypoints: Waypoints, limits: ArmLimits, cycle_time_s: float) -> Spline:
    """The spline through the waypoints as they are, checked against every limit (else CommandRejected)."""
    spline = Spline.through(waypoints)
    spline.check_limits(limits, cycle_time_s)
    return spline


def along_straight_lines(trajectory: JointTrajectory, limits: ArmLimits, start: StartState, cycle_time_s: float
                         ) -> Spline:
    """The motion that follows the straight joint-space lines between the points exactly, at rest at each one
    (the last layer of `fit_to_limits`), for a caller that needs the lines themselves, such as a planned path."""
    return _stopping_at_points(_checked_waypoints(trajectory, limits, start), limits, cycle_time_s)


def _checked_waypoints(trajectory: JointTrajectory, limits: ArmLimits, start: StartState) -> Waypoints:
    """The trajectory's knots, every point within the position limits (else CommandRejected)."""
    waypoints = read_waypoints(trajectory, limits, *start)
    for index, knot in enumerate(waypoints.point_knots):
        limits.check_positions(waypoints.states[knot, 0], f"point {index}")
    return waypoints


def _final_state(motion: PolynomialMotion) -> np.ndarray:
    """Position, velocity and acceleration at the end of `motion`, stacked."""
    return np.stack([motion.final_positions, motion.final_velocities, motion.final_accelerations])


def _moving(start: np.ndarray) -> bool:
    """Whether the arm moves (or accelerates) at the start."""
    return bool(np.abs(start[1:]).max() > AT_REST)


def _smoothest(waypoints: Waypoints, limits: ArmLimits, cycle_time_s: float) -> tuple[Spline, str] | None:
    """The first smoothed motion that fits, with what was done to get it; the points' own velocities first."""
    complete = bool(waypoints.has_velocities.all() and waypoints.has_accelerations.all())
    carried = bool(waypoints.has_velocities[waypoints.first_point:].any())
    requested = float(waypoints.times[-1])
    attempts = [(True, "spline")] * carried + [(False, "spline"), (False, "monotone")]
    for keep_given, estimate in attempts:
        motion = _smoothed(waypoints, limits, cycle_time_s, keep_given, estimate)
        if motion is None:
            continue
        slowed = motion.duration > requested * (1.0 + 1e-6)
        smoothed = ("" if keep_given and complete else "smoothed at the points" if keep_given or not carried
                    else "smoothed with velocities and accelerations estimated from the positions")
        return motion, " and ".join(filter(None, [smoothed, "slowed" if slowed else ""])) or "re-timed"
    return None


def _from_rest_at_first_point(waypoints: Waypoints) -> Waypoints:
    """The points after the first, as a trajectory that starts at rest at the first (times counted from it)."""
    states = waypoints.states[1:]
    start = np.zeros_like(waypoints.start)
    start[0] = states[0, 0]
    return Waypoints(waypoints.joint_names, waypoints.times[1:] - waypoints.times[1], states,
                     waypoints.has_velocities[1:], waypoints.has_accelerations[1:], start, first_point=0)


def _toward_first_point(waypoints: Waypoints, limits: ArmLimits) -> PolynomialMotion:
    """ruckig's jerk-limited motion from the moving start to rest at the first knot after it, on time or later."""
    start = waypoints.start
    return plan_point_to_point(limits, (start[0], start[1], start[2]), waypoints.states[1, 0],
                               minimum_duration=float(waypoints.times[1])).polynomial()


def _joined(waypoints: Waypoints, pieces: list[tuple[np.ndarray, np.ndarray, list[int]]], final: np.ndarray,
            limits: ArmLimits, cycle_time_s: float) -> Spline:
    """Motions one after the other as one spline, checked. Each piece is its knots (from 0), its coefficients and
    which of its knots reach the next points of `waypoints`."""
    knots, blocks, point_knots, offset = [np.zeros(1)], [], [0], 0.0
    for piece_knots, coefficients, reached in pieces:
        point_knots.extend(len(np.concatenate(knots)) - 1 + index for index in reached)
        knots.append(offset + piece_knots[1:])
        blocks.append(coefficients)
        offset += float(piece_knots[-1])
    spline = Spline(waypoints.joint_names, np.concatenate(knots), np.concatenate(blocks),
                    ("quintic",) * sum(len(block) for block in blocks), waypoints.start, final,
                    np.array(point_knots[waypoints.first_point:]))
    spline.check_limits(limits, cycle_time_s)
    return spline


# -- smoothing and slowing ------------------------------------------------------------------------------------
def _monotone_velocities(times: np.ndarray, positions: np.ndarray, given: np.ndarray, values: np.ndarray
                         ) -> np.ndarray:
    """The given velocities, and where a point has none a monotone estimate (Fritsch-Butland): zero where the
    joint turns, else a weighted harmonic mean of the neighbouring slopes. With zero accelerations at the
    points it seldom swings past one, where the smoothest spline often does."""
    durations = np.diff(times)[:, None]
    slopes = np.diff(positions, axis=0) / durations
    before, after, t_before, t_after = slopes[:-1], slopes[1:], durations[:-1], durations[1:]
    w_before, w_after = 2 * t_after + t_before, t_after + 2 * t_before
    same_sign = before * after > 0.0
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        mean = (w_before + w_after) / (w_before / before + w_after / after)
    estimate = np.zeros_like(positions)
    estimate[1:-1] = np.where(same_sign, mean, 0.0)
    return np.where(given[:, None], values, estimate)


def _spline_velocities(times: np.ndarray, positions: np.ndarray, given: np.ndarray, values: np.ndarray
                       ) -> np.ndarray:
    """Velocities of the cubic spline through the points that is smooth in acceleration wherever no velocity
    is given (given ones, the first and the last stay as they are): the smoothest curve, which may swing past
    a point. Solved as the tridiagonal system of the spline's slopes (Thomas algorithm)."""
    fixed = given.copy()
    fixed[0] = fixed[-1] = True
    inverse = 1.0 / np.diff(times)
    slopes = np.diff(positions, axis=0) * inverse[:, None]
    count = len(times)
    below, diagonal, above = np.zeros(count), np.ones(count), np.zeros(count)
    right = np.where(fixed[:, None], values, 0.0)
    free = np.flatnonzero(~fixed)
    below[free], above[free] = inverse[free - 1], inverse[free]
    diagonal[free] = 2.0 * (inverse[free - 1] + inverse[free])
    right[free] = 3.0 * (slopes[free - 1] * inverse[free - 1, None] + slopes[free] * inverse[free, None])
    for i in range(1, count):
        factor = below[i] / diagonal[i - 1]
        diagonal[i] -= factor * above[i - 1]
        right[i] -= factor * right[i - 1]
    result = np.empty_like(right)
    result[-1] = right[-1] / diagonal[-1]
    for i in range(count - 2, -1, -1):
        result[i] = (right[i] - above[i] * result[i + 1]) / diagonal[i]
    return result


def _cubic_accelerations(times: np.ndarray, positions: np.ndarray, velocities: np.ndarray, given: np.ndarray,
                         values: np.ndarray) -> np.ndarray:
    """The given accelerations, and elsewhere the mean of the accelerations the cubic segments through the
    positions and velocities have at the point from either side (equal where the spline is smooth)."""
    durations = np.diff(times)[:, None]
    slopes = np.diff(positions, axis=0) / durations
    leaving = (6 * slopes - 4 * velocities[:-1] - 2 * velocities[1:]) / durations
    arriving = (-6 * slopes + 2 * velocities[:-1] + 4 * velocities[1:]) / durations
    estimate = np.zeros_like(velocities)
    estimate[1:-1] = (leaving[1:] + arriving[:-1]) / 2
    return np.where(given[:, None], values, estimate)


#: How velocities a point lacks are estimated: the smoothest spline first, the monotone estimate second.
ESTIMATES = {"spline": _spline_velocities, "monotone": _monotone_velocities}


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


def _gradual(pace: np.ndarray, times: np.ndarray, velocities: np.ndarray, limits: ArmLimits) -> np.ndarray:
    """`pace` lowered where needed so that changing pace costs at most PACE_SHARE of the acceleration limits.

    Running the spline at pace r adds v·d(r²)/dt / 2 to a joint's acceleration, so r² may change between
    two points by at most 2·PACE_SHARE·a_max/|v| per second of the original timing (a forward and a
    backward pass, as in time-optimal path parameterisation).
    """
    speed = np.maximum(np.abs(velocities[:-1]), np.abs(velocities[1:]))
    with np.errstate(divide="ignore", over="ignore"):
        room = np.min(2.0 * PACE_SHARE * limits.max_acceleration / speed, axis=1) * np.diff(times)
    squared = pace**2
    for i in range(1, len(squared)):
        squared[i] = min(squared[i], squared[i - 1] + room[i - 1])
    for i in range(len(squared) - 2, -1, -1):
        squared[i] = min(squared[i], squared[i + 1] + room[i])
    result: np.ndarray = np.sqrt(squared)
    return result


def _smoothed(waypoints: Waypoints, limits: ArmLimits, cycle_time_s: float, keep_given: bool,
              estimate: str) -> Spline | None:
    """The quintic through the points, re-timed until it fits; None when it would leave the position limits.

    With `keep_given`, the velocities and accelerations the points carry are kept and only missing ones filled;
    without, all are estimated from the positions (the shape the points alone suggest), by the ESTIMATES
    method named `estimate`.

    Re-timing runs the original spline at a pace r(t) ≤ 1, linear between the points: a segment then takes
    its duration over the logarithmic mean of its end paces, a point's velocity becomes v·r and its
    acceleration a·r² + v·r·dr/dt. A segment whose peaks exceed a limit slows the pace at both its ends.
    The start keeps the arm's own state.
    """
    positions, velocities, accelerations = _point_states(waypoints, keep_given, estimate)
    candidates = [_paced(waypoints, positions, velocities, accelerations, limits, cycle_time_s, local)
                  for local in PACINGS]
    feasible = [spline for spline in candidates if spline is not None]
    return min(feasible, key=lambda spline: spline.duration) if feasible else None


def _point_states(waypoints: Waypoints, keep_given: bool, estimate: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions, velocities and accelerations at the points for smoothing (see `_smoothed`); the start is the
    arm's own state."""
    times, states = waypoints.times, waypoints.states
    positions = states[:, 0].copy()
    positions[0] = waypoints.start[0]
    given_v = waypoints.has_velocities & keep_given
    given_a = waypoints.has_accelerations & keep_given
    given_v[0] = given_a[0] = True  # the start state
    known = states.copy()
    known[0] = waypoints.start
    velocities = ESTIMATES[estimate](times, positions, given_v, known[:, 1])
    accelerations = (_cubic_accelerations(times, positions, velocities, given_a, known[:, 2]) if estimate == "spline"
                     else np.where(given_a[:, None], known[:, 2], 0.0))
    return positions, velocities, accelerations


def smoothing_needs(trajectory: JointTrajectory, limits: ArmLimits, start: StartState) -> np.ndarray | None:
    """Per segment between the trajectory's knots, how many times longer it must take for the smoothest spline
    through its points (the first one `fit_to_limits` tries, given velocities and accelerations kept) to keep the
    velocity, acceleration and jerk limits (1 where it does); None when that spline swings past a position limit.
    For a caller that times a path itself and slows it where needed before handing it over."""
    waypoints = _checked_waypoints(trajectory, limits, start)
    positions, velocities, accelerations = _point_states(waypoints, True, "spline")
    durations = np.diff(waypoints.times)
    coefficients = hermite_coefficients(durations[:, None], positions[:-1], positions[1:], velocities[:-1],
                                        velocities[1:], accelerations[:-1], accelerations[1:],
                                        np.full(len(durations), 5))
    return _needed_slowdown(coefficients, durations, limits)


def _paced(waypoints: Waypoints, positions: np.ndarray, velocities: np.ndarray, accelerations: np.ndarray,
           limits: ArmLimits, cycle_time_s: float, local: bool) -> Spline | None:
    """The quintic through the point states run at the slowest pace its peaks need: the same pace everywhere
    (an exact time scaling), or with `local` a pace that slows only the segments that need it."""
    times = waypoints.times
    durations = np.diff(times)
    pace = np.ones(len(times))
    quintic = np.full(len(durations), 5)
    rounds = max(UNIFORM_ROUNDS, min(SEGMENT_ROUNDS, SEGMENT_WORK // len(durations))) if local else UNIFORM_ROUNDS
    for _ in range(rounds):
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
        if not local:
            pace = np.full(len(times), pace.min() / (need.max() * MARGIN))
            continue
        factor = np.where(need > 1.0, need * MARGIN, 1.0)
        slower = pace.copy()
        slower[:-1] = np.minimum(slower[:-1], early / factor)
        slower[1:] = np.minimum(slower[1:], late / factor)
        pace = _gradual(slower, times, velocities, limits)
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
    calculate(Ruckig(1), parameters, profile, "a straight segment of the path")
    along = from_ruckig(profile, 1)
    coefficients = along.coefficients * delta
    coefficients[:, 0] += begin
    return along.knots, coefficients


def _stopping_at_points(waypoints: Waypoints, limits: ArmLimits, cycle_time_s: float) -> Spline:
    """Straight lines between consecutive points, at rest at each; from a moving start, a jerk-limited
    motion to the first point."""
    times, positions = waypoints.times, waypoints.states[:, 0]
    pieces: list[tuple[np.ndarray, np.ndarray, list[int]]] = []
    first = 0
    if _moving(waypoints.start):
        toward = _toward_first_point(waypoints, limits)
        pieces.append((toward.knots, toward.coefficients, [len(toward.knots) - 1]))
        first = 1
    for s in range(first, len(times) - 1):
        knots, coefficients = _line(limits, waypoints.start[0] if s == 0 else positions[s], positions[s + 1],
                                    float(times[s + 1] - times[s]))
        pieces.append((knots, coefficients, [len(knots) - 1]))
    final = np.zeros((3, limits.dof))
    final[0] = positions[-1]
    return _joined(waypoints, pieces, final, limits, cycle_time_s)
