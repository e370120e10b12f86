"""Shapes of real upstream description packages, each rebuilt as a small mutation of a built-in package.

UR's and Indy's joint_limits.yaml use xacro's unit tags, MoveIt packages write kinematics.yaml and controllers.yaml
as ROS 2 parameters files, clones live in folders named otherwise than their package, device macros emit a
second ros2_control block, indy-ros2 names a link and a joint alike.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
import uuid

import numpy as np
import pytest

from plem.control.limits import ArmLimits
from plem.core.paths import BUILTIN_PACKAGES_DIR
from plem.description.controllers import read_controllers
from plem.description.drives import drive_parameters
from plem.description.hardware import driven_block
from plem.description.package_yaml import read_package_yaml
from plem.errors import ConfigError, PlemError
from plem.launch import rt_driver
from plem.launch.plan import plan_robot
from plem.planning.groups import read_groups
from plem.planning.planner import Planner
from tests.integration.test_broken_packages import (
    CONTROLLERS,
    JOINTS,
    KINEMATICS,
    LIMITS,
    ROS2_CONTROL,
    SRDF,
    URDF,
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


def test_joint_limits_as_ros2_parameters_file(tmp_path, monkeypatch):
    """joint_limits.yaml as the parameters of a node, as ros2_control's joint_limits reads them."""
    root = make_package(tmp_path, monkeypatch)
    text = (root / LIMITS).read_text()
    body = text[text.index("joint_limits:"):]
    write(LIMITS, "/**:\n  ros__parameters:\n" + "".join(f"    {line}\n" for line in body.splitlines()))(root)
    replace(LIMITS, "max_velocity: 2.617993878", "max_velocity: -1.0")(root)
    report = run_validation(root)
    (problem,) = report.findings.problems
    assert problem.code == "limits.nonpositive" and problem.line == next(
        n for n, line in enumerate((root / LIMITS).read_text().splitlines(), 1) if "max_velocity: -1.0" in line)
    assert len(report.file_limits) == 6


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


@pytest.mark.parametrize("node", ["/**", "move_group", "/arm_left/move_group"])
def test_kinematics_yaml_as_ros2_parameters_file(tmp_path, monkeypatch, node):
    """UR's form: `/**: ros__parameters: robot_description_kinematics: GROUP:` (or a node's name for `/**`)
    validates and reaches the planner."""
    root = make_package(tmp_path, monkeypatch)
    write(KINEMATICS, KINEMATICS_AS_PARAMETERS.replace("/**:", f"{node}:"))(root)
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


#: An upstream device macro, as Kinova's, xArm's and indy-ros2's are: it always emits a ros2_control block for
#: its own driver (mock hardware only when asked), here before the wrapper's own block.
DEVICE_MACRO = """<?xml version="1.0"?>
<robot xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:macro name="acme_arm_device" params="prefix:='' use_fake_hardware:=false">
    <ros2_control name="${prefix}AcmeArmHardware" type="system">
      <hardware>
        <xacro:if value="${use_fake_hardware}"><plugin>mock_components/GenericSystem</plugin></xacro:if>
        <xacro:unless value="${use_fake_hardware}"><plugin>acme_driver/AcmeSystemHardware</plugin></xacro:unless>
        <param name="robot_ip">192.168.1.10</param>
      </hardware>
      <xacro:macro name="acme_joint" params="name">
        <joint name="${prefix}${name}">
          <command_interface name="position"/>
          <state_interface name="position"/>
          <state_interface name="velocity"/>
        </joint>
      </xacro:macro>
      <xacro:acme_joint name="joint0"/><xacro:acme_joint name="joint1"/><xacro:acme_joint name="joint2"/>
      <xacro:acme_joint name="joint3"/><xacro:acme_joint name="joint4"/><xacro:acme_joint name="joint5"/>
    </ros2_control>
  </xacro:macro>
</robot>
"""
DEVICE_CALL = ('  <xacro:include filename="$(find indy7_v2_description)/urdf/acme_device.xacro"/>\n'
               '  <xacro:acme_arm_device prefix="$(arg prefix)" use_fake_hardware="{fake}"/>\n'
               '  <!-- hardware interface description -->')


def _with_device_macro(root, fake: bool) -> None:
    write("urdf/acme_device.xacro", DEVICE_MACRO)(root)
    replace(URDF, "  <!-- hardware interface description -->", DEVICE_CALL.format(fake=str(fake).lower()))(root)


def test_upstream_block_beside_plem_block_is_ignored_with_a_warning(tmp_path, monkeypatch):
    """The wrapper pattern: the upstream macro's block stays, the wrapper's block names plem's plugin; validate and
    launch planning pass, and the drive parameters and the hardware the bridge reports come from plem's block."""
    root = make_package(tmp_path, monkeypatch)
    _with_device_macro(root, fake=False)
    report = run_validation(root)
    assert [(p.code, p.severity.value) for p in report.findings.problems] == [
        ("ros2_control.ignored_block", "warning")], describe(report.findings.problems)
    (warning,) = report.findings.warnings
    assert "AcmeArmHardware" in warning.summary and "acme_driver/AcmeSystemHardware" in warning.why
    assert [block.name for block in report.urdf.ros2_control] == ["AcmeArmHardware", "indy7_v2_hardware"]
    assert driven_block(report.urdf).plugin == "hardware/HardwareInterface"
    assert [d.gear_ratio for d in drive_parameters(report.urdf, JOINTS)] == [121.0] * 3 + [101.0] * 3
    plan = plan_robot({"bus": "mock", "robot_id": "wrapped_device", "description_package": str(root),
                       "record": "false"})
    assert plan.config.dof == 6


