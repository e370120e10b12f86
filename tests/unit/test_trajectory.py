"""Trajectory splines: JTC interpolation per segment, validation, limit checks, tolerances and results."""

from __future__ import annotations

import math
import tracemalloc

import numpy as np
import pytest
from hypothesis import given, settings, target
from hypothesis import strategies as st

from plem.control.limits import ArmLimits
from plem.control.trajectory import (
    DEFAULT_GOAL_TIME,
    ErrorCode,
    JointNamesRejected,
    JointTrajectory,
    Spline,
    TrajectoryOutcome,
    TrajectoryPoint,
    TrajectoryResult,
    TrajectoryTolerances,
)
from plem.errors import CommandRejected

NAMES = tuple(f"joint{i}" for i in range(6))
DOF = len(NAMES)
LIMITS = ArmLimits(NAMES, np.full(DOF, -3.05), np.full(DOF, 3.05), np.full(DOF, 2.6), np.full(DOF, 3.0),
                   np.full(DOF, 30.0), np.full(DOF, 400.0))
CYCLE = 0.001
REST = np.zeros(DOF)


def ramp(*values: float) -> tuple[float, ...]:
    """A per-joint vector that differs from joint to joint, so a mixed-up column shows."""
    return tuple(values[i % len(values)] * (1 + 0.1 * i) for i in range(DOF))


def point(positions, time, velocities=None, accelerations=None) -> TrajectoryPoint:
    return TrajectoryPoint(tuple(positions), time,
                           None if velocities is None else tuple(velocities),
                           None if accelerations is None else tuple(accelerations))


def build(points, start=(REST, REST, REST), names=NAMES) -> Spline:
    return Spline.build(JointTrajectory(tuple(names), tuple(points)), LIMITS, *start)


# ---------------------------------------------------------------------------------------------------------------
# Independent reference: closed-form Hermite basis functions in s = tau / T, with d/ds and d²/ds².

def linear_reference(s, T, p0, p1):
    return p0 + (p1 - p0) * s, (p1 - p0) / T, np.zeros_like(p0)


def cubic_reference(s, T, p0, v0, p1, v1):
    basis = [  # (h, h', h'') for p0, T v0, p1, T v1
        (2 * s**3 - 3 * s**2 + 1, 6 * s**2 - 6 * s, 12 * s - 6),
        (s**3 - 2 * s**2 + s, 3 * s**2 - 4 * s + 1, 6 * s - 4),
        (-2 * s**3 + 3 * s**2, -6 * s**2 + 6 * s, -12 * s + 6),
        (s**3 - s**2, 3 * s**2 - 2 * s, 6 * s - 2),
    ]
    weights = [p0, T * v0, p1, T * v1]
    return tuple(sum(b[d] * w for b, w in zip(basis, weights, strict=False)) / T**d for d in range(3))


def quintic_reference(s, T, p0, v0, a0, p1, v1, a1):
    basis = [  # (H, H', H'') for p0, T v0, T² a0, T² a1, T v1, p1
        (1 - 10 * s**3 + 15 * s**4 - 6 * s**5, -30 * s**2 + 60 * s**3 - 30 * s**4, -60 * s + 180 * s**2 - 120 * s**3),
        (s - 6 * s**3 + 8 * s**4 - 3 * s**5, 1 - 18 * s**2 + 32 * s**3 - 15 * s**4, -36 * s + 96 * s**2 - 60 * s**3),
        ((s**2 - 3 * s**3 + 3 * s**4 - s**5) / 2, (2 * s - 9 * s**2 + 12 * s**3 - 5 * s**4) / 2,
         (2 - 18 * s + 36 * s**2 - 20 * s**3) / 2),
        ((s**3 - 2 * s**4 + s**5) / 2, (3 * s**2 - 8 * s**3 + 5 * s**4) / 2, (6 * s - 24 * s**2 + 20 * s**3) / 2),
        (-4 * s**3 + 7 * s**4 - 3 * s**5, -12 * s**2 + 28 * s**3 - 15 * s**4, -24 * s + 84 * s**2 - 60 * s**3),
        (10 * s**3 - 15 * s**4 + 6 * s**5, 30 * s**2 - 60 * s**3 + 30 * s**4, 60 * s - 180 * s**2 + 120 * s**3),
    ]
    weights = [p0, T * v0, T**2 * a0, T**2 * a1, T * v1, p1]
    return tuple(sum(b[d] * w for b, w in zip(basis, weights, strict=False)) / T**d for d in range(3))


