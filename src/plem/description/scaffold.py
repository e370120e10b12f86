"""`plem create-description`: a complete, valid description package for a generic 6- or 7-axis arm.

The generated arm is a real one: joint axes alternate roll and pitch, links have lengths, masses and
cylinder inertias, and the limits are those of a mid-size cobot, so kinematics and simulation work on it.
"""

from __future__ import annotations

import re
import stat
from dataclasses import dataclass, field
from pathlib import Path

from plem.core.files import file_kind, read_regular, write_atomic
from plem.description.compat import PROTOCOL_VERSION
from plem.description.discover import COMPAT_FILE
from plem.description.drives import param_line
from plem.description.generate import controllers_yaml, kinematics_yaml
from plem.description.problems import DescriptionError
from plem.errors import ConfigError
from plem.robot.config import SUPPORTED_DOF
from plem.robot.models import LARGE_JOINT_GEAR, MOTOR_ENCODER_COUNTS, WRIST_GEAR

PACKAGE_NAME = re.compile(r"[a-z][a-z0-9_]*")
#: A file name has at most 255 bytes on Linux file systems. The longest one a package needs is the temporary
#: file NAME.ros2_control.xacro is written through, so a longer robot name cannot be created.
FILE_NAME_MAX = 255
LONGEST_FILE_NAME = ".{name}.ros2_control.xacro.XXXXXXXX.tmp"
MAX_NAME_LENGTH = FILE_NAME_MAX - len(LONGEST_FILE_NAME.format(name=""))
SEGMENT_RADIUS = 0.05


@dataclass(frozen=True)
class JointSpec:
    """One actuated joint of the generated arm and the link it moves."""

    axis: str          # "z" (roll) or "y" (pitch)
    offset: float      # distance from the previous joint along the parent's z axis [m]
    length: float      # length of the link this joint drives [m]
    mass: float        # [kg]
    limit: float       # symmetric position limit [rad]
    velocity: float    # [rad/s]
    acceleration: float
    jerk: float
    effort: float      # [N·m]
    home: float        # home position [rad]
    gear: float        # gear ratio: motor revolutions per joint revolution


ARMS: dict[int, tuple[JointSpec, ...]] = {
    6: (
        JointSpec("z", 0.15, 0.10, 4.0, 3.05, 2.0, 5.0, 50.0, 150.0, 0.0, LARGE_JOINT_GEAR),
        JointSpec("y", 0.10, 0.40, 6.0, 3.05, 2.0, 5.0, 50.0, 150.0, 0.5, LARGE_JOINT_GEAR),
        JointSpec("y", 0.40, 0.35, 3.5, 2.6, 2.5, 6.0, 60.0, 80.0, 1.0, LARGE_JOINT_GEAR),
        JointSpec("z", 0.35, 0.10, 1.5, 3.05, 3.0, 8.0, 80.0, 30.0, 0.0, WRIST_GEAR),
        JointSpec("y", 0.10, 0.10, 1.2, 3.05, 3.0, 8.0, 80.0, 30.0, 1.0, WRIST_GEAR),
        JointSpec("z", 0.10, 0.05, 0.5, 3.05, 3.0, 8.0, 80.0, 30.0, 0.0, WRIST_GEAR),
    ),
    7: (
        JointSpec("z", 0.15, 0.10, 4.0, 2.9, 2.0, 5.0, 50.0, 150.0, 0.0, LARGE_JOINT_GEAR),
        JointSpec("y", 0.10, 0.20, 4.0, 1.75, 2.0, 5.0, 50.0, 150.0, 0.5, LARGE_JOINT_GEAR),
        JointSpec("z", 0.20, 0.20, 3.0, 2.9, 2.0, 5.0, 50.0, 100.0, 0.0, LARGE_JOINT_GEAR),
        JointSpec("y", 0.20, 0.20, 2.5, 2.6, 2.5, 6.0, 60.0, 80.0, 1.0, LARGE_JOINT_GEAR),
        JointSpec("z", 0.20, 0.20, 1.5, 2.9, 3.0, 8.0, 80.0, 30.0, 0.0, WRIST_GEAR),
        JointSpec("y", 0.20, 0.10, 1.2, 2.9, 3.0, 8.0, 80.0, 30.0, 1.0, WRIST_GEAR),
        JointSpec("z", 0.10, 0.05, 0.5, 2.9, 3.0, 8.0, 80.0, 30.0, 0.0, WRIST_GEAR),
    ),
}
BASE_MASS = 5.0
BASE_HEIGHT = 0.15
TOOL_OFFSET = 0.05


