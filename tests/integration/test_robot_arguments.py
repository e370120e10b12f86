"""The in-process Robot checks its arguments as the client does: wrong types, numbers too large for a float and
points under a nanosecond are refused in words before anything is planned, and the arm holds on."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator

import pytest

from plem.control.modes import Mode
from plem.control.trajectory import JointTrajectory
from plem.errors import CommandRejected
from plem.robot import Robot
from tests.integration.robot_fixtures import simulated_robot


@pytest.fixture(scope="module")
def robot() -> Iterator[Robot]:
    robot = simulated_robot()
    robot.start()
    robot.set_mode("hold")
    yield robot
    robot.shutdown()


CALLS: dict[str, Callable[[Robot], object]] = {
    "move_joints huge ints": lambda r: r.move_joints([10**400] * 6),
    "move_joints str speed": lambda r: r.move_joints([0.0] * 6, speed_scale="fast"),  # type: ignore[arg-type]
    "move_joints tolerances dict": lambda r: r.move_joints([0.0] * 6, tolerances={"goal": 1}),  # type: ignore
    "move_joints tiny speed": lambda r: r.move_joints([0.1] * 6, speed_scale=1e-100),
    "execute_trajectory None": lambda r: r.execute_trajectory(None),  # type: ignore[arg-type]
    "set_mode timeout str": lambda r: r.set_mode("hold", timeout="x"),  # type: ignore[arg-type]
    "set_mode mode None": lambda r: r.set_mode(None),  # type: ignore[arg-type]
    "wait_until_idle nan": lambda r: r.wait_until_idle(math.nan),
    "stop goal str": lambda r: r.stop("goal"),  # type: ignore[arg-type]
}


@pytest.mark.parametrize("name", CALLS)
def test_wrong_arguments_are_refused_in_words(robot, name):
    with pytest.raises(CommandRejected) as caught:
        CALLS[name](robot)
    assert caught.value.what and caught.value.why and caught.value.how
    assert robot.mode is Mode.HOLD


@pytest.mark.parametrize("time_from_start", [1e-100, 5e-324])
def test_a_point_under_a_nanosecond_is_refused_and_never_reaches_the_loop(robot, time_from_start):
    """It used to be fitted into a spline of NaN, which the loop caught as a fault."""
    target = (robot.live_state().position + 0.01).tolist()
    trajectory = JointTrajectory.from_lists(robot.joint_names, [{"positions": target,
                                                                 "time_from_start": time_from_start}])
    with pytest.raises(CommandRejected, match="time_from_start"):
        robot.execute_trajectory(trajectory)
    assert robot.mode is Mode.HOLD and not robot.live_state().faulted