def reference(knots, t):
    """State at t of (time, p, v|None, a|None) knots in arm order: JTC's choice of segment kind, final hold."""
    times = [k[0] for k in knots]
    if t >= times[-1]:
        _, p, v, a = knots[-1]
        return p, REST if v is None else v, REST if a is None else a
    i = max(j for j, time in enumerate(times) if time <= t)
    (t0, p0, v0, a0), (t1, p1, v1, a1) = knots[i], knots[i + 1]
    T, s = t1 - t0, (t - t0) / (t1 - t0)
    if v0 is not None and v1 is not None and a0 is not None and a1 is not None:
        return quintic_reference(s, T, p0, v0, a0, p1, v1, a1)
    if v0 is not None and v1 is not None:
        return cubic_reference(s, T, p0, v0, p1, v1)
    return linear_reference(s, T, p0, p1)


def sample_times(knots):
    """Many times: every knot exactly, just either side of it, a dense grid, and past the end."""
    times = [k[0] for k in knots]
    around = [t + d for t in times for d in (-1e-7, 0.0, 1e-7) if t + d >= 0.0]
    return sorted(around + list(np.linspace(0.0, times[-1] + 0.5, 257)))


def assert_matches_reference(spline: Spline, knots) -> None:
    out = np.zeros((3, DOF))
    p, v, a = out
    for t in sample_times(knots):
        done = spline.sample(t, out)
        expected = reference(knots, t)
        assert done == (t >= knots[-1][0])
        for got, want in zip((p, v, a), expected, strict=False):
            np.testing.assert_allclose(got, want, rtol=0, atol=1e-9, err_msg=f"t = {t}")


START = (np.array(ramp(0.1, -0.2)), np.array(ramp(0.05, 0.02)), np.array(ramp(-0.1, 0.3)))


@pytest.mark.parametrize("fields, kinds", [
    (("p", "p", "p"), ("linear", "linear", "linear")),
    (("pv", "pv", "pv"), ("cubic", "cubic", "cubic")),
    (("pva", "pva", "pva"), ("quintic", "quintic", "quintic")),
    (("p", "pv", "pva"), ("linear", "linear", "cubic")),
    (("pva", "pv", "pva"), ("quintic", "cubic", "cubic")),
])
def test_sampling_matches_the_closed_form_splines(fields, kinds):
    positions = [ramp(0.4, -0.3), ramp(0.9, 0.1), ramp(0.6, 0.5)]
    velocities = [ramp(0.3, -0.2), ramp(-0.1, 0.25), REST]
    accelerations = [ramp(0.5, -0.4), ramp(-0.2, 0.1), REST]
    times = [0.7, 1.5, 2.6]
    points, knots = [], [(0.0, *START)]
    for f, p, v, a, t in zip(fields, positions, velocities, accelerations, times, strict=False):
        v, a = (np.array(v) if "v" in f else None), (np.array(a) if "a" in f else None)
        points.append(point(p, t, v, a))
        knots.append((t, np.array(p), v, a))
    spline = build(points, start=START)
    assert spline.segment_kinds == kinds
    assert spline.duration == 2.6
    assert spline.coefficients.shape == (3, 6, DOF)
    np.testing.assert_array_equal(spline.segment_starts, [0.0, 0.7, 1.5])
    assert_matches_reference(spline, knots)


