"""Real third-party arms (UR5, Franka Panda from example-robot-data), wrapped as description packages at test time.

Meshes stay `package://example-robot-data/...` and resolve through AMENT_PREFIX_PATH (the wheel's `cmeel.prefix`).
"""

from __future__ import annotations

import importlib.metadata
from dataclasses import dataclass
from pathlib import Path

import pytest
import yaml
from lxml import etree

from plem.description.compat import PROTOCOL_VERSION
from plem.description.model import ACTUATED_TYPES
from plem.description.validate import BUILTIN_PLUGIN

DATA_DISTRIBUTION = "example-robot-data"
DATA_PACKAGE = "example-robot-data"  # the share/ folder name its URDFs use in package:// URIs
XACRO_NS = "http://www.ros.org/wiki/xacro"
PREFIX = "$(arg prefix)"
REFERENCE_ATTRIBUTES = ("link", "joint", "reference")  # <parent link>, <mimic joint>, <gazebo reference>
MAX_ACCELERATION = 5.0  # rad/s²; the URDFs publish none, so a conservative figure
MAX_JERK = 50.0  # rad/s³
COMMAND_INTERFACES = ("position", "velocity")
STATE_INTERFACES = ("position", "velocity", "effort")


@dataclass(frozen=True)
class ArmSpec:
    """Which URDF of example-robot-data to wrap, and the facts the wrapper needs about it."""

    name: str
    urdf: str
    base_link: str
    tip_link: str
    dof: int
    fixed_joints: tuple[str, ...] = ()

    @property
    def package(self) -> str:
        return f"{self.name}_description"


ARMS = (
    ArmSpec("ur5", "robots/ur_description/urdf/ur5_robot.urdf", "base_link", "tool0", dof=6),
    # The Panda's gripper has two finger joints (one prismatic, one mimicking it) that would make it an 8-DOF
    # robot; plem drives 6- or 7-axis arms, so the wrapper makes both fingers fixed and keeps the 7-axis arm.
    ArmSpec("panda", "robots/panda_description/urdf/panda.urdf", "panda_link0", "panda_hand_tcp", dof=7,
            fixed_joints=("panda_finger_joint1", "panda_finger_joint2")),
)


@dataclass(frozen=True)
class JointLimits:
    """An actuated joint of the source URDF with its <limit>."""

    name: str
    lower: float
    upper: float
    velocity: float
    effort: float

    @property
    def home(self) -> float:
        """Zero, clipped into the position limits."""
        return min(max(0.0, self.lower), self.upper)


@dataclass(frozen=True)
class WrappedArm:
    """A generated description package on PLEM_PACKAGE_PATH and what it was generated from."""

    spec: ArmSpec
    root: Path
    links: tuple[str, ...]
    joints: tuple[str, ...]
    actuated: tuple[JointLimits, ...]

    @property
    def urdf_xacro(self) -> Path:
        return self.root / "urdf" / f"{self.spec.name}.urdf.xacro"


def data_prefix() -> Path:
    """The install prefix example-robot-data's wheel ships (it holds share/example-robot-data/package.xml)."""
    try:
        distribution = importlib.metadata.distribution(DATA_DISTRIBUTION)
    except importlib.metadata.PackageNotFoundError:
        pytest.fail(f"{DATA_DISTRIBUTION}, a test dependency, is not installed: run the tests through `make test` "
                    "(it installs '.[test]')")
    return Path(distribution.locate_file("cmeel.prefix"))


def load_arm(spec: ArmSpec, prefix: Path) -> etree._Element:
    """The source URDF's <robot>, with the joints the spec lists turned fixed."""
    robot = etree.parse(str(prefix / "share" / DATA_PACKAGE / spec.urdf)).getroot()
    for name in spec.fixed_joints:
        joint = robot.find(f"joint[@name='{name}']")
        joint.set("type", "fixed")
        for child in joint.findall("mimic") + joint.findall("limit"):
            joint.remove(child)
    return robot


