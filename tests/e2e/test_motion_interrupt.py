"""Ctrl-C of `plem move` mid-motion against `plem launch bus:=mock`: the motion is canceled, the arm stops, exit 130."""

from __future__ import annotations

import os
import signal
import subprocess
from collections.abc import Iterator

import numpy as np
import pytest

from plem.bridge import connect
from plem.control.modes import Mode
from tests.e2e.cli import plem_executable
from tests.e2e.launched import Launch, launched_robot, wait_for

DISTANCE_RAD = 0.8
MOVING_RAD = 0.01


@pytest.fixture(scope="module")
def robot(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Launch]:
    with launched_robot(tmp_path_factory, "bridge:=false", "record:=false") as launch:
        yield launch


def ignore_sigint() -> None:
    """What a shell does to a background job (`plem move ... &`): SIGINT ignored before plem starts."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


@pytest.mark.parametrize("inherited", ["default", "ignored"])
def test_ctrl_c_cancels_the_move_and_the_arm_stops_short_of_the_goal(robot: Launch, inherited: str):
    with connect(robot.robot_id) as client:
        start = client.live_state().position.copy()
        goal = start + np.where(start > 0, -DISTANCE_RAD, DISTANCE_RAD)   # inside the limits wherever it starts
        move = subprocess.Popen(
            [plem_executable(), "move", "--robot-id", robot.robot_id, "--to", ",".join(f"{v:.4f}" for v in goal),
             "--speed-scale", "0.05"], stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
            text=True, env={**os.environ, **robot.env}, preexec_fn=ignore_sigint if inherited == "ignored" else None)
        try:
            moving = wait_for(lambda: np.abs(client.live_state().position - start).max() > MOVING_RAD, 120)
            assert moving, "the arm did not start moving"
            move.send_signal(signal.SIGINT)
            out, err = move.communicate(timeout=60)
        finally:
            if move.poll() is None:
                move.kill()
                move.wait()
        assert move.returncode == 130, (move.returncode, out, err)
        assert "interrupted (Ctrl-C): motion canceled, the arm stopped smoothly" in err, err
        assert "goal" not in out, out
        state = client.live_state()
        assert state.mode is Mode.HOLD and not state.faulted
        assert np.abs(state.velocity).max() < 1e-3, state.velocity
        travelled = np.abs(state.position - start).max()
        assert travelled < 0.5 * DISTANCE_RAD, (start, state.position, goal)