def test_a_first_point_at_time_zero_on_the_start_has_no_start_segment():
    first = ramp(0.1, -0.2)
    points = [point(first, 0.0, REST, REST), point(ramp(0.5, 0.2), 1.0, REST, REST)]
    spline = build(points, start=(np.array(first), REST, REST))
    assert spline.segment_kinds == ("quintic",)
    assert_matches_reference(spline, [(0.0, np.array(first), REST, REST), (1.0, np.array(ramp(0.5, 0.2)), REST, REST)])


def test_a_single_point_at_the_start_is_done_at_once():
    spline = build([point(ramp(0.1), 0.0)], start=(np.array(ramp(0.1)), REST, REST))
    out = np.ones((3, DOF))
    p, v, a = out
    assert spline.duration == 0.0 and spline.segment_kinds == ()
    assert spline.sample(0.0, out) and spline.sample(-1.0, out)
    np.testing.assert_array_equal(p, ramp(0.1))
    np.testing.assert_array_equal(v, REST)
    spline.check_limits(LIMITS, CYCLE)


def test_the_final_point_is_held_after_the_end():
    points = [point(ramp(0.5), 1.0, REST, REST), point(ramp(0.8), 2.0)]
    spline = build(points)
    out = np.full((3, DOF), 9.0)
    p, v, a = out
    assert not spline.sample(1.999, out)
    for t in (2.0, 2.5, 100.0):
        assert spline.sample(t, out)
        np.testing.assert_array_equal(p, ramp(0.8))
        np.testing.assert_array_equal(v, REST)
        np.testing.assert_array_equal(a, REST)
    np.testing.assert_array_equal(spline.final_positions, ramp(0.8))


def test_sampling_backwards_in_time_finds_the_segment_again():
    knots = [(0.0, REST, REST, REST)] + [(t, np.array(ramp(0.1 * t)), REST, REST) for t in (1.0, 2.0, 3.0)]
    spline = build([point(p, t, v, a) for t, p, v, a in knots[1:]])
    out = np.zeros((3, DOF))
    p, v, a = out
    for t in (2.5, 0.5, 2.9, 1.0, -0.1):
        spline.sample(t, out)
        np.testing.assert_allclose(p, reference(knots, max(t, 0.0))[0], atol=1e-12)


def test_columns_are_mapped_to_the_arm_joint_order():
    order = [3, 0, 5, 1, 4, 2]
    target = np.array(ramp(0.3, -0.6))
    names = [NAMES[i] for i in order]
    spline = build([point(target[order], 1.0, REST, REST)], names=names)
    out = np.zeros((3, DOF))
    p, v, a = out
    assert spline.sample(1.0, out)
    np.testing.assert_array_equal(p, target)
    assert spline.joint_names == NAMES


def test_from_lists_builds_points_and_rejects_unknown_keys():
    trajectory = JointTrajectory.from_lists(NAMES, [
        {"positions": [0.1] * DOF, "time_from_start": 1},
        {"positions": [0.2] * DOF, "velocities": [0] * DOF, "accelerations": [0] * DOF, "time_from_start": 2.0}])
    assert trajectory.points[0] == TrajectoryPoint((0.1,) * DOF, 1.0)
    assert trajectory.points[1].accelerations == (0.0,) * DOF
    with pytest.raises(CommandRejected, match="point 0") as error:
        JointTrajectory.from_lists(NAMES, [{"positions": [0.0] * DOF, "time": 1.0}])
    assert "unknown keys: time" in error.value.why and "missing: time_from_start" in error.value.why
    with pytest.raises(CommandRejected, match="point 0 holds"):
        JointTrajectory.from_lists(NAMES, [{"positions": ["a"] * DOF, "time_from_start": 1.0}])


# ---------------------------------------------------------------------------------------------------------------
# Rejections in build, each naming the point and the joint.

GOOD = ramp(0.2)