def _cylinder_inertia(mass: float, length: float, radius: float = SEGMENT_RADIUS) -> str:
    side = mass * (3 * radius**2 + length**2) / 12
    axial = mass * radius**2 / 2
    return f'ixx="{side:.6g}" iyy="{side:.6g}" izz="{axial:.6g}" ixy="0" ixz="0" iyz="0"'


def _link(name: str, mass: float, length: float) -> str:
    return f"""  <link name="${{pfx}}{name}">
    <inertial>
      <origin xyz="0 0 {length / 2:.6g}" rpy="0 0 0"/>
      <mass value="{mass:g}"/>
      <inertia {_cylinder_inertia(mass, length)}/>
    </inertial>
    <xacro:segment length="{length:g}"/>
  </link>
"""


def urdf_xacro(name: str, dof: int) -> str:
    """The arm's URDF: base, a revolute joint and cylinder link per axis, a tool frame and the ros2_control call."""
    joints = ARMS[dof]
    parts = [f"""<?xml version="1.0"?>
<!-- {name}: a generic {dof}-axis arm made by `plem create-description`. Units: m, kg, rad, rad/s, N·m.
     Renders with no arguments; prefix:=left_ renames every link and joint for multi-robot setups. -->
<robot name="{name}" xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:arg name="prefix" default=""/>
  <xacro:property name="pfx" value="$(arg prefix)"/>

  <!-- a cylinder along the link's z axis, used for visual and collision -->
  <xacro:macro name="segment" params="length">
    <visual>
      <origin xyz="0 0 ${{length / 2}}" rpy="0 0 0"/>
      <geometry><cylinder radius="{SEGMENT_RADIUS}" length="${{length}}"/></geometry>
    </visual>
    <collision>
      <origin xyz="0 0 ${{length / 2}}" rpy="0 0 0"/>
      <geometry><cylinder radius="{SEGMENT_RADIUS}" length="${{length}}"/></geometry>
    </collision>
  </xacro:macro>

{_link("base_link", BASE_MASS, BASE_HEIGHT)}"""]
    parent = "base_link"
    for index, joint in enumerate(joints, start=1):
        axis = "0 0 1" if joint.axis == "z" else "0 1 0"
        parts.append(f"""  <joint name="${{pfx}}joint{index}" type="revolute">
    <parent link="${{pfx}}{parent}"/>
    <child link="${{pfx}}link{index}"/>
    <origin xyz="0 0 {joint.offset:g}" rpy="0 0 0"/>
    <axis xyz="{axis}"/>
    <limit lower="{-joint.limit:g}" upper="{joint.limit:g}" velocity="{joint.velocity:g}" effort="{joint.effort:g}"/>
  </joint>
{_link(f"link{index}", joint.mass, joint.length)}""")
        parent = f"link{index}"
    parts.append(f"""  <joint name="${{pfx}}tool_joint" type="fixed">
    <parent link="${{pfx}}{parent}"/>
    <child link="${{pfx}}tool0"/>
    <origin xyz="0 0 {joints[-1].length + TOOL_OFFSET:g}" rpy="0 0 0"/>
  </joint>
  <link name="${{pfx}}tool0"/>

  <xacro:include filename="$(find {name}_description)/urdf/{name}.ros2_control.xacro"/>
  <xacro:{name}_ros2_control prefix="$(arg prefix)"/>
</robot>
""")
    return "".join(parts)


