"""Time parameterisation: every trajectory within the position limits runs within every other limit."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from plem.control.limits import ArmLimits
from plem.control.trajectory import JointTrajectory, TrajectoryPoint
from plem.description.validate import validate_package
from plem.errors import CommandRejected
from plem.planning import Timed, fit_to_limits

CYCLE = 0.001
finite = {"allow_nan": False, "allow_infinity": False}


def point(positions, time, velocities=None, accelerations=None) -> TrajectoryPoint:
    return TrajectoryPoint(tuple(map(float, positions)), float(time),
                           None if velocities is None else tuple(map(float, velocities)),
                           None if accelerations is None else tuple(map(float, accelerations)))


def at_rest(position) -> list[np.ndarray]:
    return [np.asarray(position, dtype=float), np.zeros(len(position)), np.zeros(len(position))]


# -- an independent judge: the motion evaluated on a dense grid, every knot compared across ----------------------
def dense_states(timed: Timed, per_segment: int = 40) -> np.ndarray:
    """Position, velocity, acceleration and jerk at `per_segment` instants of every segment: (4, samples, dof)."""
    motion = timed.motion
    rows = []
    for s in range(motion.segments):
        tau = np.linspace(0.0, motion.knots[s + 1] - motion.knots[s], per_segment)[:, None]
        c = motion.coefficients[s]
        powers = np.arange(c.shape[0])
        terms = []
        for k in range(4):
            factor = np.array([np.prod(np.arange(n - k + 1, n + 1)) if n >= k else 0.0 for n in powers])
            exponent = np.maximum(powers - k, 0)
            terms.append((factor * tau ** exponent) @ c)
        rows.append(np.stack(terms))
    return np.concatenate(rows, axis=1) if rows else np.zeros((4, 0, len(motion.final_positions)))


def states_at(timed: Timed, times: np.ndarray) -> np.ndarray:
    """Position, velocity and acceleration at each of `times` (clamped to the motion): (3, len(times), dof)."""
    motion = timed.motion
    final = np.stack([motion.final_positions, motion.final_velocities, motion.final_accelerations])
    if not motion.segments:
        return np.repeat(final[:, None], len(times), axis=1)
    t = np.clip(times, 0.0, motion.duration)
    s = np.clip(np.searchsorted(motion.knots, t, side="right") - 1, 0, motion.segments - 1)
    tau = (t - motion.knots[s])[:, None]
    c = motion.coefficients[s]  # (samples, ORDER, dof)
    powers = np.arange(c.shape[1])
    rows = []
    for k in range(3):
        factor = np.array([np.prod(np.arange(n - k + 1, n + 1)) if n >= k else 0.0 for n in powers])
        rows.append(np.einsum("sp,spj->sj", factor * tau ** np.maximum(powers - k, 0), c))
    after = t >= motion.duration
    result = np.stack(rows)
    result[:, after] = final[:, None]
    return result


def assert_cycle_steps_within(timed: Timed, limits: ArmLimits, start) -> None:
    """As the loop commands it: from one 1 kHz sample to the next, velocity changes by at most a_max·dt and
    acceleration by at most j_max·dt. Sampled around every knot and on a grid across the motion."""
    motion = timed.motion
    grid = np.linspace(0.0, motion.duration, min(20_000, int(motion.duration / CYCLE) + 2))
    around = (motion.knots[:, None] + np.array([-1.0, -0.5, -0.1, 0.0])[None] * CYCLE).ravel()
    t = np.concatenate([grid, around[around >= 0.0]])
    now, later = states_at(timed, t), states_at(timed, t + CYCLE)
    slack = 1e-6
    assert (np.abs(later[1] - now[1]) <= limits.max_acceleration * CYCLE * (1 + slack) + 1e-9).all()
    assert (np.abs(later[2] - now[2]) <= limits.max_jerk * CYCLE * (1 + slack) + 1e-9).all()
    first = states_at(timed, np.array([0.0]))[:, 0]
    assert (np.abs(first[1] - start[1]) <= limits.max_acceleration * CYCLE * (1 + slack) + 1e-9).all()
    assert (np.abs(first[2] - start[2]) <= limits.max_jerk * CYCLE * (1 + slack) + 1e-9).all()


def assert_within(timed: Timed, limits: ArmLimits, start, points: list[TrajectoryPoint], order: np.ndarray) -> None:
    assert_cycle_steps_within(timed, limits, start)
    motion = timed.motion
    states = dense_states(timed)
    slack = 1e-6
    assert (states[0] >= limits.min_position - slack).all() and (states[0] <= limits.max_position + slack).all()
    for k, kind in ((1, "velocity"), (2, "acceleration"), (3, "jerk")):
        peak = np.abs(states[k]).max(axis=0, initial=0.0)
        assert (peak <= limits.maximum(kind) * (1 + slack) + slack).all(), (kind, peak, limits.maximum(kind))
    # From the start state and at every knot the state is continuous up to what one cycle may change.
    steps = [(start, motion.state_at(0.0))]
    steps += [(motion.state_at(knot - 1e-12), motion.state_at(knot)) for knot in motion.knots[1:-1]]
    for before, after in steps:
        assert np.allclose(before[0], after[0], atol=1e-7)
        assert (np.abs(after[1] - before[1]) <= limits.max_acceleration * CYCLE * (1 + slack) + 1e-9).all()
        assert (np.abs(after[2] - before[2]) <= limits.max_jerk * CYCLE * (1 + slack) + 1e-9).all()
    assert np.allclose(motion.final_positions, np.asarray(points[-1].positions)[order], atol=1e-9)
    assert np.allclose(motion.final_velocities, 0.0) and np.allclose(motion.final_accelerations, 0.0)
    assert motion.duration >= points[-1].time_from_start - 1e-9


def assert_passes_every_point(timed: Timed, points: list[TrajectoryPoint], order: np.ndarray) -> None:
    """Each point is where the motion is at one of its knots, in order."""
    knots = iter(timed.motion.knots)
    for p in points:
        target = np.asarray(p.positions)[order]
        assert any(np.allclose(timed.motion.state_at(t)[0], target, atol=1e-7) for t in knots), p


# -- generated trajectories against generated limits ----------------------------------------------------------------
@st.composite
def arms(draw):
    dof = draw(st.integers(1, 3))
    reach = np.array(draw(st.lists(st.floats(0.5, 3.2), min_size=dof, max_size=dof)))

    def maxima(low, high):
        return np.array(draw(st.lists(st.floats(low, high), min_size=dof, max_size=dof)))

    names = tuple(f"j{i}" for i in range(dof))
    return ArmLimits(names, -reach, reach, maxima(0.3, 4.0), maxima(0.5, 15.0), maxima(2.0, 300.0),
                     np.full(dof, 100.0))


@st.composite
def problems(draw):
    limits = draw(arms())
    dof = limits.dof
    shape = draw(st.sampled_from(["positions", "cubic", "quintic"]))

    def inside(fraction=1.0):
        return np.array([draw(st.one_of(st.floats(-fraction, fraction), st.sampled_from([-fraction, fraction])))
                         for _ in range(dof)]) * limits.max_position

    def anything(bound):
        return np.array(draw(st.lists(st.floats(-bound, bound, **finite), min_size=dof, max_size=dof)))

    moving = draw(st.booleans())
    start = at_rest(inside(0.7) if moving else inside())
    if moving:
        start[1] = anything(0.2) * np.minimum(1.0, limits.max_velocity)
        start[2] = anything(0.3) * np.minimum(1.0, limits.max_acceleration)
    count = draw(st.integers(1, 6))
    first_at_zero = draw(st.booleans()) and not moving
    time, points = 0.0, []
    for index in range(count):
        last = index == count - 1
        if index == 0 and first_at_zero:
            positions = start[0]
        else:
            time += draw(st.sampled_from([1e-3, 0.05, 0.1, 0.5, 2.0, 10.0]))
            positions = inside()
        velocities = None if shape == "positions" else (np.zeros(dof) if last else anything(5.0))
        accelerations = None if shape != "quintic" else (np.zeros(dof) if last else anything(20.0))
        points.append(point(positions, time, velocities, accelerations))
    columns = draw(st.permutations(range(dof)))
    return limits, start, points, np.array(columns)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(problems())
def test_every_trajectory_within_the_position_limits_runs_within_every_limit(problem):
    limits, start, points, columns = problem
    # Send the columns in a shuffled order; `order` maps the arm's joints to the message's columns.
    names = tuple(limits.joint_names[c] for c in columns)
    sent = [point(np.asarray(p.positions)[columns], p.time_from_start,
                  None if p.velocities is None else np.asarray(p.velocities)[columns],
                  None if p.accelerations is None else np.asarray(p.accelerations)[columns]) for p in points]
    order = np.argsort(columns)
    timed = fit_to_limits(JointTrajectory(names, tuple(sent)), limits, start, CYCLE)
    event(timed.change.split(" to ")[0] or "as sent")
    assert_within(timed, limits, start, sent, order)
    assert_passes_every_point(timed, sent, order)
    assert bool(timed.change) == bool(timed.note())


# -- the trajectories ROS users send, on the built-in Indy7 -----------------------------------------------------------
NAMES = tuple(f"joint{i}" for i in range(6))
LIMITS = ArmLimits.from_joint_limits(validate_package("indy7_description").limits, NAMES)
HOME = at_rest(np.zeros(6))


def fit(points) -> Timed:
    return fit_to_limits(JointTrajectory(NAMES, tuple(points)), LIMITS, HOME, CYCLE)


def trapezoid(time: float, duration: float = 2.0, acceleration: float = 0.5, blend: float = 0.5):
    """Position, velocity and acceleration of a trapezoidal velocity profile, as MoveIt's time parameterisation
    samples one."""
    top = acceleration * blend
    distance = top * (duration - blend)
    if time < blend:
        return 0.5 * acceleration * time**2, acceleration * time, acceleration
    if time < duration - blend:
        return 0.5 * top * blend + top * (time - blend), top, 0.0
    left = max(duration - time, 0.0)
    return distance - 0.5 * acceleration * left**2, acceleration * left, -acceleration if left else 0.0


def test_a_one_point_positions_only_goal_runs_smoothly_in_the_time_asked():
    timed = fit([point(np.full(6, 0.5), 10.0)])
    assert timed.motion.duration == pytest.approx(10.0)
    assert timed.note().startswith("smoothed at the points to stay within the limits")
    assert "10.000 s as asked" in timed.note()
    assert_within(timed, LIMITS, HOME, [point(np.full(6, 0.5), 10.0)], np.arange(6))


def test_a_goal_too_fast_for_the_limits_runs_slower_and_says_how_much():
    timed = fit([point(np.full(6, 1.0), 0.5)])
    assert timed.slowdown > 2.0
    assert f"{timed.motion.duration:.3f} s instead of 0.500 s ({timed.slowdown:.2f}x as long)" in timed.note()
    assert "exceeds the acceleration limit of joint0" in timed.note()


def test_a_cubic_trajectory_gets_accelerations_and_keeps_its_timing():
    points = [point(np.full(6, 0.2 * k), k, np.full(6, 0.0 if k == 5 else 0.2)) for k in range(1, 6)]
    timed = fit(points)
    assert timed.motion.duration == pytest.approx(5.0)
    assert "jerk limit" in timed.reason
    assert timed.note() == "smoothed at the points to stay within the limits; 5.000 s as asked"


def test_a_moveit_trapezoid_is_slowed_only_a_little():
    points = []
    for k in range(1, 21):
        p, v, a = trapezoid(0.1 * k)
        points.append(point(np.full(6, p), 0.1 * k, np.full(6, v), np.full(6, a)))
    timed = fit(points)
    assert timed.note().startswith("slowed to stay within the limits")
    assert 1.0 < timed.slowdown < 1.2
    assert_within(timed, LIMITS, HOME, points, np.arange(6))
    assert_passes_every_point(timed, points, np.arange(6))


def test_a_feasible_trajectory_runs_exactly_as_sent():
    points = [point(np.full(6, 0.3), 3.0, np.zeros(6), np.zeros(6))]
    timed = fit(points)
    assert timed.change == "" and timed.note() == ""
    assert timed.motion.segment_kinds == ("quintic",)
    assert timed.motion.duration == 3.0


def test_points_swinging_past_a_limit_are_joined_by_straight_lines_at_rest():
    reach = LIMITS.max_position
    points = [point(reach * (-1) ** k, 0.2 * k, np.full(6, 0.0), np.full(6, 0.0)) for k in range(1, 4)]
    points[1] = point(points[1].positions, 0.4, np.full(6, 2.0), np.full(6, 0.0))  # overshoots as sent
    timed = fit(points)
    assert_within(timed, LIMITS, HOME, points, np.arange(6))
    assert_passes_every_point(timed, points, np.arange(6))


def test_a_point_outside_the_position_limits_is_refused_with_its_index():
    beyond = np.zeros(6)
    beyond[2] = LIMITS.max_position[2] + 0.01
    with pytest.raises(CommandRejected) as refused:
        fit([point(np.full(6, 0.1), 1.0), point(beyond, 2.0)])
    assert "point 1 is outside the position limits of joint2" in refused.value.summary


def test_dense_positions_only_points_are_judged_by_what_changes_within_a_cycle():
    """5000 points 0.2 ms apart: each velocity step is tiny, five of them in one cycle are not."""
    u = np.arange(1, 5001) / 5000
    ramp = 10 * u**3 - 15 * u**4 + 6 * u**5
    points = [point(np.linspace(0.2, 1.5, 6) * r, t) for r, t in zip(ramp, u, strict=True)]
    timed = fit(points)
    assert "steps adding up to" in timed.reason and "points after it, made within one 1 ms cycle" in timed.reason
    assert timed.slowdown > 1.0
    assert_within(timed, LIMITS, HOME, points, np.arange(6))