@pytest.mark.parametrize("names, points, pieces", [
    (NAMES[:5], [point(GOOD[:5], 1.0)], ["missing: joint5"]),
    ((*NAMES, "gripper"), [point((*GOOD, 0.0), 1.0)], ["not joints of this arm: gripper"]),
    ((*NAMES[:5], "joint0"), [point(GOOD, 1.0)], ["listed more than once: joint0", "missing: joint5"]),
])
def test_joint_names_must_be_the_arm_joints_once_each(names, points, pieces):
    with pytest.raises(JointNamesRejected) as error:
        build(points, names=names)
    for piece in pieces:
        assert piece in error.value.why
    assert TrajectoryResult.rejected(error.value).error_code == ErrorCode.INVALID_JOINTS


REVERSED = tuple(reversed(NAMES))
NAN_FIRST = (math.nan, *GOOD[1:])


@pytest.mark.parametrize("points, names, start, summary, detail", [
    ([], NAMES, None, "no points", "points is empty"),
    ([point(GOOD, 1.0), point(GOOD[:5], 2.0)], NAMES, None, "point 1 has 5 positions for 6 joints", "point 1"),
    ([point(GOOD, 1.0, REST), point(GOOD, 2.0, NAN_FIRST)], REVERSED, None, "point 1 velocities contain NaN",
     "not finite for joint5"),
    ([point(GOOD, 1.0, REST, (math.inf, *GOOD[1:]))], NAMES, None, "point 0 accelerations", "not finite for joint0"),
    ([point(GOOD, -1.0)], NAMES, None, "point 0 has an invalid time_from_start", "-1 s"),
    ([point(GOOD, math.nan)], NAMES, None, "point 0 has an invalid time_from_start", "nan"),
    ([point(GOOD, 1.0), point(GOOD, 1.0)], NAMES, None, "point 1 has an invalid time_from_start",
     "point 0 is at 1 s, point 1 at 1 s"),
    ([point(GOOD, 2.0), point(GOOD, 1.0)], NAMES, None, "point 1", "point 1 at 1 s"),
    ([point(GOOD, 1.0, None, REST)], NAMES, None, "point 0 has accelerations but no velocities", "point 0"),
    ([point(GOOD, 0.0)], NAMES, None, "time_from_start 0 but is not where the arm is",
     "joint5 is at 0 rad, point 0 asks for 0.3 rad"),
    ([point(GOOD, 1.0), point(GOOD, 2.0, ramp(0.0, 0.0, 0.0, 1e-3))], NAMES, None,
     "last point has non-zero velocities", "point 1 has velocities 0.0013 for joint3"),
    ([point(GOOD, 1.0, REST, ramp(0.0, 0.0, 0.5))], NAMES, None, "non-zero accelerations", "joint2"),
    ([point(GOOD, 1.0)], NAMES, (REST[:5], REST, REST), "the start positions has 5 values", "got 5"),
])
def test_invalid_trajectories_are_rejected_saying_where(points, names, start, summary, detail):
    with pytest.raises(CommandRejected) as error:
        build(points, start=start or (REST, REST, REST), names=names)
    assert summary in error.value.summary
    assert detail in error.value.why
    assert error.value.how
    assert not isinstance(error.value, JointNamesRejected)
    assert TrajectoryResult.rejected(error.value).error_code == ErrorCode.INVALID_GOAL


def test_a_first_point_at_time_zero_may_differ_from_the_start_as_a_measured_state_does():
    """A client's current state comes from joint_states: within 0.01 rad the point is taken as the start."""
    start = np.array(GOOD)
    spline = build([point(start + 0.004, 0.0), point(start + 0.1, 2.0, REST, REST)], start=(start, REST, REST))
    assert np.array_equal(spline.state_at(0.0)[0], start)
    with pytest.raises(CommandRejected, match="not where the arm is"):
        build([point(start + 0.02, 0.0)], start=(start, REST, REST))


# ---------------------------------------------------------------------------------------------------------------
# check_limits: exact extrema inside segments, steps at knots, the start state and the end.