def actuated_joints(robot: etree._Element) -> tuple[JointLimits, ...]:
    """Actuated joints in document order (mimic joints follow another and are not actuated)."""
    return tuple(
        JointLimits(joint.get("name"), *(float(joint.find("limit").get(key))
                                         for key in ("lower", "upper", "velocity", "effort")))
        for joint in robot.findall("joint")
        if joint.get("type") in ACTUATED_TYPES and joint.find("mimic") is None
    )


def _xml(root: etree._Element) -> bytes:
    etree.indent(root, space="  ")
    return etree.tostring(root, xml_declaration=True, encoding="utf-8")


def _xacro_robot(**attributes: str) -> etree._Element:
    return etree.Element("robot", attributes, nsmap={"xacro": XACRO_NS})


def urdf_xacro(robot: etree._Element, spec: ArmSpec) -> bytes:
    """The source URDF as a protocol xacro: a prefix argument on every name and reference, ros2_control included."""
    names = {el.get("name") for el in robot if el.tag in ("link", "joint")}
    wrapper = _xacro_robot(name=robot.get("name"))
    wrapper.append(etree.Comment(f" {spec.urdf} from {DATA_DISTRIBUTION}, wrapped for plem by the test suite "))
    etree.SubElement(wrapper, f"{{{XACRO_NS}}}arg", name="prefix", default="")
    wrapper.extend(list(robot))
    for element in wrapper.iter(etree.Element):
        for attribute in ("name", *REFERENCE_ATTRIBUTES):
            value = element.get(attribute)
            if value in names and (attribute != "name" or element.tag in ("link", "joint")):
                element.set(attribute, PREFIX + value)
    etree.SubElement(wrapper, f"{{{XACRO_NS}}}include",
                     filename=f"$(find {spec.package})/urdf/{spec.name}.ros2_control.xacro")
    etree.SubElement(wrapper, f"{{{XACRO_NS}}}{spec.name}_ros2_control", prefix=PREFIX)
    return _xml(wrapper)


def ros2_control_xacro(spec: ArmSpec, joints: tuple[JointLimits, ...]) -> bytes:
    """The ros2_control macro: built-in hardware plugin, every actuated joint named ${prefix}JOINT."""
    root = _xacro_robot()
    macro = etree.SubElement(root, f"{{{XACRO_NS}}}macro", name=f"{spec.name}_ros2_control", params="prefix:=''")
    block = etree.SubElement(macro, "ros2_control", name=f"${{prefix}}{spec.name}_hardware", type="system")
    etree.SubElement(etree.SubElement(block, "hardware"), "plugin").text = BUILTIN_PLUGIN
    for joint in joints:
        element = etree.SubElement(block, "joint", name=f"${{prefix}}{joint.name}")
        for kind, interfaces in (("command_interface", COMMAND_INTERFACES), ("state_interface", STATE_INTERFACES)):
            for interface in interfaces:
                etree.SubElement(element, kind, name=interface)
    return _xml(root)


def joint_limits(joints: tuple[JointLimits, ...]) -> dict[str, object]:
    """joint_limits.yaml content: URDF position, velocity and effort; fixed acceleration and jerk."""
    return {"joint_limits": {
        joint.name: {"has_position_limits": True, "min_position": joint.lower, "max_position": joint.upper,
                     "max_velocity": joint.velocity, "max_acceleration": MAX_ACCELERATION, "max_jerk": MAX_JERK,
                     "max_effort": joint.effort}
        for joint in joints}}


def srdf(robot: etree._Element, spec: ArmSpec, joints: tuple[JointLimits, ...]) -> bytes:
    """Group `arm` as a base-to-tip chain, a `home` state of zeros within limits, adjacent links not
    collision-checked."""
    root = etree.Element("robot", name=robot.get("name"))
    group = etree.SubElement(root, "group", name="arm")
    etree.SubElement(group, "chain", base_link=spec.base_link, tip_link=spec.tip_link)
    home = etree.SubElement(root, "group_state", name="home", group="arm")
    for joint in joints:
        etree.SubElement(home, "joint", name=joint.name, value=repr(joint.home))
    for joint in robot.findall("joint"):
        etree.SubElement(root, "disable_collisions", link1=joint.find("parent").get("link"),
                         link2=joint.find("child").get("link"), reason="Adjacent")
    return _xml(root)


