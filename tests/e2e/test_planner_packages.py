"""A launched arm whose package leaves out its jerk limits (and the wrist's acceleration limits) and spells its home
state `Home`, as upstream packages do: the launch states the limits plem derives, `plem plan` and `plem move` find
`home`, and every plan runs on the simulated arm exactly as planned, never slowed by the driver."""

from __future__ import annotations

import re
from collections.abc import Iterator

import numpy as np
import pytest

from plem.bridge.client import RobotClient, connect
from plem.control.events import EventKind
from tests.e2e.cli import run_plem
from tests.e2e.launched import Launch, launched_robot
from tests.integration.packages import copy_builtin
from tests.integration.test_planner_packages import KINOVA_HOME, without

PLANNED = re.compile(r"RRTConnect: (\d+\.\d+) s motion")
WRIST = ("joint3", "joint4", "joint5")


@pytest.fixture(scope="module")
def launch(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Launch]:
    package = copy_builtin("indy7_v2", tmp_path_factory.mktemp("package"))
    for edit in (without("max_jerk"), without("max_acceleration", joints=WRIST), KINOVA_HOME):
        edit(package)
    with launched_robot(tmp_path_factory, f"description_package:={package}", "planner:=true", "record:=false",
                        "bridge:=false") as running:
        yield running


@pytest.fixture(scope="module")
def client(launch: Launch) -> Iterator[RobotClient]:
    with connect(launch.robot_id) as connected:
        yield connected


def test_the_launch_states_the_limits_it_derives(launch: Launch, client: RobotClient) -> None:
    assert "max_acceleration = max_velocity / 0.5 s (joint3 6.283, joint4 6.283, joint5 6.283 rad/s²)" in launch.output
    assert "plem move --to Home, plem topic list" in launch.output  # the hint names the SRDF's own spelling
    assert "max_jerk = max_acceleration / 0.1 s (joint0 30, joint1 30, joint2 30, joint3 62.83" in launch.output
    limits = client.limits  # what the core enforces, as the driver published it
    np.testing.assert_allclose(limits.max_acceleration, [3.0, 3.0, 3.0, *(limits.max_velocity[3:] / 0.5)])
    np.testing.assert_allclose(limits.max_jerk, limits.max_acceleration / 0.1)


def executed_durations(client: RobotClient, run: object) -> tuple[str, list[float]]:
    """What `run()` (a CLI call) printed, and the duration of each motion the driver started meanwhile."""
    events = client.events(timeout=0)
    result = run()  # type: ignore[operator]
    assert result.returncode == 0, result.stderr
    started = [event for event in events if event.kind is EventKind.MOTION_STARTED]
    return result.stdout, [float(event.reason.split(" s")[0]) for event in started]


def test_plans_to_home_and_to_a_pose_run_exactly_as_planned(launch: Launch, client: RobotClient) -> None:
    env, robot = launch.env, ("--robot-id", launch.robot_id)
    home = client.channels.state.poses["Home"]
    tool = client.compute_fk(home, ["tcp"])["tcp"]
    pose = [str(v) for v in (tool.position[0], tool.position[1], tool.position[2] - 0.15, *tool.orientation)]
    for target in (("--to", "home"), ("--to-pose", *pose)):
        dry = run_plem("plan", *target, "--dry-run", *robot, env=env)
        assert dry.returncode == 0, dry.stderr
        assert "every limit kept" in dry.stdout and "nothing moved" in dry.stdout
    for target in (("--to", "home"), ("--to-pose", *pose)):
        printed, durations = executed_durations(
            client, lambda target=target: run_plem("move", *target, "--speed-scale", "1", *robot, env=env))
        planned = PLANNED.search(printed)
        assert planned and "every limit kept" in printed and "reached its goal" in printed, printed
        assert "instead of" not in printed and "to stay within the limits" not in printed, printed
        assert durations == [pytest.approx(float(planned.group(1)), abs=1.5e-3)], (printed, durations)
    np.testing.assert_allclose(client.compute_fk(links=["tcp"])["tcp"].position, [float(v) for v in pose[:3]],
                               atol=1e-3)


def test_a_name_the_srdf_lacks_lists_the_states_there_are(launch: Launch) -> None:
    refused = run_plem("move", "--to", "ready", "--robot-id", launch.robot_id, env=launch.env)
    assert refused.returncode == 1 and "Traceback" not in refused.stderr
    assert "unknown named state 'ready'" in refused.stderr and "Home, zero" in refused.stderr
