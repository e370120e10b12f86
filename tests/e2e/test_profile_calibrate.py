"""`plem profile calibrate` on `plem launch bus:=mock`: the zero pose it assumes, what it shows, --force and backups."""

from __future__ import annotations

import json
import os
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from plem.bridge import connect
from tests.e2e.cli import run_plem
from tests.e2e.launched import Launch, launched_robot, wait_until


@pytest.fixture(scope="module")
def robot(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Launch]:
    with launched_robot(tmp_path_factory, "bridge:=false", "record:=false") as launch:
        yield launch


def calibrate(launch: Launch, *extra: str):
    return run_plem("profile", "calibrate", "--serial", "CAL01", "--robot-id", launch.robot_id, *extra,
                    env=launch.env)


def profiles(launch: Launch) -> Path:
    return Path(launch.env["PLEM_HOME"]) / "profiles"


def move_to(launch: Launch, name: str) -> list[int]:
    """Move to a named state of the SRDF and wait until the arm rests; the raw encoder counts there."""
    with connect(launch.robot_id) as client:
        client.set_mode("hold")
        target = client.channels.state.poses[name]
        client.move_joints(target).wait(60)
        assert wait_until(lambda: np.abs(client.live_state().velocity).max() < 1e-4, 30)
        since = client.live_state().monotonic_ns
        assert wait_until(lambda: (client.stats() or {}).get("monotonic_ns", 0) > since, 10)
        return list(client.stats()["encoders"])


def test_calibrate_assumes_the_zero_pose_shows_it_and_replaces_a_profile_only_with_force(robot: Launch):
    raw = move_to(robot, "zero")
    first = calibrate(robot)
    assert first.returncode == 0, first.stderr
    assert "zero pose" in first.stdout and "not the SRDF's home" in first.stdout, first.stdout
    for count in raw:
        assert str(count) in first.stdout and str(-count) in first.stdout, first.stdout   # raw and new offset
    assert first.stderr == "", first.stderr
    path = profiles(robot) / "CAL01.json"
    saved = path.read_text()
    assert json.loads(saved)["joint_offsets"] == [-count for count in raw]

    again = calibrate(robot)
    assert again.returncode == 1
    assert "ERROR: Profile CAL01 already exists" in again.stderr and "HOW:" in again.stderr and "--force" in \
        again.stderr, again.stderr
    assert path.read_text() == saved, "a refused calibration writes nothing"

    raw_home = move_to(robot, "home")
    forced = calibrate(robot, "--force")
    assert forced.returncode == 0, forced.stderr
    assert "WARNING" in forced.stderr and "'home'" in forced.stderr, forced.stderr   # home is not the zero pose
    backups = sorted(path.parent.glob("CAL01.json.*.bak"))
    assert len(backups) == 1 and f"Kept the previous profile as {backups[0]}" in forced.stdout, forced.stdout
    assert backups[0].read_text() == saved
    assert json.loads(path.read_text())["joint_offsets"] == [-count for count in raw_home]
    assert oct(os.stat(backups[0]).st_mode & 0o777) == oct(0o600)

    listed = run_plem("profile", "list", env=robot.env)
    assert listed.returncode == 0 and listed.stdout.count("CAL01") == 1, listed.stdout


def test_create_force_keeps_the_replaced_profile(robot: Launch):
    create = ("profile", "create", "--serial", "CAL02", "--offsets", "1,2,3,4,5,6")
    assert run_plem(*create, env=robot.env).returncode == 0
    replaced = run_plem("profile", "create", "--serial", "CAL02", "--offsets", "7,8,9,10,11,12", "--force",
                        env=robot.env)
    assert replaced.returncode == 0, replaced.stderr
    (backup,) = profiles(robot).glob("CAL02.json.*.bak")
    assert f"Kept the previous profile as {backup}" in replaced.stdout
    assert json.loads(backup.read_text())["joint_offsets"] == [1, 2, 3, 4, 5, 6]


def test_calibrating_again_keeps_the_profiles_payload(robot: Launch):
    assert run_plem("profile", "create", "--serial", "CAL03", "--offsets", "1,2,3,4,5,6", env=robot.env).returncode == 0
    path = profiles(robot) / "CAL03.json"
    stored = json.loads(path.read_text())
    stored["payload"] = {"mass": 2.0, "center_of_mass": [0.0, 0.01, 0.1], "inertia": [0.01, 0, 0, 0.02, 0, 0.02]}
    path.write_text(json.dumps(stored))
    calibrated = run_plem("profile", "calibrate", "--serial", "CAL03", "--robot-id", robot.robot_id, "--force",
                          env=robot.env)
    assert calibrated.returncode == 0, calibrated.stderr
    replaced = json.loads(path.read_text())
    assert replaced["joint_offsets"] != [1, 2, 3, 4, 5, 6] and replaced["payload"] == stored["payload"]