def ros2_control_xacro(name: str, dof: int) -> str:
    """The ros2_control macro: plem's hardware plugin and each joint's interfaces and placeholder drive parameters."""
    identity = "".join(f"        <!-- {param_line(key, '0x00000000')} -->\n"
                       for key in ("vendor_id", "product_code", "revision"))
    joints = "".join(f"""      <joint name="${{prefix}}joint{i}">
        {param_line("encoder_resolution", str(MOTOR_ENCODER_COUNTS))}
        {param_line("gear_ratio", f"{joint.gear:g}")}
        {param_line("direction", "1")}
{identity}        <command_interface name="position"/>
        <command_interface name="velocity"/>
        <command_interface name="acceleration"/>
        <command_interface name="effort"/>
        <state_interface name="position"/>
        <state_interface name="velocity"/>
        <state_interface name="effort"/>
      </joint>
""" for i, joint in enumerate(ARMS[dof], start=1))
    return f"""<?xml version="1.0"?>
<!-- Hardware interface of {name}: plem's RT driver, every actuated joint with its interfaces and drive. -->
<robot xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:macro name="{name}_ros2_control" params="prefix:=''">
    <ros2_control name="${{prefix}}{name}_hardware" type="system">
      <hardware>
        <plugin>hardware/HardwareInterface</plugin>
      </hardware>
      <!-- Drive parameters of each joint, which the EtherCAT bus needs to turn encoder counts into angles:
             encoder_resolution  encoder counts per motor revolution (a positive integer)
             gear_ratio          motor revolutions per joint revolution
             direction           1, or -1 when the drive counts opposite to the joint's URDF axis
           and, optionally, each drive's EtherCAT identity: vendor_id, product_code, revision (from its ESI
           file, hex or decimal). The values below are placeholders for a 16-bit encoder and strain-wave
           gearing: set them from your drives' documentation. -->
{joints}    </ros2_control>
  </xacro:macro>
</robot>
"""


def joint_limits_yaml(dof: int) -> str:
    """joint_limits.yaml with every limit of every joint switched on, within the URDF `<limit>` values."""
    lines = ["# Joint limits. Units: rad, rad/s, rad/s^2, rad/s^3, N·m. They must stay within the URDF <limit>.",
             "joint_limits:"]
    for index, joint in enumerate(ARMS[dof], start=1):
        lines += [f"  joint{index}:", "    has_position_limits: true", f"    min_position: {-joint.limit:g}",
                  f"    max_position: {joint.limit:g}", "    has_velocity_limits: true",
                  f"    max_velocity: {joint.velocity:g}", "    has_acceleration_limits: true",
                  f"    max_acceleration: {joint.acceleration:g}", "    has_jerk_limits: true",
                  f"    max_jerk: {joint.jerk:g}", "    has_effort_limits: true", f"    max_effort: {joint.effort:g}"]
    return "\n".join(lines) + "\n"


def srdf(name: str, dof: int) -> str:
    """An SRDF with the `arm` chain group, `home` and `zero` poses and adjacent links excluded from collisions."""
    home = "".join(f'    <joint name="joint{i}" value="{j.home:g}"/>\n' for i, j in enumerate(ARMS[dof], start=1))
    zero = "".join(f'    <joint name="joint{i}" value="0"/>\n' for i in range(1, dof + 1))
    links = ["base_link", *(f"link{i}" for i in range(1, dof + 1)), "tool0"]
    adjacent = "".join(f'  <disable_collisions link1="{a}" link2="{b}" reason="Adjacent"/>\n'
                       for a, b in zip(links, links[1:], strict=False))
    return f"""<?xml version="1.0"?>
<!-- Semantic description of {name} for planning: the arm group, named poses, collision filter. -->
<robot name="{name}">
  <group name="arm">
    <chain base_link="base_link" tip_link="tool0"/>
  </group>
  <group_state name="home" group="arm">
{home}  </group_state>
  <group_state name="zero" group="arm">
{zero}  </group_state>
{adjacent}</robot>
"""