def test_mock_components_block_runs_on_the_simulated_arm(tmp_path, monkeypatch):
    """Without a block naming plem's plugin, ros2_control's own mock plugin means plem's simulated arm."""
    root = make_package(tmp_path, monkeypatch)
    _with_device_macro(root, fake=True)
    write(ROS2_CONTROL, '<?xml version="1.0"?>\n<robot xmlns:xacro="http://www.ros.org/wiki/xacro">\n'
                        '  <xacro:macro name="indy7_v2_ros2_control" params="prefix:=\'\'"/>\n</robot>\n')(root)
    report = run_validation(root)
    codes = sorted((p.code, p.severity.value) for p in report.findings.problems)
    assert codes == [("drive.none", "warning"), ("ros2_control.simulated", "warning")], \
        describe(report.findings.problems)
    assert driven_block(report.urdf).plugin == "mock_components/GenericSystem"
    plan_robot({"bus": "mock", "robot_id": "fake_device", "description_package": str(root), "record": "false"})


def test_two_blocks_for_plem_are_an_error(tmp_path, monkeypatch):
    root = make_package(tmp_path, monkeypatch)
    _with_device_macro(root, fake=False)
    replace("urdf/acme_device.xacro", "acme_driver/AcmeSystemHardware", "hardware/HardwareInterface")(root)
    report = run_validation(root)
    assert "ros2_control.several_blocks" in [p.code for p in report.findings.errors], \
        describe(report.findings.problems)


def _link_named_like_its_joint(root) -> None:
    """indy-ros2's shape: the fixed joint to the tool centre point and the tool centre point link are both `tcp`."""
    replace(URDF, 'name="${pfx}tcp_joint" type="fixed"', 'name="${pfx}tcp" type="fixed"')(root)


def test_link_and_joint_named_alike_run_in_the_driver_and_the_planner(tmp_path, monkeypatch):
    """URDF allows a link and a joint of one name: validate passes, the RT driver process starts and the planner
    plans for the link (pinocchio has two frames of that name; plem looks links up as links)."""
    root = make_package(tmp_path, monkeypatch)
    _link_named_like_its_joint(root)
    report = run_validation(root)
    assert report.findings.problems == [], describe(report.findings.problems)
    assert "tcp" in report.urdf.links and "tcp" in report.urdf.joints
    arguments = {"bus": "mock", "robot_id": f"alike_{uuid.uuid4().hex[:8]}", "description_package": str(root),
                 "record": "false"}
    driver = subprocess.Popen([sys.executable, "-m", "plem.launch.rt_driver", json.dumps(arguments)],
                              stdout=subprocess.PIPE, text=True,
                              env={**os.environ, "PLEM_LAUNCH_PID": str(os.getpid())})
    try:
        assert driver.stdout is not None
        announcement = json.loads(driver.stdout.readline() or "{}")  # one line, or none when the driver died
        assert announcement.get("ready"), announcement
        assert announcement["joint_names"] == JOINTS
    finally:
        driver.terminate()
        driver.wait(60)
    planner = Planner.for_package(report, JOINTS, ArmLimits.from_joint_limits(report.limits, JOINTS), 0.001)
    assert planner.group().tip_link == "tcp"
    flange, tcp = (planner.fk([0.0] * 6, [link])[link] for link in ("link6", "tcp"))
    assert not np.allclose(tcp.position, flange.position)  # the link, beyond the flange
    target = planner.fk([0.3, -0.2, 0.4, 0.0, 0.5, 0.0], ["tcp"])["tcp"]
    solution = planner.ik(target, [0.0] * 6)
    assert np.allclose(planner.fk(solution, ["tcp"])["tcp"].position, target.position, atol=1e-3)


def test_a_driver_that_cannot_build_its_robot_names_the_package(tmp_path, monkeypatch):
    """An unexpected failure while the driver builds the robot is said as a start-up failure of that package, with
    validate as the fix, never as a traceback or a hint about load."""
    root = make_package(tmp_path, monkeypatch)
    plan = plan_robot({"bus": "mock", "robot_id": f"broken_{uuid.uuid4().hex[:8]}", "description_package": str(root),
                       "record": "false"})

    def fail(*_: object, **__: object) -> None:
        raise ValueError("Several frames match the filter - please specify the FrameType (name=\"tcp\", type=\"31\")")

    monkeypatch.setattr(rt_driver.Robot, "builder", fail)
    with pytest.raises(PlemError) as caught:
        rt_driver.build(plan)
    error = caught.value
    assert "indy7_v2_description" in error.summary and "Several frames match the filter" in error.why
    assert f"plem validate {root} --strict" in error.how and "cycle_time" not in error.how


def test_kinematics_groups_straight_among_a_nodes_parameters(tmp_path):
    path = tmp_path / "kinematics.yaml"
    path.write_text("move_group:\n  ros__parameters:\n    use_sim_time: false\n    arm:\n"
                    "      kinematics_solver_timeout: 0.01\n")
    document = read_package_yaml(path)
    assert document.root == {"arm": {"kinematics_solver_timeout": 0.01}}
    assert document.line("arm", "kinematics_solver_timeout") == 5
