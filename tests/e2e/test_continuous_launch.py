"""`plem launch bus:=mock` of a package with a continuous joint, started past half a turn with initial_positions:=:
the driver, the command service and the planner take the joint's unwrapped angle."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest

from plem.bridge import connect
from plem.control.trajectory import TrajectoryOutcome
from tests.e2e.launched import Launch, launched_robot
from tests.integration.arm_shapes import continuous_wrist

START = [0.0, 0.3, 0.4, 0.1, 0.2, 5.0]


@pytest.fixture(scope="module")
def robot(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Launch]:
    root = continuous_wrist(tmp_path_factory.mktemp("package"))
    arguments = (f"description_package:={root}", "record:=false", "bridge:=false", "planner:=true",
                 "initial_positions:=" + ",".join(map(str, START)))
    with launched_robot(tmp_path_factory, *arguments) as launch:
        yield launch


def test_the_launched_arm_starts_where_asked_and_turns_its_continuous_joint_unwrapped(robot: Launch):
    with connect(robot.robot_id) as client:
        client.wait_until_idle(30)
        assert np.allclose(client.state().position, START, atol=1e-3)
        target = [0.0, 0.3, 0.4, 0.1, 0.2, -4.0]
        result = client.move_joints(target).wait(60)
        assert result.outcome is TrajectoryOutcome.SUCCEEDED, result
        assert np.allclose(client.state().position, target, atol=1e-3)
        plan = client.plan([0.0, 0.3, 0.4, 0.1, 0.2, 3.5])
        assert plan.trajectory.points[-1].positions[5] == pytest.approx(3.5)
        assert client.execute_trajectory(plan.trajectory).wait(60).outcome is TrajectoryOutcome.SUCCEEDED
        assert client.state().position[5] == pytest.approx(3.5, abs=1e-3)