def launch_file(name: str) -> str:
    """A launch file calling plem's bringup, with each component as a switch to edit."""
    command = f"plem launch {name}_description/launch/bringup.launch.py"
    return f'''"""Bring-up of {name}: switch components on or off, then run `{command}`."""

from plem.launch import bringup


def generate_launch_description():
    return bringup(
        "{name}_description",
        rt_driver=True,   # the real-time loop; every other component needs it
        bridge=True,      # ROS 2 topics and actions over DDS
        recorder=True,    # rosbag2 flight recorder
        planner=True,     # motion planning (starts only when srdf/ exists)
    )
'''


def package_xml(name: str) -> str:
    """package.xml (format 3, ament_cmake) so colcon and the package search path find the package."""
    return f"""<?xml version="1.0"?>
<package format="3">
  <name>{name}_description</name>
  <version>0.1.0</version>
  <description>Description package of {name} (URDF, ros2_control, limits) for plem.</description>
  <maintainer email="todo@example.com">TODO</maintainer>
  <license>BSD-3-Clause</license>
  <buildtool_depend>ament_cmake</buildtool_depend>
  <exec_depend>xacro</exec_depend>
  <export>
    <build_type>ament_cmake</build_type>
  </export>
</package>
"""


def cmakelists(name: str) -> str:
    """CMakeLists.txt installing the package's directories and PLEM_COMPAT_VERSION into share/."""
    return f"""cmake_minimum_required(VERSION 3.8)
project({name}_description)
find_package(ament_cmake REQUIRED)
foreach(dir urdf srdf config launch meshes)
  if(EXISTS ${{CMAKE_CURRENT_SOURCE_DIR}}/${{dir}})
    install(DIRECTORY ${{dir}} DESTINATION share/${{PROJECT_NAME}})
  endif()
endforeach()
install(FILES {COMPAT_FILE} DESTINATION share/${{PROJECT_NAME}})
ament_package()
"""


def readme(name: str, dof: int, with_moveit: bool, launch: bool) -> str:
    """README.md listing what the package holds and how to check it."""
    lines = [f"# {name}_description", "", f"A {dof}-axis arm described for plem.", "",
             "- `urdf/` — the arm (`" + name + ".urdf.xacro`, renders with no arguments) and its hardware interface",
             "- `config/joint_limits.yaml` — safety limits; `config/controllers.yaml` — trajectory controller"]
    if with_moveit:
        lines.append("- `srdf/` and `config/kinematics.yaml` — planning group `arm` and IK settings")
    if launch:
        lines.append("- `launch/bringup.launch.py` — choose which components start")
    lines += ["", "Check it with `plem validate ./" + name + "_description --strict` in the folder holding it (or by "
              "its name, `" + name + "_description`, once that folder is on PLEM_PACKAGE_PATH).", ""]
    return "\n".join(lines)


def plan_package(name: str, dof: int, *, with_moveit: bool = False, launch: bool = True) -> dict[str, str]:
    """Every file of the package by relative path, with its content."""
    _check_arguments(name, dof)
    files = {
        f"urdf/{name}.urdf.xacro": urdf_xacro(name, dof),
        f"urdf/{name}.ros2_control.xacro": ros2_control_xacro(name, dof),
        "config/joint_limits.yaml": joint_limits_yaml(dof),
        "config/controllers.yaml": controllers_yaml([f"joint{i}" for i in range(1, dof + 1)]),
        "meshes/.gitkeep": "",
        COMPAT_FILE: PROTOCOL_VERSION + "\n",
        "package.xml": package_xml(name),
        "CMakeLists.txt": cmakelists(name),
        "README.md": readme(name, dof, with_moveit, launch),
    }
    if with_moveit:
        files[f"srdf/{name}.srdf"] = srdf(name, dof)
        files["config/kinematics.yaml"] = kinematics_yaml(["arm"])
    if launch:
        files["launch/bringup.launch.py"] = launch_file(name)
    return files