def rest_to_rest(distance: float, duration: float) -> Spline:
    """A quintic from rest to rest: peak velocity 15/8 d/T, acceleration 10/sqrt(3) d/T², jerk 60 d/T³."""
    return build([point(np.full(DOF, distance), duration, REST, REST)])


def limits_with(**maxima: float) -> ArmLimits:
    arrays = {kind: np.full(DOF, value) for kind, value in maxima.items()}
    return ArmLimits(NAMES, LIMITS.min_position, LIMITS.max_position, arrays.get("velocity", LIMITS.max_velocity),
                     arrays.get("acceleration", LIMITS.max_acceleration), arrays.get("jerk", LIMITS.max_jerk),
                     LIMITS.max_effort)


@pytest.mark.parametrize("kind, peak, where", [
    ("velocity", 15 / 8 * 1.0 / 2.0, ["t = 1 s"]),
    ("acceleration", 10 / math.sqrt(3) * 1.0 / 4.0, ["t = 0.42265 s", "t = 1.57735 s"]),  # +peak, -peak
    ("jerk", 60 * 1.0 / 8.0, ["t = 0 s", "t = 2 s"]),
])
def test_interior_extrema_are_found_exactly(kind, peak, where):
    spline = rest_to_rest(1.0, 2.0)
    spline.check_limits(limits_with(**{kind: peak * (1 + 1e-7)}), CYCLE)
    with pytest.raises(CommandRejected) as error:
        spline.check_limits(limits_with(**{kind: peak * (1 - 1e-7)}), CYCLE)
    assert f"{kind} limit of joint0" in error.value.summary
    assert any(w in error.value.why for w in where) and "between the start state and point 0" in error.value.why
    assert f"needs {peak:.6g}" in error.value.why
    assert "more time" in error.value.how and "move_joints" in error.value.how


def test_an_overshoot_between_points_leaves_the_position_range():
    spline = build([point(np.full(DOF, 2.9), 1.0, np.full(DOF, 1.0), REST), point(np.full(DOF, 2.9), 4.0, REST, REST)])
    with pytest.raises(CommandRejected) as error:
        spline.check_limits(limits_with(velocity=100.0, acceleration=100.0, jerk=1000.0), CYCLE)
    assert "position limits of joint0" in error.value.summary
    assert "max_position 3.05" in error.value.why and "between point 0 and point 1" in error.value.why


def test_a_start_outside_the_range_is_rejected_even_without_motion():
    start = np.full(DOF, -3.1)
    with pytest.raises(CommandRejected, match="position limits of joint0"):
        build([point(start, 0.0)], start=(start, REST, REST)).check_limits(LIMITS, CYCLE)


def test_a_velocity_step_at_a_knot_counts_as_acceleration_within_one_cycle():
    spline = build([point(ramp(0.2), 1.0), point(ramp(0.2), 2.0)])
    with pytest.raises(CommandRejected) as error:
        spline.check_limits(LIMITS, CYCLE)
    assert "acceleration limit of joint0" in error.value.summary
    assert "velocity step of 0.2 rad/s at the start state (t = 0 s)" in error.value.why
    assert "needs 200 rad/s²" in error.value.why
    assert "add velocities and accelerations" in error.value.how
    spline.check_limits(limits_with(acceleration=math.inf), CYCLE)  # no acceleration limit: steps are allowed


def test_a_velocity_step_at_the_end_is_an_abrupt_stop():
    spline = build([point(np.full(DOF, 0.2), 1.0)], start=(REST, np.full(DOF, 0.2), REST))
    with pytest.raises(CommandRejected, match="velocity step of 0.2 rad/s at point 0 \\(t = 1 s\\)"):
        spline.check_limits(limits_with(acceleration=150.0), CYCLE)


def test_an_acceleration_step_of_a_cubic_counts_as_jerk():
    spline = build([point(ramp(0.2), 2.0, REST), point(ramp(0.4), 4.0, REST)])
    with pytest.raises(CommandRejected) as error:
        spline.check_limits(LIMITS, CYCLE)
    assert "jerk limit of joint0" in error.value.summary and "acceleration step" in error.value.why
    spline.check_limits(limits_with(jerk=math.inf), CYCLE)


