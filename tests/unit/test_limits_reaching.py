"""An arm outside a joint's range is never trapped: motions back toward the range are accepted, never farther out.

A joint without position limits (a continuous joint) has the range (-inf, inf) and no position check.
"""

from __future__ import annotations

import numpy as np
import pytest

from plem.control.limits import ArmLimits
from plem.control.motion import plan_point_to_point
from plem.control.trajectory import JointTrajectory
from plem.errors import CommandRejected
from plem.planning import fit_to_limits

JOINTS = ("a", "b", "c")
#: b's range excludes 0 (like FR3's joint4); c is a continuous joint.
LIMITS = ArmLimits(JOINTS, np.array([-1.0, -3.04, -np.inf]), np.array([1.0, -0.15, np.inf]), np.full(3, 2.0),
                   np.full(3, 4.0), np.full(3, 40.0), np.full(3, 10.0))
CYCLE = 0.001
OUTSIDE = np.array([0.0, 0.0, 0.0])   # b at 0 rad, 0.15 rad above its range


def at_rest(position: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return np.asarray(position, dtype=float), np.zeros(3), np.zeros(3)


def trajectory(*positions: list[float]) -> JointTrajectory:
    return JointTrajectory.from_lists(JOINTS, [{"positions": p, "time_from_start": 1.0 + k}
                                               for k, p in enumerate(positions)])


def test_reaching_widens_only_the_joints_outside_to_where_they_are():
    assert LIMITS.reaching([0.5, -1.0, 100.0]) is LIMITS
    widened = LIMITS.reaching(OUTSIDE)
    assert widened.min_position.tolist() == [-1.0, -3.04, -np.inf]
    assert widened.max_position.tolist() == [1.0, 0.0, np.inf]


def test_a_continuous_joint_has_no_position_check():
    LIMITS.check_positions(np.array([0.0, -1.0, 1e6]), "the target")
    motion = plan_point_to_point(LIMITS, at_rest(np.array([0.0, -1.0, 3.0])), np.array([0.0, -1.0, -4.0]))
    assert motion.final_positions[2] == pytest.approx(-4.0)


def test_a_move_back_into_the_range_is_accepted_and_never_goes_farther_out():
    motion = plan_point_to_point(LIMITS, at_rest(OUTSIDE), np.array([0.0, -1.0, 0.0]))
    positions = np.array([motion.state_at(t)[0] for t in np.linspace(0.0, motion.duration, 400)])
    assert np.all(np.diff(positions[:, 1]) <= 1e-12)        # b only comes down, toward its range
    assert positions[-1, 1] == pytest.approx(-1.0)
    partial = plan_point_to_point(LIMITS, at_rest(OUTSIDE), np.array([0.0, -0.1, 0.0]))   # closer, still outside
    assert partial.final_positions[1] == pytest.approx(-0.1)


def test_a_move_farther_out_says_how_to_come_back():
    with pytest.raises(CommandRejected) as refused:
        plan_point_to_point(LIMITS, at_rest(OUTSIDE), np.array([0.0, 0.2, 0.0]))
    error = refused.value
    assert error.summary == "the target takes b farther outside its position limits"
    assert "where it is (0 rad, outside its range)" in error.what and "[-3.04, -0.15]" in error.what
    assert "brings b back into [-3.04, -0.15] rad" in error.how
    with pytest.raises(CommandRejected, match="outside the position limits of a"):   # the others keep their range
        plan_point_to_point(LIMITS, at_rest(OUTSIDE), np.array([1.5, -1.0, 0.0]))


def test_a_trajectory_back_into_the_range_is_accepted_from_outside_only():
    back = trajectory([0.0, 0.0, 0.0], [0.0, -0.1, 0.5], [0.0, -0.6, 1.0])   # point 0 is where the arm is
    timed = fit_to_limits(back, LIMITS.reaching(OUTSIDE), at_rest(OUTSIDE), CYCLE)
    assert timed.motion.final_positions.tolist() == pytest.approx([0.0, -0.6, 1.0])
    with pytest.raises(CommandRejected, match="point 0 is outside the position limits of b"):
        fit_to_limits(back, LIMITS, at_rest(np.array([0.0, -1.0, 0.0])), CYCLE)
    out = trajectory([0.0, -0.1, 0.0], [0.0, 0.1, 0.0])
    with pytest.raises(CommandRejected, match="point 1 takes b farther outside"):
        fit_to_limits(out, LIMITS.reaching(OUTSIDE), at_rest(OUTSIDE), CYCLE)
