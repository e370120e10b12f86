import itertools
from pathlib import Path

import pytest

from plem.description.drives import DriveParameters, drive_parameters
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
    # no two consecutive colinear roll axes
    assert all(a != b or a == "y" for a, b in itertools.pairwise(axes))


@pytest.mark.parametrize("dof", [6, 7])
def test_generated_package_declares_its_drives(tmp_path: Path, dof: int):
    root = create_package(tmp_path, "bot", dof).root
    report = validate_package(root)
    names = [joint.name for joint in report.urdf.actuated_joints]
    assert drive_parameters(report.urdf, names) == tuple(DriveParameters(65536, spec.gear, 1) for spec in ARMS[dof])
    assert {spec.gear for spec in ARMS[dof]} == {121.0, 101.0}
    control = root / "urdf" / "bot.ros2_control.xacro"
    text = control.read_text()
    assert "drives' documentation" in text
    for name in ("vendor_id", "product_code", "revision"):  # offered, commented out
        assert text.count(f'<!-- <param name="{name}">0x00000000</param> -->') == dof


def test_generated_identity_lines_validate_once_uncommented(tmp_path: Path):
    root = create_package(tmp_path, "bot", 6).root
    control = root / "urdf" / "bot.ros2_control.xacro"
    text = control.read_text()
    for name in ("vendor_id", "product_code", "revision"):
        text = text.replace(f'<!-- <param name="{name}">0x00000000</param> -->', f'<param name="{name}">0x1A</param>')
    control.write_text(text)
    report = validate_package(root)
    assert report.findings.problems == []
    drives = drive_parameters(report.urdf, [joint.name for joint in report.urdf.actuated_joints])
    assert all((d.vendor_id, d.product_code, d.revision) == (0x1A, 0x1A, 0x1A) for d in drives)


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
