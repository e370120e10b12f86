"""Profile files: created exclusively, read only when regular and small, and every bad one is a ProfileError."""

import json
import os
from pathlib import Path

import pytest

from plem.errors import ProfileError
from plem.robot import RobotProfile
from plem.robot.profile import ProfileExists


def test_exclusive_save_never_replaces(tmp_path: Path):
    path = tmp_path / "profiles" / "A1.json"
    RobotProfile(robot_serial="A1", joint_offsets=[1] * 6).save(path, exclusive=True)
    with pytest.raises(ProfileExists) as error:
        RobotProfile(robot_serial="A1", joint_offsets=[2] * 6).save(path, exclusive=True)
    assert "--force" in error.value.how
    assert RobotProfile.load(path).joint_offsets == [1] * 6
    assert os.listdir(path.parent) == ["A1.json"]
    assert oct(path.stat().st_mode & 0o777) == "0o600"
    RobotProfile(robot_serial="A1", joint_offsets=[3] * 6).save(path)
    assert RobotProfile.load(path).joint_offsets == [3] * 6


def test_unwritable_folder_is_a_profile_error():
    with pytest.raises(ProfileError, match="Cannot write profile file"):
        RobotProfile(robot_serial="A1", joint_offsets=[1] * 6).save(Path("/proc/1/profiles/A1.json"))


@pytest.mark.parametrize(("make", "fragment"), [
    (lambda path: os.mkfifo(path), "is a FIFO"),
    (lambda path: os.symlink("/dev/zero", path), "is a character device"),
    (lambda path: path.write_text("[" * 100_000), "of at most 64.0 KiB"),
    (lambda path: path.write_text("[" * 5000), "nest too deeply"),
    (lambda path: path.write_text(json.dumps({"robot_serial": "A1"})[:-1] + ', "joint_offsets": [' + "7" * 5000
                                  + "]}"), "a number has more than"),
])
def test_hostile_files_are_refused(tmp_path: Path, make, fragment: str):
    path = tmp_path / "A1.json"
    make(path)
    with pytest.raises(ProfileError) as error:
        RobotProfile.load(path)
    assert fragment in error.value.render()
    assert "--force" in error.value.how
