from pathlib import Path

import pytest

from plem.description.problems import DescriptionError
from plem.description.render import render_xacro
from plem.description.scaffold import ARMS, create_package
from plem.description.validate import validate_package
from plem.launch import load_launch_file
from tests.integration.packages import tree_fingerprint

SPEC_TREE = {"urdf/bot.urdf.xacro", "urdf/bot.ros2_control.xacro", "config/joint_limits.yaml",
             "config/controllers.yaml", "meshes/.gitkeep", "PLEM_COMPAT_VERSION", "package.xml", "CMakeLists.txt",
             "README.md"}


@pytest.mark.parametrize("dof", [6, 7])
def test_generated_package_passes_strict(tmp_path: Path, dof: int):
    result = create_package(tmp_path, "bot", dof, with_moveit=True)
    assert set(result.created) == SPEC_TREE | {"srdf/bot.srdf", "config/kinematics.yaml", "launch/bringup.launch.py"}
    report = validate_package(result.root)
    assert report.findings.problems == [] and report.dof == dof
    assert report.srdf.group_states[0].name == "home"


@pytest.mark.parametrize("dof", [6, 7])
def test_generated_arm_is_kinematically_sensible(tmp_path: Path, dof: int):
    root = create_package(tmp_path, "bot", dof).root
    report = validate_package(root)
    joints = report.urdf.actuated_joints
    assert {j.type for j in joints} == {"revolute"}
    assert all(j.lower < 0 < j.upper and j.velocity > 0 and j.effort > 0 for j in joints)
    reach = sum(spec.offset for spec in ARMS[dof][1:]) + ARMS[dof][-1].length
    assert 0.8 <= reach <= 1.3
    assert all(spec.mass > 0 and spec.length > 0 for spec in ARMS[dof])
    axes = [spec.axis for spec in ARMS[dof]]
    assert all(a != b or a == "y" for a, b in zip(axes, axes[1:]))  # no two consecutive colinear roll axes


def test_minimal_package_and_prefix(tmp_path: Path):
    result = create_package(tmp_path, "bot", 6, launch=False)
    assert set(result.created) == SPEC_TREE
    rendered = render_xacro(result.root / "urdf" / "bot.urdf.xacro", {"prefix": "r_"})
    assert 'name="r_joint1"' in rendered and 'name="joint1"' not in rendered


def test_rerun_skips_identical_and_refuses_to_clobber(tmp_path: Path):
    root = create_package(tmp_path, "bot", 6).root
    again = create_package(tmp_path, "bot", 6)
    assert again.created == [] and len(again.identical) == len(SPEC_TREE) + 1
    limits = root / "config" / "joint_limits.yaml"
    limits.write_text(limits.read_text().replace("max_velocity: 2", "max_velocity: 1.5"))
    before = tree_fingerprint(root)
    (root / "urdf" / "bot.ros2_control.xacro").unlink()
    with pytest.raises(DescriptionError) as error:
        create_package(tmp_path, "bot", 6)
    assert "config/joint_limits.yaml" in error.value.why
    assert not (root / "urdf" / "bot.ros2_control.xacro").exists()  # nothing written when refusing
    forced = create_package(tmp_path, "bot", 6, force=True)
    assert forced.overwritten == ["config/joint_limits.yaml"] and forced.created == ["urdf/bot.ros2_control.xacro"]
    assert tree_fingerprint(root) != before


def test_launch_file_describes_the_bringup(tmp_path: Path):
    root = create_package(tmp_path, "bot", 7).root
    description = load_launch_file(root / "launch" / "bringup.launch.py")
    assert description.description_package == "bot_description"
    assert description.enabled == ["rt_driver", "bridge", "recorder", "planner"]


@pytest.mark.parametrize("name, dof", [("Bot", 6), ("9bot", 6), ("b-ot", 6), ("bot", 5), ("bot", 8), ("a__b", 6)])
def test_bad_arguments(tmp_path: Path, name: str, dof: int):
    with pytest.raises(DescriptionError):
        create_package(tmp_path, name, dof)
    assert list(tmp_path.iterdir()) == []
