"""Motions as piecewise polynomials: ruckig's motions converted exactly, sampling and state_at agreeing."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from plem.control.limits import ArmLimits
from plem.control.motion import plan_point_to_point, plan_stop
from plem.control.polynomial import ORDER, PolynomialMotion

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


@settings(max_examples=20, deadline=None)
@given(start=vectors, velocity=vectors, acceleration=vectors)
def test_a_stop_becomes_the_same_polynomial(start, velocity, acceleration):
    motion = plan_stop(LIMITS, (start, velocity, acceleration * 3))
    assert_same_motion(motion, motion.polynomial())


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
