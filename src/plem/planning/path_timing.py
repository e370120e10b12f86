"""Time parameterisation of a dense path that may pass corners without stopping, within the joint limits and the
tool's speed and acceleration limits.

The path is a list of joint states with the tool's placement at each, the states where the arm stops (its ends
and every corner without a blend), and the steps on which the tool limits apply. Between two stops it is one
smooth curve, parameterised by its joint-space length σ (derivatives by finite differences over states
KNOT_SPACING apart). Its pace σ̇ is the fastest that a forward and a backward pass allow (time-optimal path
parameterisation on the discretised path): at each state at most what every joint's velocity limit, the tool's
translational and rotational speed limits, the curvature (the joint and tool accelerations σ̇²·q'' that turning
takes) and its change (the jerk σ̇³·q''') allow; from state to state, σ̇² changes by at most what the
acceleration limits allow, a share of them going to the change of pace and the rest to turning. That time law
σ(t) is then averaged over a window (`_jerk_limited`), which makes it an S-curve: the change of pace ramps
within the jerk limits, and each piece still starts and ends at rest. The states with those times, at rest at
every stop, are handed to `fit_to_limits`, the re-timing every trajectory sent to plem gets: it smooths them
(the smoothest spline through the states) and slows them exactly where a limit still needs it.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from plem.control.limits import ArmLimits
from plem.control.spline import Spline
from plem.control.trajectory import JointTrajectory, TrajectoryPoint
from plem.planning.parameterisation import MINIMUM_STEP_S
from plem.planning.retiming import fit_to_limits, smoothing_needs
from plem.planning.sequence import ToolLimits

#: Share of each joint's acceleration limit the change of pace may take along the path; the rest is for turning.
ACCELERATION_SHARE = 0.5
#: Share of the tool's acceleration limit each of the change of pace and turning may take: the two are at right
#: angles, so together they stay within the limit.
TOOL_SHARE = 0.5**0.5
#: Share of each jerk limit the change of turning may take (the averaging of the time law takes the rest).
JERK_SHARE = 0.5
#: A piece shorter than this in joint space (rad) is no motion: its stops are merged.
STILL = 1e-9
#: Rounds of slowing the pace where the smoothed trajectory would still break a limit (`smoothing_needs`).
SLOWING_ROUNDS = 12
#: Each slowing asks for this much more than the segment needs.
SLOWING_MARGIN = 1.02
#: Joint-space distance (rad) between the states a path's trajectory passes as its points.
KNOT_SPACING = 0.01


def time_path(states: np.ndarray, positions: np.ndarray, rotations: np.ndarray, stops: np.ndarray,
              cartesian: np.ndarray, limits: ArmLimits, tool: ToolLimits, cycle_time_s: float) -> Spline:
    """The motion through `states` (arm order, one row per state) from rest to rest within `limits` and, on the
    steps flagged `cartesian` (the step arriving at each state), within `tool`; at rest at each state flagged in
    `stops`. `positions` and `rotations` are the tool's at each state."""
    stops = stops.copy()
    stops[0] = stops[-1] = True
    keep = _knots(states, stops)
    if len(keep) == 1:  # nothing moves: at rest where the arm is, for the shortest step a plan has
        keep = np.array([0, 0])
    cartesian = np.array([False, *(bool(cartesian[a + 1:b + 1].any())
                                   for a, b in zip(keep[:-1], keep[1:], strict=True))])
    states, positions, rotations, stops = states[keep], positions[keep], rotations[keep], stops[keep]
    turn = np.concatenate([[0.0], np.cumsum([np.linalg.norm(pin.log3(a.T @ b))
                                             for a, b in zip(rotations[:-1], rotations[1:], strict=True)])])
    window = 2.0 * ACCELERATION_SHARE * float(np.min(limits.max_acceleration / limits.max_jerk))
    marks = np.flatnonzero(stops)
    pieces = []
    for first, last in zip(marks[:-1], marks[1:], strict=True):
        piece = slice(first, last + 1)
        length = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(states[piece], axis=0), axis=1))])
        if length[-1] <= STILL:
            continue
        cap, change = _caps(length, _derivatives(states[piece], length),
                            _derivatives(np.column_stack([positions[piece], turn[piece]]), length), cartesian[piece],
                            limits, tool)
        pieces.append((first, last, length, cap, change))
    rest = np.zeros(limits.dof)
    start = (states[0].copy(), rest, rest.copy())
    for _ in range(SLOWING_ROUNDS):
        times = [np.zeros(1)] if pieces else [np.array([0.0, MINIMUM_STEP_S])]
        for _, _, length, cap, change in pieces:
            times.append(times[-1][-1] + _jerk_limited(length, _pass(length, cap, change), window, cycle_time_s)[1:])
        trajectory = JointTrajectory(limits.joint_names, tuple(
            TrajectoryPoint(tuple(map(float, q)), float(t), (0.0,) * limits.dof if stop else None,
                            (0.0,) * limits.dof if stop else None)
            for q, t, stop in zip(states, np.concatenate(times), stops, strict=True)))
        need = smoothing_needs(trajectory, limits, start)
        if need is None or need.max(initial=1.0) <= 1.0:
            break
        slower = _spread(need, np.concatenate(times), window)
        for first, last, _, cap, _ in pieces:
            cap /= np.where(slower[first:last + 1] > 1.0, slower[first:last + 1] * SLOWING_MARGIN, 1.0)
    return fit_to_limits(trajectory, limits, start, cycle_time_s).motion