PACKAGE_XML = """<?xml version="1.0"?>
<package format="3">
  <name>{package}</name>
  <version>1.0.0</version>
  <description>{robot} from {data}, wrapped as a plem description package by the test suite.</description>
  <maintainer email="plem@example.com">plem maintainers</maintainer>
  <license>BSD-3-Clause</license>
  <buildtool_depend>ament_cmake</buildtool_depend>
  <exec_depend>xacro</exec_depend>
  <exec_depend>{data}</exec_depend>
  <export>
    <build_type>ament_cmake</build_type>
  </export>
</package>
"""

CMAKELISTS = """cmake_minimum_required(VERSION 3.8)
project({package})
find_package(ament_cmake REQUIRED)
install(DIRECTORY urdf srdf config DESTINATION share/${{PROJECT_NAME}})
install(FILES PLEM_COMPAT_VERSION DESTINATION share/${{PROJECT_NAME}})
ament_package()
"""

KINEMATICS = {"arm": {"kinematics_solver": "kdl_kinematics_plugin/KDLKinematicsPlugin",
                      "kinematics_solver_search_resolution": 0.005, "kinematics_solver_timeout": 0.05}}


def _write_yaml(path: Path, content: dict[str, object]) -> None:
    path.write_text(yaml.safe_dump(content, sort_keys=False), encoding="utf-8")


def write_package(spec: ArmSpec, prefix: Path, folder: Path) -> WrappedArm:
    """Generate the whole description package for `spec` under folder/<package>."""
    robot = load_arm(spec, prefix)
    links = tuple(el.get("name") for el in robot.findall("link"))
    joint_names = tuple(el.get("name") for el in robot.findall("joint"))
    actuated = actuated_joints(robot)
    root = folder / spec.package
    for sub in ("urdf", "srdf", "config"):
        (root / sub).mkdir(parents=True)
    (root / "urdf" / f"{spec.name}.ros2_control.xacro").write_bytes(ros2_control_xacro(spec, actuated))
    (root / "srdf" / f"{spec.name}.srdf").write_bytes(srdf(robot, spec, actuated))
    _write_yaml(root / "config" / "joint_limits.yaml", joint_limits(actuated))
    _write_yaml(root / "config" / "kinematics.yaml", KINEMATICS)
    (root / "PLEM_COMPAT_VERSION").write_text(PROTOCOL_VERSION + "\n", encoding="utf-8")
    (root / "package.xml").write_text(
        PACKAGE_XML.format(package=spec.package, robot=spec.name, data=DATA_DISTRIBUTION), encoding="utf-8")
    (root / "CMakeLists.txt").write_text(CMAKELISTS.format(package=spec.package), encoding="utf-8")
    wrapped = WrappedArm(spec, root, links, joint_names, actuated)
    wrapped.urdf_xacro.write_bytes(urdf_xacro(robot, spec))  # last: it moves the source elements
    return wrapped


def wrap(spec: ArmSpec, folder: Path, monkeypatch: pytest.MonkeyPatch) -> WrappedArm:
    """The arm wrapped under `folder`, findable by name; example-robot-data findable through AMENT_PREFIX_PATH."""
    prefix = data_prefix()
    assert (prefix / "share" / DATA_PACKAGE / "package.xml").is_file()
    packages = folder / "packages"
    monkeypatch.setenv("PLEM_PACKAGE_PATH", str(packages))
    monkeypatch.setenv("AMENT_PREFIX_PATH", str(prefix))
    return write_package(spec, prefix, packages)

