import fcntl
import os
import stat
from pathlib import Path

import pytest

from plem.core.config import load_config
from plem.description.generate import KEPT_GENERATED_DIRS, generated_directories, resolve_description
from plem.description.validate import validate_package
from plem.errors import MultipleErrors
from tests.integration.packages import copy_builtin, tree_fingerprint


@pytest.fixture
def package(tmp_path: Path) -> Path:
    """An external package without controllers.yaml (the built-in arms ship theirs)."""
    root = copy_builtin("indy7_v2", tmp_path / "ws")
    (root / "config" / "controllers.yaml").unlink()
    return root


def test_missing_controllers_are_generated_outside_the_package(package: Path, tmp_path: Path, caplog):
    before = tree_fingerprint(package)
    caplog.set_level("INFO", logger="plem.launch")
    resolved = resolve_description(package, cycle_time_us=500, temp_root=tmp_path / "tmp")
    assert tree_fingerprint(package) == before
    assert resolved.generated_dir.parent == tmp_path / "tmp"
    assert resolved.generated_dir.name.startswith("wim_launch_")
    assert resolved.controllers == resolved.generated_dir / "controllers.yaml"
    assert resolved.kinematics == package / "config" / "kinematics.yaml"
    assert load_config(resolved.controllers, "controller_manager.ros__parameters.update_rate", int) == 2000
    joints = load_config(resolved.controllers, "arm_controller.ros__parameters.joints", list[str])
    assert joints == [f"joint{i}" for i in range(6)]
    assert "Auto-generating controllers.yaml from joint_limits.yaml" in caplog.text
    assert stat.S_IMODE(resolved.generated_dir.stat().st_mode) == 0o700   # owner-only, like the robot's other files
    assert stat.S_IMODE(resolved.controllers.stat().st_mode) == 0o600


def test_generated_controllers_pass_validation_when_kept(package: Path, tmp_path: Path):
    resolved = resolve_description(package, temp_root=tmp_path)
    (package / "config" / "controllers.yaml").write_bytes(resolved.controllers.read_bytes())
    report = validate_package(package)
    assert report.files.controllers == package / "config" / "controllers.yaml"
    assert report.passed(strict=True)


def test_kinematics_generated_only_with_an_srdf(package: Path, tmp_path: Path):
    (package / "config" / "kinematics.yaml").unlink()
    resolved = resolve_description(package, temp_root=tmp_path)
    assert "Auto-generating kinematics.yaml (KDL solver)" in resolved.log_lines
    assert load_config(resolved.kinematics, "arm.kinematics_solver", str) == "kdl_kinematics_plugin/KDLKinematicsPlugin"
    assert load_config(resolved.kinematics, "arm.kinematics_solver_attempts", int) == 3
    for path in (package / "srdf").iterdir():
        path.unlink()
    without = resolve_description(package, temp_root=tmp_path)
    assert without.log_lines[0] == "SRDF not found - MoveIt will not be started"
    assert without.kinematics is None and not without.planner_enabled


def test_the_same_files_reuse_their_directory_and_other_files_get_another(package: Path, tmp_path: Path):
    first = resolve_description(package, temp_root=tmp_path)
    again = resolve_description(package, temp_root=tmp_path)
    other = resolve_description(package, cycle_time_us=500, temp_root=tmp_path)
    assert again.generated_dir == first.generated_dir and first.generated_dir.is_dir()
    assert other.generated_dir != first.generated_dir
    assert load_config(other.controllers, "controller_manager.ros__parameters.update_rate", int) == 2000
    assert load_config(again.controllers, "controller_manager.ros__parameters.update_rate", int) == 1000


def test_a_changed_directory_is_not_reused(package: Path, tmp_path: Path):
    first = resolve_description(package, temp_root=tmp_path)
    first.controllers.write_text("# edited by hand\n")
    assert resolve_description(package, temp_root=tmp_path).generated_dir != first.generated_dir


def make_old_directories(root: Path, count: int) -> list[Path]:
    """`count` generated directories of earlier launches, oldest first, none of them in use."""
    made = []
    for index in range(count):
        path = root / f"wim_launch_20200101_0000{index:02d}"
        path.mkdir(mode=0o700)
        (path / "controllers.yaml").write_text(f"# launch {index}\n")
        os.utime(path, (1_600_000_000 + index, 1_600_000_000 + index))
        made.append(path)
    return made


def test_only_the_newest_directories_are_kept(package: Path, tmp_path: Path):
    make_old_directories(tmp_path, KEPT_GENERATED_DIRS + 5)
    current = resolve_description(package, temp_root=tmp_path).generated_dir
    kept = generated_directories(tmp_path)
    assert len(kept) == KEPT_GENERATED_DIRS and kept[0] == current


def test_a_directory_a_running_launch_uses_is_never_removed(package: Path, tmp_path: Path):
    old = make_old_directories(tmp_path, KEPT_GENERATED_DIRS + 2)
    fd = os.open(old[0], os.O_RDONLY | os.O_DIRECTORY)   # the oldest, held as a running launch holds its own
    try:
        fcntl.flock(fd, fcntl.LOCK_SH)
        in_use = resolve_description(package, temp_root=tmp_path)
        assert old[0].is_dir() and not old[1].exists()
        assert in_use.generated_dir in generated_directories(tmp_path)
    finally:
        os.close(fd)


def test_links_and_other_files_named_like_generated_directories_are_left_alone(package: Path, tmp_path: Path):
    target = tmp_path / "elsewhere"
    target.mkdir()
    (tmp_path / "wim_launch_link").symlink_to(target)
    (tmp_path / "wim_launch_file").write_text("not a directory")
    resolve_description(package, temp_root=tmp_path)
    assert (tmp_path / "wim_launch_link").is_symlink() and (tmp_path / "wim_launch_file").is_file()
    assert tmp_path / "wim_launch_link" not in generated_directories(tmp_path)


def test_nothing_generated_when_all_files_exist(package: Path, tmp_path: Path):
    (package / "config" / "controllers.yaml").write_text(
        "arm_controller:\n  ros__parameters:\n    joints: [joint0, joint1, joint2, joint3, joint4, joint5]\n")
    resolved = resolve_description(package, temp_root=tmp_path)
    assert resolved.generated_dir is None and resolved.generated == []


def test_invalid_package_is_refused_with_every_error(package: Path, tmp_path: Path):
    (package / "PLEM_COMPAT_VERSION").unlink()
    (package / "config" / "joint_limits.yaml").unlink()
    with pytest.raises(MultipleErrors) as error:
        resolve_description(package, temp_root=tmp_path)
    rendered = error.value.render()
    assert "PLEM_COMPAT_VERSION" in rendered and "joint_limits.yaml" in rendered
    assert not list(tmp_path.glob("wim_launch_*"))
