"""Motions as piecewise polynomials: ruckig's motions converted exactly, sampling and state_at agreeing."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from ruckig import ControlInterface, InputParameter, Result, Ruckig, Trajectory

from plem.control.limits import ArmLimits
from plem.control.motion import INSIDE, plan_point_to_point, plan_stop
from plem.control.polynomial import ORDER, PolynomialMotion
from tests import core_references as reference

DOF = 6
LIMITS = ArmLimits(tuple(f"j{i}" for i in range(DOF)), np.full(DOF, -100.0), np.full(DOF, 100.0), np.full(DOF, 1.5),
                   np.full(DOF, 4.0), np.full(DOF, 30.0), np.full(DOF, 100.0))
vectors = st.lists(st.floats(-1.0, 1.0), min_size=DOF, max_size=DOF).map(np.array)


def assert_same_motion(ruckig_motion, polynomial: PolynomialMotion) -> None:
    out = np.zeros((3, DOF))
    position, velocity, acceleration = out
    for t in np.linspace(0.0, ruckig_motion.duration, 401):
        polynomial.sample(t, out)
        expected = ruckig_motion.state_at(t)
        assert np.allclose(position, expected[0], atol=1e-7)
        assert np.allclose(velocity, expected[1], atol=1e-7)
        assert np.allclose(acceleration, expected[2], atol=1e-7)
        assert all(np.allclose(a, b, atol=1e-7) for a, b in zip(polynomial.state_at(t), expected, strict=False))


@settings(max_examples=40, deadline=None)
@given(start=vectors, velocity=vectors, target=vectors, scale=st.floats(0.05, 1.0))
def test_a_point_to_point_motion_becomes_the_same_polynomial(start, velocity, target, scale):
    motion = plan_point_to_point(LIMITS, (start, velocity, np.zeros(DOF)), target, scale)
    polynomial = motion.polynomial()
    assert abs(polynomial.duration - motion.duration) < 1e-9
    assert_same_motion(motion, polynomial)


def ruckig_stop_duration(velocity: float, acceleration: float, max_acceleration: float, max_jerk: float) -> float:
    """The reference: ruckig's time-optimal stop of one joint (velocity interface to v = a = 0)."""
    parameters = InputParameter(1)
    parameters.control_interface = ControlInterface.Velocity
    parameters.current_position, parameters.current_velocity = [0.0], [velocity]
    parameters.current_acceleration = [acceleration]
    parameters.target_velocity, parameters.target_acceleration = [0.0], [0.0]
    parameters.max_velocity, parameters.max_acceleration, parameters.max_jerk = [1e9], [max_acceleration], [max_jerk]
    trajectory = Trajectory(1)
    assert Ruckig(1).calculate(parameters, trajectory) in (Result.Working, Result.Finished)
    return float(trajectory.duration)


@settings(max_examples=200, deadline=None)
@given(velocity=st.floats(-2.0, 2.0), acceleration=st.floats(-4.0, 4.0), max_acceleration=st.floats(0.5, 10.0),
       max_jerk=st.floats(1.0, 500.0))
def test_each_joint_stops_as_quickly_as_ruckig_stops_it(velocity, acceleration, max_acceleration, max_jerk):
    acceleration = float(np.clip(acceleration, -max_acceleration * INSIDE, max_acceleration * INSIDE))
    limits = ArmLimits(("j",), np.array([-1e3]), np.array([1e3]), np.array([10.0]),
                       np.array([max_acceleration]), np.array([max_jerk]), np.array([100.0]))
    stop = plan_stop(limits, (np.zeros(1), np.array([velocity]), np.array([acceleration])))
    expected = ruckig_stop_duration(velocity, acceleration, max_acceleration * INSIDE, max_jerk * INSIDE)
    assert abs(stop.duration - expected) <= 1e-9 + 1e-9 * expected


