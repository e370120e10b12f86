"""`plem launch bus:=mock` of a package with a continuous joint, started past half a turn with initial_positions:=:
the driver, the command service, the planner and the view's teach panel take the joint's unwrapped angle."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import viser

from plem.bridge import connect
from plem.control.trajectory import TrajectoryOutcome
from plem.description.validate import validate_package
from plem.view.model import ViewModel
from plem.view.scene import ArmScene
from plem.view.teach import TeachPanel
from tests.e2e.launched import Launch, launched_robot
from tests.integration.arm_shapes import continuous_wrist
from tests.local_servers import free_port

START = [0.0, 0.3, 0.4, 0.1, 0.2, 5.0]


@pytest.fixture(scope="module")
def package(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return continuous_wrist(tmp_path_factory.mktemp("package"))


@pytest.fixture(scope="module")
def robot(tmp_path_factory: pytest.TempPathFactory, package: Path) -> Iterator[Launch]:
    arguments = (f"description_package:={package}", "record:=false", "bridge:=false", "planner:=true",
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


def test_the_teach_panel_gives_a_continuous_joint_a_turn_either_way_of_where_it_is(robot: Launch, package: Path):
    with connect(robot.robot_id) as client:
        client.wait_until_idle(30)
        report = validate_package(package)
        assert report.urdf_xml is not None
        server = viser.ViserServer(host="127.0.0.1", port=free_port())
        try:
            panel = TeachPanel(server, client, ArmScene(server, ViewModel(report.urdf_xml, client.joint_names)),
                               lambda: False)
            assert [(s.min, s.max) for s in panel.sliders][5] == (-np.pi, np.pi)      # finite before it is used
            panel.enabled.value = True
            panel._toggle()  # what ticking the box runs
            position = client.state().position[5]
            slider = panel.sliders[5]
            assert (slider.min, slider.max) == pytest.approx((position - 2 * np.pi, position + 2 * np.pi))
            assert slider.value == pytest.approx(position)
            assert (panel.sliders[0].min, panel.sliders[0].max) == pytest.approx((-3.05, 3.05))
        finally:
            server.stop()
