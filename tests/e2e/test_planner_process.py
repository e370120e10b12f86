"""The planner as `plem launch` runs it: plem's clients and CLI plan through it, and killing it mid-request never
moves or stalls the arm."""

from __future__ import annotations

import os
import signal
import threading
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from plem.bridge.client import RobotClient, connect
from plem.control.modes import Mode
from plem.errors import MoveItCode, PlanningError
from plem.planning import Box, Pose, SceneObject
from plem.planning.goals import MAX_IK_TIMEOUT_S
from tests.e2e.cli import run_plem
from tests.e2e.launched import Launch, launched_robot, process_gone, wait_for

SCENE = """\
objects:
  - name: post
    cylinder: {radius: 0.05, length: 0.6}
    position: [0.45, -0.45, 0.3]
"""


@pytest.fixture(scope="module")
def launch(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Launch]:
    scene = tmp_path_factory.mktemp("scene") / "scene.yaml"
    scene.write_text(SCENE)
    arguments = ("record:=false", "planner:=true", "bridge:=false", f"scene:={scene}")
    with launched_robot(tmp_path_factory, *arguments) as running:
        yield running


@pytest.fixture(scope="module")
def client(launch: Launch) -> Iterator[RobotClient]:
    with connect(launch.robot_id) as connected:
        yield connected


def test_the_summary_names_the_planner_and_its_scene(launch: Launch) -> None:
    assert "planner       running, pid" in launch.output and "groups arm, 1 scene objects" in launch.output


def test_the_cli_plans_around_the_scene_and_moves(launch: Launch, client: RobotClient, tmp_path: Path) -> None:
    dry = run_plem("plan", "--to", "home", "--dry-run", "--robot-id", launch.robot_id, env=launch.env)
    assert dry.returncode == 0, dry.stderr
    assert all(text in dry.stdout for text in ("RRTConnect", "no collision, every limit kept", "nothing moved"))
    moved = run_plem("move", "--to", "home", "--speed-scale", "1", "--robot-id", launch.robot_id, env=launch.env)
    assert moved.returncode == 0, moved.stderr
    assert "trajectory reached its goal" in moved.stdout
    np.testing.assert_allclose(client.live_state().position, client.channels.state.poses["home"], atol=1e-3)

    blocked = run_plem("move", "--to-pose", "0.45", "-0.45", "0.3", "0", "1", "0", "0", "--robot-id", launch.robot_id,
                       env=launch.env)
    assert blocked.returncode == 1 and "Traceback" not in blocked.stderr
    assert "every solution found is in collision" in blocked.stderr and "post" in blocked.stderr

    scene = tmp_path / "more.yaml"
    scene.write_text("objects:\n  - name: crate\n    box: [0.2, 0.2, 0.2]\n    position: [0.6, 0.4, 0.1]\n")
    added = run_plem("scene", "add", str(scene), "--robot-id", launch.robot_id, env=launch.env)
    assert added.returncode == 0 and "added crate" in added.stdout
    listed = run_plem("scene", "list", "--robot-id", launch.robot_id, env=launch.env)
    assert "crate" in listed.stdout and "post" in listed.stdout
    run_plem("scene", "remove", "crate", "--robot-id", launch.robot_id, env=launch.env)
    assert [item.name for item in client.planning_scene().objects()] == ["post"]


def test_python_clients_plan_ik_fk_and_attach(client: RobotClient) -> None:
    tool = client.compute_fk(links=["tcp"])["tcp"]
    lower = Pose((tool.position[0], tool.position[1], tool.position[2] - 0.1), tool.orientation)
    q = client.compute_ik(lower)
    assert client.compute_fk(q, ["tcp"])["tcp"].position == pytest.approx(lower.position, abs=1e-5)
    client.add_objects(SceneObject("block", Box((0.04, 0.04, 0.04)), Pose(tool.position)))
    try:
        assert ("tcp", "block") in client.contacts() or ("link6", "block") in client.contacts()
        client.attach_object("block", "tcp", ["link6"])
        assert client.contacts() == []
        plan = client.plan(q)
        result = client.execute_trajectory(plan.trajectory).wait(30)
        assert result.succeeded, result.message
        held = client.planning_scene().get("block")
        assert held.attached_to == "tcp"
        client.detach_object("block")
        left = client.planning_scene().get("block")
        assert left.attached_to is None
        assert left.pose.position == pytest.approx(lower.position, abs=1e-4)
    finally:
        client.remove_object("block")


def test_killing_the_planner_mid_request_leaves_the_arm_holding(launch: Launch, client: RobotClient) -> None:
    """An unreachable pose keeps the planner busy for the whole IK time; it is killed meanwhile."""
    client.set_mode("hold")
    before = client.live_state()
    pid = launch.component_pid("planner")
    failures: list[PlanningError] = []

    def ask() -> None:
        try:
            client.compute_ik(Pose((5.0, 0.0, 0.0)), timeout=MAX_IK_TIMEOUT_S)
        except PlanningError as error:
            failures.append(error)

    asking = threading.Thread(target=ask)
    idle = _cpu_seconds(pid)
    asking.start()
    assert wait_for(lambda: _cpu_seconds(pid) > idle + 0.2, 10), "the planner never got busy with the request"
    os.kill(pid, signal.SIGKILL)
    asking.join(30)
    assert wait_for(lambda: process_gone(pid), 10)
    assert failures and failures[0].code == MoveItCode.FAILURE and "did not answer" in failures[0].summary
    after = wait_for(lambda: s if (s := client.live_state()).cycle > before.cycle + 500 else None, 10)
    assert after is not None and after.mode is Mode.HOLD and not after.faulted
    np.testing.assert_allclose(after.position, before.position, atol=1e-6)
    launch.wait_for("planner] killed by SIGKILL")
    assert launch.process.poll() is None, "the launch stopped with its planner"
    fallback = run_plem("move", "--to", "zero", "--robot-id", launch.robot_id, env=launch.env)
    assert fallback.returncode == 0 and "no planner runs" in fallback.stdout


def _cpu_seconds(pid: int) -> float:
    """CPU time a process has used (user and system)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