def _check_arguments(name: str, dof: int) -> None:
    problems = []
    if len(name or "") > MAX_NAME_LENGTH:
        longest = LONGEST_FILE_NAME.format(name="NAME")
        problems.append(f"name has {len(name)} characters; at most {MAX_NAME_LENGTH} fit: writing the package "
                        f"needs the file {longest}, and a file name has at most {FILE_NAME_MAX} characters")
    elif not PACKAGE_NAME.fullmatch(name or "") or "__" in name:
        problems.append(f"name {name!r} is not a ROS package name (lowercase letters, digits, single '_', "
                        "starting with a letter)")
    if dof not in SUPPORTED_DOF:
        problems.append(f"dof {dof} is not 6 or 7")
    if problems:
        raise DescriptionError("Cannot create the description package", what=f"--name NAME (e.g. my_robot, at most "
                               f"{MAX_NAME_LENGTH} characters) and --dof 6 or 7", why="; ".join(problems),
                               how="e.g. plem create-description --name my_robot --dof 6")


@dataclass
class ScaffoldResult:
    """What `create_package` did, as paths relative to `root`: files created, left identical, overwritten."""

    root: Path
    created: list[str] = field(default_factory=list)
    identical: list[str] = field(default_factory=list)
    overwritten: list[str] = field(default_factory=list)


def create_package(output: Path, name: str, dof: int, *, with_moveit: bool = False, launch: bool = True,
                   force: bool = False) -> ScaffoldResult:
    """Write the package under `output/NAME_description`; differing files need `force`, or nothing is written."""
    planned = plan_package(name, dof, with_moveit=with_moveit, launch=launch)
    root = output / f"{name}_description"
    try:
        _check_folder(output, "--output")
        _check_folder(root, "the package's folder")
        return _write_package(root, planned, force)
    except OSError as error:
        raise DescriptionError(
            f"Cannot write the package to {root}",
            what="--output naming a folder that exists or can be created, and that you can write to",
            why=f"creating {error.filename or root} failed: {error.strerror or error}",
            how="choose a folder you can write to with --output (e.g. --output ~/ws/src)",
        ) from None


def _check_folder(path: Path, role: str) -> None:
    """Refuse a `path` that exists and is not a folder: the package cannot be created in or as it."""
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        return
    if not stat.S_ISDIR(mode):
        raise DescriptionError(
            f"Not a folder: {path}",
            what=f"a folder at {path} ({role}), or nothing there yet",
            why=f"{path} is a {file_kind(mode)}",
            how="choose a folder with --output (e.g. --output ~/ws/src), or move the file out of the way",
        )


def _write_package(root: Path, planned: dict[str, str], force: bool) -> ScaffoldResult:
    """Compare every planned file with what is on disk, then write the new and (with `force`) the changed ones."""
    result = ScaffoldResult(root=root)
    changed = []
    for relative, text in planned.items():
        path = root / relative
        if not path.exists():
            result.created.append(relative)
        elif _holds(path, text.encode("utf-8")):
            result.identical.append(relative)
        else:
            changed.append(relative)
    if changed and not force:
        raise DescriptionError(
            f"{len(changed)} file(s) in {root} differ from what would be generated",
            what="an empty target, identical files, or --force to overwrite",
            why="these files differ: " + ", ".join(changed),
            how="rerun with --force to overwrite them (your edits are lost), or choose another --output",
        )
    result.overwritten = changed
    for relative in result.created + changed:
        write_atomic(root / relative, planned[relative])
    return result


def _holds(path: Path, data: bytes) -> bool:
    """Whether `path` is a regular file holding exactly `data`; a folder, FIFO, device or larger file never does."""
    try:
        return read_regular(path, len(data), "generated file") == data
    except ConfigError:
        return False