def test_a_moving_start_must_be_continued_smoothly():
    moving = (REST, np.full(DOF, 0.5), REST)
    with pytest.raises(CommandRejected, match="velocity step of 0.25 rad/s at the start state"):
        build([point(np.full(DOF, 0.5), 2.0)], start=moving).check_limits(LIMITS, CYCLE)
    build([point(np.full(DOF, 1.0), 2.0, REST, REST)], start=moving).check_limits(LIMITS, CYCLE)


def test_check_limits_needs_a_cycle_time():
    with pytest.raises(ValueError):
        rest_to_rest(0.1, 1.0).check_limits(LIMITS, 0.0)


# ---------------------------------------------------------------------------------------------------------------
# Property: whatever check_limits accepts stays inside the limits when sampled.

finite = {"allow_nan": False, "allow_infinity": False}
vector = st.lists(st.floats(-3.05, 3.05, **finite), min_size=DOF, max_size=DOF).map(np.array)


def derivative(bound: float):
    """Zero, small or anything up to the bound: most trajectories should get through check_limits."""
    return st.one_of(st.just(REST), st.lists(st.floats(-bound, bound, **finite), min_size=DOF, max_size=DOF)
                     .map(np.array), st.lists(st.floats(-0.3, 0.3, **finite), min_size=DOF, max_size=DOF).map(np.array))


@st.composite
def quintic_trajectories(draw):
    """Rest-to-rest or moving quintics; each point near the one before (clipped at the limits) or anywhere."""
    start = (draw(vector), draw(derivative(0.5)), draw(derivative(0.5)))
    count = draw(st.integers(1, 3))
    time, previous, points = 0.0, start[0], []
    for index in range(count):
        time += draw(st.floats(0.2, 1.5))
        step = st.lists(st.floats(-0.8, 0.8, **finite), min_size=DOF, max_size=DOF).map(np.array)
        previous = draw(st.one_of(vector, step.map(lambda d, p=previous: np.clip(p + d, -3.05, 3.05))))
        last = index == count - 1
        points.append(point(previous, time, REST if last else draw(derivative(2.6)),
                            REST if last else draw(derivative(3.0))))
    return points, start


def beyond(values: np.ndarray, limit: float, slack: float = 1e-9) -> bool:
    return bool((np.abs(values) > limit + slack * max(1.0, limit)).any())


@settings(max_examples=200, deadline=None)
@given(quintic_trajectories(), st.floats(0.0, 0.999))
def test_accepted_trajectories_stay_inside_the_limits_when_sampled(trajectory, phase):
    points, start = trajectory
    spline = build(points, start=start)
    try:
        spline.check_limits(LIMITS, CYCLE)
    except CommandRejected:
        return
    peaks = np.zeros(3)
    # The 1 kHz grid at a random phase over the whole motion and past its end, and 5 kHz over the first 0.5 s.
    for step, offset, end in ((CYCLE, phase * CYCLE, math.inf), (CYCLE / 5, 0.0, 0.5)):
        times = np.arange(offset, min(spline.duration + 2 * step, end), step)
        p, v, a = (np.empty((len(times), DOF)) for _ in range(3))
        out = np.zeros((3, DOF))
        for k, t in enumerate(times):
            spline.sample(float(t), out)
            p[k], v[k], a[k] = out
        jerk = np.diff(a, axis=0) / step
        assert not (p < LIMITS.min_position - 1e-9 * 3.05).any() and not (p > LIMITS.max_position + 1e-9 * 3.05).any()
        assert not beyond(v, 2.6) and not beyond(a, 3.0) and not beyond(jerk, 30.0, slack=1e-6)
        peaks = np.maximum(peaks, [np.abs(v).max() / 2.6, np.abs(a).max() / 3.0, np.abs(jerk).max(initial=0) / 30.0])
    for kind, peak in zip(("velocity", "acceleration", "jerk"), peaks, strict=False):
        target(float(peak), label=kind)  # steer towards trajectories that just pass


