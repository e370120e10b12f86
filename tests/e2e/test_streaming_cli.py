"""`plem speed` and `plem jog` run as a user runs them, against `plem launch bus:=mock`; what the arm did is read from
shared memory."""

from __future__ import annotations

import os
import signal
import subprocess
import time
from collections.abc import Iterator

import numpy as np
import pytest

from plem.bridge.client import RobotClient
from plem.control.modes import Mode
from tests.e2e.cli import plem_executable, run_plem
from tests.e2e.launched import Launch, launched_robot, wait_until


@pytest.fixture(scope="module")
def robot(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Launch]:
    with launched_robot(tmp_path_factory, "bridge:=false", "record:=false") as launch:
        yield launch


def plem(robot: Launch, *args: str) -> subprocess.CompletedProcess[str]:
    return run_plem(*args, "--robot-id", robot.robot_id, env=robot.env)


def at_rest(client: RobotClient) -> bool:
    state = client.live_state()
    return state.mode is Mode.HOLD and not state.command_velocity.any()


def test_speed_sets_the_override_and_prints_the_factor_asked_and_in_force(robot: Launch, client: RobotClient) -> None:
    try:
        set_it = plem(robot, "speed", "0.3")
        assert set_it.returncode == 0, set_it.stderr
        assert set_it.stdout.strip() == f"{robot.robot_id}: speed override 0.3 asked, 0.3 in force"
        assert client.stream_status().override_target == 0.3 and abs(client.speed_override - 0.3) < 1e-6
        shown = plem(robot, "speed")
        assert shown.returncode == 0, shown.stderr
        assert shown.stdout.strip() == f"{robot.robot_id}: speed override 0.3 in force, 0.3 asked"
    finally:
        client.set_speed_override(1.0)


@pytest.mark.parametrize(("args", "why"), [(("speed", "1.5"), "WHY: got 1.5"), (("speed", "nan"), "WHY: got nan"),
                                           (("jog", "joint9", "0.1"), "has no joint 'joint9'"),
                                           (("jog", "0", "100"), "WHY: got 100 rad/s"),
                                           (("jog", "0", "0.1", "--duration", "0"), "WHY: --duration 0")])
def test_bad_values_are_usage_errors_and_nothing_moves(robot: Launch, client: RobotClient, args: tuple[str, ...],
                                                       why: str) -> None:
    before = client.live_state().command_position.copy()
    result = plem(robot, *args)
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert "WHAT: " in result.stderr and why in result.stderr and "HOW: e.g. " in result.stderr, result.stderr
    assert np.array_equal(client.live_state().command_position, before)
    assert client.stream_status().override_target == 1.0


def test_jog_moves_one_joint_for_its_duration_then_comes_to_rest(robot: Launch, client: RobotClient) -> None:
    client.set_mode("hold")
    start = client.live_state().command_position.copy()
    velocity = -0.2 if start[1] > 0 else 0.2
    result = plem(robot, "jog", "joint1", f"{velocity}", "--duration", "0.5")   # a negative value is not an option
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith(f"{robot.robot_id}: jogged joint1 at {velocity:g} rad/s for 0.5 s; the arm came "
                                    "to rest at ["), result.stdout
    assert at_rest(client)
    moved = client.live_state().command_position - start
    assert np.all(moved[[0, 2, 3, 4, 5]] == 0.0)
    # 0.5 s at the velocity, then the stream's 0.1 s timeout and the ramp to rest; by index the same way.
    assert 0.45 < moved[1] / velocity < 0.8, moved
    again = plem(robot, "jog", "1", f"{-velocity}", "--duration", "0.5")
    assert again.returncode == 0, again.stderr
    assert abs(client.live_state().command_position[1] - start[1]) < 0.04


def test_ctrl_c_stops_a_jog_at_once_and_exits_130(robot: Launch, client: RobotClient) -> None:
    client.set_mode("hold")
    start = client.live_state().command_position.copy()
    velocity = -0.3 if start[0] > 0 else 0.3
    jog = subprocess.Popen([plem_executable(), "jog", "joint0", f"{velocity}", "--duration", "30", "--robot-id",
                            robot.robot_id], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                           env={**os.environ, **robot.env})
    try:
        assert wait_until(lambda: abs(client.live_state().command_velocity[0]) >= abs(velocity) * 0.99, 20)
        jog.send_signal(signal.SIGINT)
        sent = time.monotonic()
        out, err = jog.communicate(timeout=10)
    finally:
        if jog.poll() is None:
            jog.kill()
    assert jog.returncode == 130, err
    assert time.monotonic() - sent < 5.0
    assert "interrupted (Ctrl-C): stream stopped, the arm stopped smoothly within its limits at [" in err, err
    assert at_rest(client), "the command ends only once the arm stands still"
    assert client.last_fault() is None