@settings(max_examples=40, deadline=None)
@given(start=vectors, velocity=vectors, acceleration=vectors)
def test_a_stop_is_continuous_keeps_the_limits_and_ends_at_rest(start, velocity, acceleration):
    acceleration = np.clip(acceleration * 3, -LIMITS.max_acceleration, LIMITS.max_acceleration)
    stop = plan_stop(LIMITS, (start, velocity, acceleration))
    times = np.linspace(0.0, stop.duration, 2001)
    samples = np.array([stop.state_at(t) for t in times])        # (time, 3, dof)
    # phases under a nanosecond are taken at once: the first sample may differ by what one can change
    assert np.allclose(samples[0], [start, velocity, acceleration], atol=2e-9 * LIMITS.max_jerk[0])
    assert np.all(np.abs(samples[:, 2]) <= LIMITS.max_acceleration * (1 + 1e-9))
    step = times[1] - times[0] if stop.duration else 1.0
    assert np.all(np.abs(np.diff(samples[:, 2], axis=0)) <= LIMITS.max_jerk * step * (1 + 1e-6) + 1e-8)
    assert np.all(np.abs(np.diff(samples[:, 1], axis=0)) <= LIMITS.max_acceleration * step * (1 + 1e-6) + 1e-8)
    out = np.zeros((3, DOF))
    assert stop.sample(stop.duration, out)
    assert np.allclose(out[1:], 0.0) and np.allclose(out[0], samples[-1, 0], atol=1e-9)


def test_sampling_jumps_back_and_forth_and_ends_at_the_final_state():
    knots = np.array([0.0, 1.0, 2.0, 3.0])
    coefficients = np.zeros((3, ORDER, 1))
    coefficients[:, 0, 0] = [0.0, 1.0, 2.0]
    coefficients[:, 1, 0] = 1.0                              # position = t, velocity 1
    final = np.array([[3.0], [0.0], [0.0]])
    motion = PolynomialMotion(knots, coefficients, final)
    out = np.zeros((3, 1))
    position, velocity, acceleration = out
    for t in (0.5, 2.5, 0.25, 1.75, 2.999):
        assert not motion.sample(t, out)
        assert np.isclose(position[0], t) and velocity[0] == 1.0
    assert motion.sample(3.0, out) and position[0] == 3.0 and velocity[0] == 0.0
    final[0, 0] = 99.0                                       # the motion keeps its own copy of the final state
    assert motion.final_positions[0] == 3.0


def test_a_motion_without_segments_is_at_its_final_state():
    motion = PolynomialMotion(np.array([0.0]), np.zeros((0, ORDER, 2)), np.array([[1.0, 2.0], [0, 0], [0, 0]]))
    out = np.zeros((3, 2))
    assert motion.duration == 0.0 and motion.sample(0.0, out)
    assert out[0].tolist() == [1.0, 2.0]


@settings(max_examples=100, deadline=None)
@given(durations=st.lists(st.floats(1e-4, 2.0), min_size=1, max_size=12),
       values=st.lists(st.floats(-10.0, 10.0), min_size=12 * ORDER * 2, max_size=12 * ORDER * 2),
       times=st.lists(st.floats(-0.5, 30.0), min_size=1, max_size=20))
def test_the_core_samples_as_the_power_series_reference_does(durations, values, times):
    segments = len(durations)
    knots = np.concatenate([[0.0], np.cumsum(durations)])
    coefficients = np.array(values[:segments * ORDER * 2]).reshape(segments, ORDER, 2)
    final = np.array([[1.0, -1.0], [0.0, 0.0], [0.0, 0.0]])
    motion = PolynomialMotion(knots, coefficients, final)
    out = np.zeros((3, 2))
    for t in times:                                   # in any order: the cursor steps or searches
        done = motion.sample(t, out)
        expected = reference.sample_polynomial(knots, coefficients, final, t)
        assert done == (t >= knots[-1])
        np.testing.assert_allclose(out, expected, rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(np.array(motion.state_at(t)), expected, rtol=1e-12, atol=1e-9)