def _spread(need: np.ndarray, times: np.ndarray, window: float) -> np.ndarray:
    """At each state, the most any segment within `window` seconds of it needs (the averaging of the time law
    spreads a state's pace over that window, so slowing one state alone would not slow its segment)."""
    ends = np.concatenate([[1.0], need]), np.concatenate([need, [1.0]])
    at_states = np.maximum(*ends)
    low = np.searchsorted(times, times - window)
    high = np.searchsorted(times, times + window, side="right")
    return np.array([at_states[a:b].max() for a, b in zip(low, high, strict=True)])


def _knots(states: np.ndarray, stops: np.ndarray) -> np.ndarray:
    """Indices of the states the trajectory passes as its points: every stop, and between two stops states about
    KNOT_SPACING apart in joint space (finite differences over closer states would amplify the IK's tolerance into
    noise). A stop where the arm already is (no motion since the last) is merged with it."""
    length = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(states, axis=0), axis=1))])
    marks = np.flatnonzero(stops)
    chosen = [int(marks[0])]
    for first, last in zip(marks[:-1], marks[1:], strict=True):
        span = length[last] - length[first]
        if span <= STILL:
            continue
        count = max(int(span // KNOT_SPACING), 1)
        inner = np.searchsorted(length[first:last + 1], np.linspace(length[first], length[last], count + 1)[1:-1])
        chosen.extend(int(k) + first for k in np.unique(inner) if 0 < k < last - first)
        chosen.append(int(last))
    return np.array(chosen)


def _derivatives(values: np.ndarray, length: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """First, second and third derivatives of `values` (a row per state) along the path length."""
    if len(length) < 3:
        slope = np.repeat(np.diff(values, axis=0) / length[-1], len(length), axis=0)
        return slope, np.zeros_like(values), np.zeros_like(values)
    slope = np.gradient(values, length, axis=0)
    bend = np.gradient(slope, length, axis=0)
    return slope, bend, np.gradient(bend, length, axis=0)


def _caps(length: np.ndarray, joint: tuple[np.ndarray, np.ndarray, np.ndarray],
          tool_path: tuple[np.ndarray, np.ndarray, np.ndarray], cartesian: np.ndarray, limits: ArmLimits,
          tool: ToolLimits) -> tuple[np.ndarray, np.ndarray]:
    """At each state of a rest-to-rest piece, the most σ̇ may be and the most σ̈ may change it by."""
    slope, bend, twist = (np.abs(values) for values in joint)
    tool_slope, tool_bend, _ = tool_path
    travel = np.linalg.norm(tool_slope[:, :3], axis=1)
    rotation = np.abs(tool_slope[:, 3])
    curve = np.linalg.norm(tool_bend[:, :3], axis=1)
    on_tool = cartesian.copy()
    on_tool[:-1] |= cartesian[1:]  # the states at either end of a step with the tool limits
    with np.errstate(divide="ignore"):
        cap = np.min(np.stack([
            limits.max_velocity / slope,
            np.sqrt((1.0 - ACCELERATION_SHARE) * limits.max_acceleration / bend),
            np.cbrt(JERK_SHARE * limits.max_jerk / twist)]).min(axis=0), axis=1)
        change = ACCELERATION_SHARE * np.min(limits.max_acceleration / slope, axis=1)
        tool_cap = np.minimum.reduce([tool.max_trans_vel / travel, tool.max_rot_vel / rotation,
                                      np.sqrt(TOOL_SHARE * tool.max_trans_acc / curve)])
        tool_change = TOOL_SHARE * np.minimum(tool.max_trans_acc / travel, tool.max_rot_acc / rotation)
    cap = np.where(on_tool, np.minimum(cap, tool_cap), cap)
    change = np.where(on_tool, np.minimum(change, tool_change), change)
    cap[0] = cap[-1] = 0.0
    return cap, change


def _pass(length: np.ndarray, cap: np.ndarray, change: np.ndarray) -> np.ndarray:
    """σ̇ at each state of a rest-to-rest piece: the forward-backward pass over the caps."""
    steps = np.diff(length)
    pace: np.ndarray = cap.copy()
    for k in range(len(pace) - 1):
        pace[k + 1] = min(pace[k + 1], np.sqrt(pace[k] ** 2 + 2.0 * min(change[k], change[k + 1]) * steps[k]))
    for k in range(len(pace) - 2, -1, -1):
        pace[k] = min(pace[k], np.sqrt(pace[k + 1] ** 2 + 2.0 * min(change[k], change[k + 1]) * steps[k]))
    return pace


def _jerk_limited(length: np.ndarray, pace: np.ndarray, window: float, step: float) -> np.ndarray:
    """The time at each state of a rest-to-rest piece once the time law σ(t) is averaged over `window` seconds: a box
    filter turns each jump of σ̈ into a ramp of `window` (an S-curve), so σ̈ changes by at most its largest jump
    over `window` per second. The piece takes `window` longer and still starts and ends at rest."""
    width = max(int(round(window / step)), 1)
    times = np.concatenate([[0.0], np.cumsum(2.0 * np.diff(length) / (pace[:-1] + pace[1:]))])
    grid = np.arange(0.0, times[-1] + step, step)
    speed = np.interp(grid, times, pace)  # σ̈ constant between states: σ̇ linear in time
    law = np.concatenate([[0.0], np.cumsum((speed[1:] + speed[:-1]) / 2.0 * step)])
    law *= length[-1] / law[-1]
    law = np.concatenate([np.zeros(width), law, np.full(width, length[-1])])
    smooth = np.convolve(law, np.ones(width) / width, mode="valid")
    clock = np.arange(len(smooth)) * step
    at: np.ndarray = np.interp(length, smooth, clock)
    at[0], at[-1] = 0.0, clock[-1]
    return at
