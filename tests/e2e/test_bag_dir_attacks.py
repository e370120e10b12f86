"""Root's real `plem launch` on a shared bag_dir where user nobody prepared the robot's directory: refused before
anything starts, with the path, the owner and the fix, and nothing written where nobody chose."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.e2e.cli import run_plem
from tests.e2e.launched import clean_environment, new_robot_id
from tests.e2e.test_launch import assert_refused_before_anything_started
from tests.integration.test_bag_dir_safety import OWNER, loot, shared_folder
from tests.integration.test_local_users import as_user


@pytest.fixture
def shared() -> Iterator[Path]:
    """A sticky directory every user may create in, holding nobody's directory `loot`."""
    with shared_folder() as folder:
        yield folder


def launch(shared: Path, robot_id: str, home: Path) -> str:
    """Run root's launch with bag_dir in `shared`; its stderr once it was refused before anything started."""
    result = run_plem("launch", "bus:=mock", f"robot_id:={robot_id}", f"bag_dir:={shared}",
                      env=clean_environment(home))
    assert_refused_before_anything_started(result, [robot_id], home)
    return result.stderr


def test_a_link_planted_as_the_robot_directory_stops_roots_launch(shared: Path, tmp_path: Path):
    robot_id = new_robot_id()
    as_user(lambda: str(os.symlink(shared / "loot", shared / robot_id)))
    stderr = launch(shared, robot_id, tmp_path / "home")
    assert f"{shared / robot_id} is a symbolic link of {OWNER}" in stderr and f"rm {shared / robot_id}" in stderr
    assert loot(shared) == []


def test_a_robot_directory_of_another_user_stops_roots_launch(shared: Path, tmp_path: Path):
    robot_id = new_robot_id()
    as_user(lambda: str((shared / robot_id).mkdir(mode=0o777)))
    stderr = launch(shared, robot_id, tmp_path / "home")
    assert f"{shared / robot_id} belongs to {OWNER}, not to root (uid 0)" in stderr and ".untrusted" in stderr
    assert list((shared / robot_id).iterdir()) == []