def test_sampling_allocates_nothing_per_call():
    spline = build([point(ramp(0.3), 1.0, ramp(0.1), REST), point(ramp(0.5), 2.0, REST, REST)])
    out = np.zeros((3, DOF))
    p, v, a = out
    for k in range(100):
        spline.sample(k * 0.0003, out)
    spline.sample(0.0, out)
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        for k in range(10_000):
            spline.sample(k * 0.00025, out)  # runs through both segments and into the hold
        grown = tracemalloc.get_traced_memory()[0] - before
    finally:
        tracemalloc.stop()
    assert grown < 500


# ---------------------------------------------------------------------------------------------------------------
# Tolerances and results.

def test_tolerances_follow_the_controller_defaults():
    tolerances = TrajectoryTolerances()
    assert tolerances.path is None and tolerances.goal is None
    assert tolerances.goal_time == DEFAULT_GOAL_TIME == 1.0
    assert tolerances.stopped_velocity_tolerance == 0.01


def test_zero_tolerances_mean_unchecked_and_zero_goal_time_means_the_default():
    tolerances = TrajectoryTolerances(path=[0.1, 0.0, -1.0], goal=np.array([0.01, 0.02, 0.03]), goal_time=0.0)
    assert tolerances.path.tolist() == [0.1, math.inf, math.inf]
    assert tolerances.goal.tolist() == [0.01, 0.02, 0.03]
    assert tolerances.goal_time == DEFAULT_GOAL_TIME
    assert TrajectoryTolerances(goal_time=math.inf).goal_time == math.inf
    with pytest.raises(ValueError):
        tolerances.path[0] = 1.0


@pytest.mark.parametrize("arguments", [{"path": [math.nan]}, {"goal_time": -1.0}, {"goal_time": math.nan},
                                       {"stopped_velocity_tolerance": 0.0}])
def test_invalid_tolerances_are_rejected(arguments):
    with pytest.raises(CommandRejected):
        TrajectoryTolerances(**arguments)


def test_results_carry_the_follow_joint_trajectory_error_codes():
    assert [code.value for code in ErrorCode] == [0, -1, -2, -3, -4, -5]
    assert TrajectoryResult.succeeded() == TrajectoryResult(TrajectoryOutcome.SUCCEEDED, "goal reached", 0)
    assert TrajectoryResult.preempted().error_code == ErrorCode.INVALID_GOAL
    assert TrajectoryResult.canceled().outcome is TrajectoryOutcome.CANCELED
    rejected = TrajectoryResult.rejected(CommandRejected("bad", what="w", why="y", how="h"))
    assert rejected.outcome is TrajectoryOutcome.REJECTED and rejected.message.startswith("ERROR: bad")


def test_state_at_agrees_with_sample_even_behind_the_cursor():
    limits = ArmLimits(tuple(f"joint{i}" for i in range(6)), np.full(6, -3.05), np.full(6, 3.05), np.full(6, 2.6),
                       np.full(6, 3.0), np.full(6, 30.0), np.full(6, 400.0))
    zeros = (0.0,) * 6
    trajectory = JointTrajectory(limits.joint_names, (
        TrajectoryPoint((0.3,) * 6, 2.0, (0.1,) * 6, zeros), TrajectoryPoint((0.5,) * 6, 4.0, zeros, zeros)))
    spline = Spline.build(trajectory, limits, np.zeros(6), np.zeros(6), np.zeros(6))
    spline.sample(3.5, np.zeros((3, 6)))
    for t in (0.0, 0.7, 2.0, 3.1, 4.0, 9.0):
        expected = np.zeros((3, 6))
        Spline.build(trajectory, limits, np.zeros(6), np.zeros(6), np.zeros(6)).sample(t, expected)
        for want, got in zip(expected, spline.state_at(t), strict=False):
            assert np.allclose(want, got, atol=1e-12)
