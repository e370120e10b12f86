import stat
from pathlib import Path

import pytest

from plem.core.config import load_config
from plem.description.generate import resolve_description
from plem.description.validate import validate_package
from plem.errors import MultipleErrors
from tests.integration.packages import copy_builtin, tree_fingerprint


@pytest.fixture
def package(tmp_path: Path) -> Path:
    return copy_builtin("indy7_v2", tmp_path / "ws")


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


def test_fresh_directory_every_time(package: Path, tmp_path: Path):
    first = resolve_description(package, temp_root=tmp_path).generated_dir
    second = resolve_description(package, temp_root=tmp_path).generated_dir
    assert first != second and first.is_dir() and second.is_dir()


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
