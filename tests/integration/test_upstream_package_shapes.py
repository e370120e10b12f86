"""Shapes of real upstream description packages, each rebuilt as a small mutation of a built-in package.

UR's and Indy's joint_limits.yaml use xacro's unit tags, MoveIt packages write kinematics.yaml and controllers.yaml
as ROS 2 parameters files, clones live in folders named otherwise than their package, device macros emit a
second ros2_control block, indy-ros2 names a link and a joint alike.
"""

from __future__ import annotations

import math
import shutil

import pytest

from plem.core.paths import BUILTIN_PACKAGES_DIR
from plem.description.controllers import read_controllers
from plem.description.package_yaml import read_package_yaml
from plem.errors import ConfigError
from plem.planning.groups import read_groups
from tests.integration.test_broken_packages import (
    CONTROLLERS,
    JOINTS,
    KINEMATICS,
    LIMITS,
    SRDF,
    describe,
    make_package,
    replace,
    run_validation,
    write,
)


def test_joint_limits_with_xacro_unit_tags(tmp_path, monkeypatch):
    """`!degrees` and `!radians` read as xacro.load_yaml reads them: degrees × π/180, radians as they are."""
    root = make_package(tmp_path, monkeypatch)
    replace(LIMITS, "min_position: -3.054326191", "min_position: !degrees -175")(root)
    replace(LIMITS, "max_position: 3.054326191", "max_position: !radians 0.97222222222 * pi")(root)
    replace(LIMITS, "max_velocity: 2.617993878", "max_velocity: !degrees 150.0")(root)
    report = run_validation(root)
    assert report.findings.problems == [], describe(report.findings.problems)
    joint0 = report.file_limits["joint0"]
    assert joint0.min_position == pytest.approx(math.radians(-175))
    assert joint0.max_position == pytest.approx(0.97222222222 * math.pi)
    assert joint0.max_velocity == pytest.approx(math.radians(150))


def test_unit_tag_that_is_no_number_names_its_line(tmp_path, monkeypatch):
    root = make_package(tmp_path, monkeypatch)
    replace(LIMITS, "max_velocity: 2.617993878", "max_velocity: !degrees fast")(root)
    (problem,) = [p for p in run_validation(root).findings.errors if p.code == "limits.yaml"]
    line = next(n for n, text in enumerate((root / LIMITS).read_text().splitlines(), 1) if "!degrees fast" in text)
    assert f"{LIMITS}:{line}:" in problem.why and "!degrees 'fast'" in problem.why


def test_unit_tags_evaluate_arithmetic_only(tmp_path):
    path = tmp_path / "joint_limits.yaml"
    path.write_text("a: !degrees __import__('os').getcwd()\n")
    with pytest.raises(ConfigError) as caught:
        read_package_yaml(path)
    assert "not a number" in caught.value.why


KINEMATICS_AS_PARAMETERS = """\
/**:
  ros__parameters:
    robot_description_kinematics:
      arm:
        kinematics_solver: kdl_kinematics_plugin/KDLKinematicsPlugin
        kinematics_solver_search_resolution: 0.005
        kinematics_solver_timeout: 0.005
"""


def test_kinematics_yaml_as_ros2_parameters_file(tmp_path, monkeypatch):
    """UR's form: `/**: ros__parameters: robot_description_kinematics: GROUP:` validates and reaches the planner."""
    root = make_package(tmp_path, monkeypatch)
    write(KINEMATICS, KINEMATICS_AS_PARAMETERS)(root)
    report = run_validation(root)
    assert report.findings.problems == [], describe(report.findings.problems)
    groups, warnings = read_groups(report.srdf, report.urdf, tuple(JOINTS), root / KINEMATICS)
    assert not warnings
    assert groups["arm"].settings.timeout_s == 0.005


def test_kinematics_group_unknown_in_parameters_file_names_its_line(tmp_path, monkeypatch):
    root = make_package(tmp_path, monkeypatch)
    write(KINEMATICS, KINEMATICS_AS_PARAMETERS.replace("      arm:", "      manipulator:"))(root)
    (problem,) = [p for p in run_validation(root).findings.errors if p.code == "kinematics.unknown_group"]
    assert problem.line == 4


CONTROLLERS_AS_PARAMETERS = """\
/**/controller_manager:
  ros__parameters:
    update_rate: 500
    arm_controller:
      type: joint_trajectory_controller/JointTrajectoryController
/**:
  ros__parameters:
    use_sim_time: false
arm_controller:
  ros__parameters:
    joints: [{joints}]
"""


def test_controllers_yaml_with_node_name_patterns(tmp_path, monkeypatch):
    """`/**/controller_manager` and a `/**` block, as ros2_control's examples write them, are read as ROS 2 does."""
    root = make_package(tmp_path, monkeypatch)
    write(CONTROLLERS, CONTROLLERS_AS_PARAMETERS.format(joints=", ".join(JOINTS[:5] + ["joint_5"])))(root)
    (problem,) = [p for p in run_validation(root).findings.errors if p.code == "controllers.unknown_joint"]
    assert problem.line == 11
    write(CONTROLLERS, CONTROLLERS_AS_PARAMETERS.format(joints=", ".join(JOINTS)))(root)
    report = run_validation(root)
    assert report.findings.problems == [], describe(report.findings.problems)
    controllers = read_controllers(root / CONTROLLERS, JOINTS, 1000)
    assert controllers.update_rate == 500
    assert controllers.trajectory.name == "arm_controller" and controllers.trajectory.joints == tuple(JOINTS)


def test_package_found_by_the_name_package_xml_declares(tmp_path, monkeypatch):
    """A clone whose folder is not named like its package (a workspace's src/REPOSITORY) is found by the name in its
    package.xml, before the built-in package of that name, and validate says that the names differ."""
    clone = tmp_path / "ws" / "src" / "Indy7_ROS2_Description"
    shutil.copytree(BUILTIN_PACKAGES_DIR / "indy7_v2_description", clone)
    (tmp_path / "ws" / "build").mkdir()
    (tmp_path / "ws" / "build" / "COLCON_IGNORE").touch()
    monkeypatch.setenv("PLEM_PACKAGE_PATH", str(tmp_path / "ws"))
    for package in ("indy7_v2_description", clone):
        report = run_validation(package)
        assert report.files.root == clone and report.files.name == "indy7_v2_description"
        assert report.findings.problems == [], describe(report.findings.problems)
        assert any("'Indy7_ROS2_Description'" in note and "'indy7_v2_description'" in note for note in report.notes)


def test_passive_joint_of_the_urdf_is_accepted(tmp_path, monkeypatch):
    root = make_package(tmp_path, monkeypatch)
    replace(SRDF, "  </group>\n", '  </group>\n  <passive_joint name="tcp_joint"/>\n')(root)
    report = run_validation(root)
    assert report.srdf.passive_joints == [("tcp_joint", 9)]
    assert report.findings.problems == [], describe(report.findings.problems)
