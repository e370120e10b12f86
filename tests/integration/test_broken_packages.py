"""A corpus of broken description packages: each a small mutation of a copy of a built-in package.

Every case names the one problem code (and severity) the validator must report for it; where the place
matters, also the 1-based line (given as a text to look up in the mutated file, so the table does not
depend on the exact layout of the built-in files) and parts of the message.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

from plem.description.drives import drive_parameters
from plem.description.problems import Problem, Severity
from plem.description.validate import Stage, ValidationReport, validate_package
from plem.errors import ConfigError, PackageNotFoundError, PlemError
from tests.integration.packages import copy_builtin

ERROR, WARNING = Severity.ERROR, Severity.WARNING

Mutation = Callable[[Path], None]

# Files of the two packages the corpus mutates (relative to the package root).
URDF = "urdf/indy7_v2.urdf.xacro"
ROS2_CONTROL = "urdf/indy7_v2.ros2_control.xacro"
SRDF = "srdf/indy7_v2.srdf"
LIMITS = "config/joint_limits.yaml"
KINEMATICS = "config/kinematics.yaml"
CONTROLLERS = "config/controllers.yaml"
COMPAT = "PLEM_COMPAT_VERSION"
RP2_URDF = "urdf/indyrp2_v2.urdf.xacro"
RP2_CONTROL = "urdf/indyrp2_v2.ros2_control.xacro"
RP2 = "indyrp2_v2"
JOINTS = [f"joint{i}" for i in range(6)]
RC_CALL = '<xacro:indy7_v2_ros2_control prefix="$(arg prefix)"/>'
RC_INCLUDE = "$(find indy7_v2_description)/urdf/indy7_v2.ros2_control.xacro"


# ---------------------------------------------------------------- mutations

def replace(rel: str, old: str, new: str, count: int = 1) -> Mutation:
    """Replace the first `count` occurrences (-1: all) of `old`; the text must be there."""
    def mutate(root: Path) -> None:
        path = root / rel
        text = path.read_text(encoding="utf-8")
        assert old in text, f"mutation does not apply: {old!r} not in {rel}"
        path.write_text(text.replace(old, new, count), encoding="utf-8")
    return mutate


def sub(rel: str, pattern: str, new: str, count: int = 1) -> Mutation:
    """Regex replacement (multiline, dot matches newline); it must match."""
    def mutate(root: Path) -> None:
        path = root / rel
        text, n = re.subn(pattern, new, path.read_text(encoding="utf-8"), count=count, flags=re.M | re.S)
        assert n, f"mutation does not apply: /{pattern}/ not in {rel}"
        path.write_text(text, encoding="utf-8")
    return mutate


def write(rel: str, text: str) -> Mutation:
    def mutate(root: Path) -> None:
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_text(text, encoding="utf-8")
    return mutate


def append(rel: str, text: str) -> Mutation:
    def mutate(root: Path) -> None:
        with (root / rel).open("a", encoding="utf-8") as handle:
            handle.write(text)
    return mutate


def delete(rel: str) -> Mutation:
    return lambda root: (root / rel).unlink()


def rename(rel: str, new_rel: str) -> Mutation:
    return lambda root: (root / rel).rename(root / new_rel)


def copy(rel: str, new_rel: str) -> Mutation:
    return lambda root: (root / new_rel).write_bytes((root / rel).read_bytes())


def together(*mutations: Mutation) -> Mutation:
    def mutate(root: Path) -> None:
        for mutation in mutations:
            mutation(root)
    return mutate


def unchanged(root: Path) -> None:
    """For cases whose problem lies in the validate_package arguments."""


def joint_type(index: int, new_type: str) -> Mutation:
    """Give one joint made by the `axis_joint` macro another type (the macro gains a jtype parameter)."""
    return together(replace(URDF, 'params="index parent child xyz rpy lower upper velocity effort"',
                            'params="index parent child xyz rpy lower upper velocity effort jtype:=revolute"'),
                    replace(URDF, 'type="revolute"', 'type="${jtype}"'),
                    replace(URDF, f'<xacro:axis_joint index="{index}"',
                            f'<xacro:axis_joint index="{index}" jtype="{new_type}"'))


def tcp_joint_type(new_type: str, urdf: str = URDF) -> Mutation:
    """The fixed joint between flange and tool centre point gets another type."""
    return replace(urdf, 'name="${pfx}tcp_joint" type="fixed"', f'name="${{pfx}}tcp_joint" type="{new_type}"')


def joint_params(joint: int) -> str:
    """An open regex group (the caller closes it): joint N's opening tag in the ros2_control file and the
    <param> lines after it."""
    return rf'(<joint name="\$\{{prefix\}}joint{joint}">\n(?: *<param [^\n]*\n)*?'


def drive_param(name: str, old: str, new: str, joint: int = 0, rel: str = ROS2_CONTROL) -> Mutation:
    """Change the value of drive parameter `name` of joint N."""
    return sub(rel, joint_params(joint) + rf' *<param name="{name}">){old}<', rf"\g<1>{new}<")


def drive_params_removed(joint: int, name: str | None = None) -> Mutation:
    """Remove drive parameter `name` (default: every one) of joint N."""
    if name is None:
        return sub(ROS2_CONTROL, joint_params(joint) + r')(?: *<param [^\n]*\n)+', r"\1")
    return sub(ROS2_CONTROL, joint_params(joint) + rf') *<param name="{name}">[^<]*</param>\n', r"\1")


def padded(rel: str, mib: int) -> Mutation:
    """Grow an XML file past `mib` MiB with a comment before its last line."""
    def mutate(root: Path) -> None:
        path = root / rel
        head, _, tail = path.read_text(encoding="utf-8").rstrip("\n").rpartition("\n")
        path.write_text(f"{head}\n<!-- {'x' * (mib * 2**20)} -->\n{tail}\n", encoding="utf-8")
    return mutate


def limit_value(attribute: str, old: str, new: str, joint: int = 0) -> Mutation:
    """Change one `<limit>` attribute in joint N's `axis_joint` call."""
    return sub(URDF, rf'(<xacro:axis_joint index="{joint}"[^>]*? {attribute}=")' + re.escape(old) + '"',
               rf'\g<1>{new}"')


def srdf_state_value(joint: str, old: str, new: str) -> Mutation:
    """Change the value of `joint` in the first group_state naming it with `old`."""
    return replace(SRDF, f'<joint name="{joint}" value="{old}"/>', f'<joint name="{joint}" value="{new}"/>')


def yaml_entry(rel: str, joint: str, body: str) -> Mutation:
    """Replace the whole entry of `joint` in a joint_limits.yaml by `body` (indented lines, or '' to drop it)."""
    return sub(rel, rf"^  {joint}:\n(?:    .*\n)*", body)


def controllers_yaml(joints: list[str]) -> str:
    return ("controller_manager:\n  ros__parameters:\n    update_rate: 1000\n\n"
            "joint_trajectory_controller:\n  ros__parameters:\n    joints:\n"
            + "".join(f"      - {joint}\n" for joint in joints))


def visual_mesh(uri: str) -> Mutation:
    """A visual-only mesh on the base link (no collision shape uses it)."""
    return replace(URDF, '<link name="${pfx}link0">  <!-- base -->',
                   f'<link name="${{pfx}}link0">\n    <visual><geometry><mesh filename="{uri}"/></geometry></visual>')


def srdf_insert(xml: str) -> Mutation:
    """Add elements to the SRDF right after the first group."""
    return replace(SRDF, "  </group>\n", "  </group>\n" + xml)


def unused_hardware_file() -> Mutation:
    """The URDF includes a renamed copy of the ros2_control file; the original stays behind in urdf/."""
    return together(copy(ROS2_CONTROL, "urdf/hardware.xacro"),
                    replace(URDF, RC_INCLUDE, "$(find indy7_v2_description)/urdf/hardware.xacro"))


# ---------------------------------------------------------------- the corpus

@dataclass(frozen=True)
class Case:
    id: str
    mutate: Mutation
    code: str
    severity: Severity
    line: str | None = None          # text whose first line (1-based) in the problem's file is the expected line
    message: dict[str, str] = field(default_factory=dict)  # Problem field -> expected substring
    kwargs: dict[str, Any] = field(default_factory=dict)    # validate_package keyword arguments
    robot: str = "indy7_v2"


CASES = [
    # --- file discovery
    Case("urdf_missing", delete(URDF), "urdf.missing", ERROR,
         message={"summary": "No URDF file found in package 'indy7_v2_description'",
                  "why": "Found 0 matching files"}),
    Case("urdf_wrong_extension", rename(URDF, "urdf/indy7_v2.urdf"), "urdf.missing", ERROR,
         message={"why": "Found 0 matching files (urdf/ holds: indy7_v2.ros2_control.xacro, indy7_v2.urdf)"}),
    Case("urdf_two_files", copy(URDF, "urdf/indy7_v2_old.urdf.xacro"), "urdf.multiple", ERROR,
         message={"why": "Found 2 matching files"}),
    Case("urdf_override_missing", unchanged, "urdf.override_missing", ERROR,
         kwargs={"urdf_file": "urdf/nope.urdf.xacro"}, message={"summary": "urdf/nope.urdf.xacro"}),
    Case("srdf_two_files", copy(SRDF, "srdf/indy7_v2_old.srdf"), "srdf.multiple", ERROR,
         message={"why": "Found 2"}),
    Case("srdf_override_missing", unchanged, "srdf.override_missing", ERROR,
         kwargs={"srdf_file": "srdf/nope.srdf"}),
    Case("kinematics_misnamed", rename(KINEMATICS, "config/kinematics.yml"), "config.misnamed", WARNING,
         message={"how": "config/kinematics.yaml"}),
    Case("joint_limits_misnamed", rename(LIMITS, "config/joint_limits.yml"), "limits.missing_file", ERROR),
    Case("package_xml_missing", delete("package.xml"), "package.xml_missing", WARNING),
    # --- rendering the URDF
    Case("xacro_arg_without_default", replace(URDF, '<xacro:arg name="prefix" default=""/>',
                                              '<xacro:arg name="prefix"/>'), "urdf.xacro_args", ERROR),
    Case("xacro_undefined_property", replace(URDF, 'rpy="0 0 ${pi}"', 'rpy="0 0 ${pie}"'), "urdf.render", ERROR),
    Case("xacro_include_missing", replace(URDF, RC_INCLUDE, "$(find indy7_v2_description)/urdf/gone.xacro"),
         "urdf.render", ERROR),
    Case("urdf_broken_xml", replace(URDF, '<link name="${pfx}tcp"/>', '<link name="${pfx}tcp">'), "urdf.xml", ERROR),
    Case("urdf_too_large", padded(URDF, 17), "urdf.render", ERROR,
         message={"summary": "indy7_v2.urdf.xacro is too large", "what": "at most 16.0 MiB", "why": "holds 17.0 MiB"}),
    Case("urdf_include_too_large", padded(ROS2_CONTROL, 17), "urdf.render", ERROR,
         message={"summary": "indy7_v2.ros2_control.xacro is too large", "why": "holds 17.0 MiB"}),
    # --- kinematic tree
    Case("joint_child_link_missing", replace(URDF, '<child link="${pfx}tcp"/>', '<child link="${pfx}tool0"/>'),
         "urdf.joint_link_missing", ERROR, message={"why": "'tool0'"}),
    Case("two_root_links", replace(URDF, '<link name="${pfx}tcp"/>',
                                   '<link name="${pfx}tcp"/><link name="${pfx}camera"/>'),
         "urdf.tree.roots", ERROR, message={"why": "camera"}),
    Case("link_with_two_parents", replace(URDF, "  <!-- hardware interface description -->",
                                          '  <joint name="${pfx}brace" type="fixed"><parent link="${pfx}link0"/>'
                                          '<child link="${pfx}link3"/></joint>'), "urdf.tree.multiple_parents", ERROR,
         message={"why": "link3 is the child of joint2, brace"}),
    Case("joint_cycle", replace(URDF, '<xacro:axis_joint index="0" parent="link0"',
                                '<xacro:axis_joint index="0" parent="tcp"'), "urdf.tree.cycle", ERROR),
    # --- joint types and limits
    Case("floating_joint", tcp_joint_type("floating"), "urdf.joint_type", ERROR),
    Case("planar_joint", tcp_joint_type("planar"), "urdf.joint_type", ERROR),
    Case("misspelt_joint_type", tcp_joint_type("fix"), "urdf.joint_type", ERROR, message={"why": "'fix'"}),
    Case("prismatic_joint", joint_type(5, "prismatic"), "joint.less_tested", WARNING),
    Case("continuous_joint", joint_type(5, "continuous"), "joint.less_tested", WARNING),
    Case("limit_tag_missing", replace(URDF, '<limit lower="${lower}" upper="${upper}" velocity="${velocity}" '
                                            'effort="${effort}"/>', ""), "urdf.limit_missing", ERROR),
    Case("limit_velocity_missing", replace(URDF, ' velocity="${velocity}" effort', " effort"),
         "urdf.limit_missing", ERROR, message={"why": "lacks velocity"}),
    Case("limit_velocity_nan", limit_value("velocity", "2.617993878", "nan"), "urdf.limit_value", ERROR,
         line="<limit lower=", message={"summary": "joint0", "why": 'velocity="nan" is not a finite number'}),
    Case("limit_effort_infinite", limit_value("effort", "79.79", "inf", joint=4), "urdf.limit_value", ERROR,
         line="<limit lower=", message={"summary": "joint4", "why": 'effort="inf"'}),
    Case("limit_lower_nan", limit_value("lower", "-3.054326191", "nan", joint=1), "urdf.limit_value", ERROR,
         message={"why": 'lower="nan"'}),
    Case("limit_velocity_zero", limit_value("velocity", "3.141592654", "0", joint=5), "urdf.limit_value", ERROR,
         message={"why": 'velocity="0" is not above 0'}),
    Case("limit_lower_above_upper", limit_value("lower", "-3.054326191", "3.1", joint=2), "urdf.limit_value", ERROR,
         message={"why": 'lower="3.1" is not below upper="3.05433"'}),
    Case("axis_zero", replace(URDF, '<axis xyz="0 0 1"/>', '<axis xyz="${int(index != 3)} 0 ${int(index != 3)}"/>'),
         "urdf.axis", ERROR, line="<axis xyz=", message={"summary": "joint3", "why": '<axis xyz="0 0 0">'}),
    Case("axis_nan", replace(URDF, '<axis xyz="0 0 1"/>', '<axis xyz="0 0 nan"/>'), "urdf.axis", ERROR,
         line="<axis xyz="),
    Case("mass_nan", replace(URDF, 'mass="2.68211719"', 'mass="nan"'), "urdf.inertial", ERROR,
         line='<link name="${pfx}link3">', message={"summary": "link3", "why": 'mass value="nan"'}),
    Case("mass_negative", replace(URDF, 'mass="2.68211719"', 'mass="-2.68211719"'), "urdf.inertial", ERROR,
         line='<link name="${pfx}link3">', message={"why": 'mass value="-2.68212"'}),
    Case("mass_zero", replace(URDF, 'mass="2.68211719"', 'mass="0"'), "urdf.inertial", ERROR,
         message={"why": "mass is 0 kg, yet joint joint2 moves it"}),
    Case("inertia_nan", replace(URDF, 'izz="0.10021441"', 'izz="nan"'), "urdf.inertial", ERROR,
         message={"summary": "link3", "why": 'izz="nan" is not a finite number'}),
    Case("inertia_negative_diagonal", replace(URDF, 'iyy="0.01627234"', 'iyy="-0.01627234"'), "urdf.inertial", ERROR,
         message={"why": "not positive semi-definite (negative diagonal iyy=-0.0162723)"}),
    Case("mass_implausible", replace(URDF, 'mass="2.68211719"', 'mass="3500"'), "urdf.inertial_implausible",
         WARNING, line='<link name="${pfx}link3">',
         message={"summary": "Link link3 weighs 3500 kg", "why": "times the median"}),
    Case("inertia_implausible", replace(URDF, 'ixx="0.11373278" iyy="0.01627234" izz="0.10021441"',
                                        'ixx="113.73278" iyy="16.27234" izz="100.21441"'),
         "urdf.inertial_implausible", WARNING, message={"summary": "link3 has an inertia too large for its mass"}),
    Case("dof_5", joint_type(5, "fixed"), "dof.unsupported", ERROR, message={"summary": "5 actuated joints"}),
    Case("dof_8", tcp_joint_type("continuous", RP2_URDF), "dof.unsupported", ERROR,
         message={"summary": "8 actuated joints"}, robot=RP2),
    # --- ros2_control
    Case("ros2_control_not_called", replace(URDF, RC_CALL, ""), "ros2_control.missing", ERROR,
         message={"why": "indy7_v2.ros2_control.xacro exists but is not included"}),
    Case("ros2_control_wrong_plugin", replace(ROS2_CONTROL, "hardware/HardwareInterface", "acme_hardware/AcmeSystem"),
         "ros2_control.plugin", ERROR, message={"why": "'acme_hardware/AcmeSystem'"}),
    Case("ros2_control_joint_missing", sub(ROS2_CONTROL, r'^ *<joint name="\$\{prefix\}joint5">.*?</joint>\n', ""),
         "ros2_control.joint_missing", ERROR, message={"summary": "joint5"}),
    Case("ros2_control_unknown_joint", replace(ROS2_CONTROL, "${prefix}joint5", "${prefix}joint6"),
         "ros2_control.unknown_joint", ERROR, message={"summary": "joint6"}),
    Case("ros2_control_no_command_interfaces", sub(ROS2_CONTROL, r'^ *<command_interface name="\w+"/>\n', "", count=0),
         "ros2_control.interfaces", ERROR),
    Case("ros2_control_no_position_state", replace(ROS2_CONTROL, '<state_interface name="position"/>', "", count=-1),
         "ros2_control.interfaces", ERROR),
    Case("ros2_control_unknown_interface", replace(ROS2_CONTROL, '<state_interface name="effort"/>',
                                                   '<state_interface name="temperature"/>'),
         "ros2_control.unknown_interface", WARNING),
    Case("ros2_control_macro_without_prefix", together(replace(ROS2_CONTROL, "params=\"prefix:=''\"", 'params=""'),
                                                       replace(ROS2_CONTROL, "${prefix}", "", count=-1),
                                                       replace(URDF, RC_CALL, "<xacro:indy7_v2_ros2_control/>")),
         "ros2_control.prefix", WARNING, message={"why": "joint0"}),
    Case("ros2_control_joints_without_prefix", replace(ROS2_CONTROL, "${prefix}joint", "joint", count=-1),
         "ros2_control.prefix", WARNING, message={"why": "joint0"}),
    Case("urdf_without_prefix_arg", together(replace(URDF, '<xacro:arg name="prefix" default=""/>', ""),
                                             replace(URDF, "$(arg prefix)", "", count=-1)),
         "ros2_control.prefix", WARNING),
    Case("wrapper_passing_an_empty_prefix", replace(URDF, "$(arg prefix)", "", count=-1),
         "ros2_control.prefix", WARNING),   # as the protocol's wrapper does: <xacro:base_robot ... prefix=""/>
    Case("link_without_prefix", together(replace(URDF, '<link name="${pfx}tcp"/>', '<link name="tcp"/>'),
                                         replace(URDF, '<child link="${pfx}tcp"/>', '<child link="tcp"/>')),
         "urdf.prefix", WARNING, message={"why": "tcp"}),
    Case("ros2_control_file_not_included", unused_hardware_file(), "ros2_control.not_included", ERROR),
    # --- drive parameters (<param> tags of the ros2_control joints)
    Case("drive_resolution_not_integer", drive_param("encoder_resolution", "65536", "65536.5"), "drive.invalid",
         ERROR, line=">65536.5<", message={"summary": "encoder_resolution of joint joint0", "why": "'65536.5'",
                                           "how": '<param name="encoder_resolution">65536</param>'}),
    Case("drive_resolution_zero", drive_param("encoder_resolution", "65536", "0", joint=3), "drive.invalid", ERROR,
         line='"encoder_resolution">0<', message={"summary": "joint3"}),
    Case("drive_gear_negative", drive_param("gear_ratio", "101", "-101", joint=4), "drive.invalid", ERROR,
         line=">-101<", message={"summary": "gear_ratio of joint joint4"}),
    Case("drive_gear_not_finite", drive_param("gear_ratio", "121", "inf"), "drive.invalid", ERROR, line=">inf<"),
    Case("drive_direction_zero", drive_param("direction", "1", "0", joint=5), "drive.invalid", ERROR,
         line='"direction">0<', message={"what": "-1 when the drive counts opposite"}),
    Case("drive_vendor_id_too_large", replace(ROS2_CONTROL, '<param name="direction">1</param>',
                                              '<param name="direction">1</param>\n'
                                              '        <param name="vendor_id">0x100000000</param>'),
         "drive.invalid", ERROR, line="0x100000000", message={"what": "32-bit"}),
    Case("drive_product_code_not_a_number", replace(ROS2_CONTROL, '<param name="direction">1</param>',
                                                    '<param name="direction">1</param>\n'
                                                    '        <param name="product_code">ELMO</param>'),
         "drive.invalid", ERROR, line=">ELMO<"),
    Case("drive_gear_missing", drive_params_removed(2, "gear_ratio"), "drive.incomplete", ERROR,
         line='<joint name="${prefix}joint2">',
         message={"summary": "joint2 lacks drive parameter gear_ratio", "how": '<param name="gear_ratio">'}),
    Case("drive_joint_without_params", drive_params_removed(4), "drive.incomplete", ERROR,
         line='<joint name="${prefix}joint4">', message={"why": "declares none of them"}),
    Case("drive_param_unknown", replace(ROS2_CONTROL, '<param name="direction">1</param>',
                                        '<param name="direction">1</param>\n'
                                        '        <param name="zero_offset">0</param>'),
         "drive.unknown_param", WARNING, line="zero_offset", message={"what": "encoder_resolution"}),
    Case("drive_params_none", sub(ROS2_CONTROL, r"^ *<param [^\n]*\n", "", count=0), "drive.none", WARNING,
         message={"why": "bus:=ethercat needs them", "how": '<param name="gear_ratio">'}),
    Case("rp2_drive_wrist_gear_zero", drive_param("gear_ratio", "101", "0", joint=6, rel=RP2_CONTROL),
         "drive.invalid", ERROR, line='"gear_ratio">0<', message={"summary": "joint6"}, robot=RP2),
    # --- joint_limits.yaml
    Case("limits_file_missing", delete(LIMITS), "limits.missing_file", ERROR),
    Case("limits_yaml_syntax", replace(LIMITS, "    max_velocity: 2.617993878\n", "    max_velocity: 2.617993878: 1\n"),
         "limits.yaml", ERROR, message={"summary": "YAML syntax error in joint_limits.yaml"}),
    Case("limits_no_joint_limits_key", replace(LIMITS, "joint_limits:", "limits:"), "limits.structure", ERROR),
    Case("limits_entry_not_mapping", yaml_entry(LIMITS, "joint5", "  joint5: 3.0\n"), "limits.structure", ERROR,
         line="joint5: 3.0"),
    Case("limits_joint_missing", yaml_entry(LIMITS, "joint5", ""), "limits.missing_joint", ERROR,
         message={"summary": "joint5"}),
    Case("limits_extra_joint", append(LIMITS, "  joint6:\n    max_velocity: 1.0\n"), "limits.extra_joint", ERROR,
         line="joint6:", message={"why": "not in the URDF"}),
    Case("limits_fixed_joint", append(LIMITS, "  tcp_joint:\n    max_velocity: 1.0\n"), "limits.extra_joint", ERROR,
         line="tcp_joint:", message={"why": "a fixed or mimic joint"}),
    Case("limits_negative_velocity", replace(LIMITS, "max_velocity: 2.617993878", "max_velocity: -2.617993878"),
         "limits.nonpositive", ERROR, line="max_velocity: -2.617993878"),
    Case("limits_zero_acceleration", replace(LIMITS, "max_acceleration: 3.0", "max_acceleration: 0.0"),
         "limits.nonpositive", ERROR, line="max_acceleration: 0.0"),
    Case("limits_min_not_below_max", replace(LIMITS, "min_position: -3.054326191", "min_position: 3.054326191"),
         "limits.min_max", ERROR, line="min_position: 3.054326191"),
    Case("limits_position_missing", replace(LIMITS, "    max_position: 3.054326191\n", ""),
         "limits.position_missing", ERROR, line="joint0:"),
    Case("limits_not_a_number", replace(LIMITS, "max_jerk: 30.0", "max_jerk: fast"), "limits.type", ERROR,
         line="max_jerk: fast"),
    Case("limits_flag_not_bool", replace(LIMITS, "has_velocity_limits: true", 'has_velocity_limits: "true"'),
         "limits.type", ERROR, line='has_velocity_limits: "true"'),
    Case("limits_wider_than_urdf", replace(LIMITS, "max_velocity: 2.617993878", "max_velocity: 5.0"),
         "limits.exceeds_urdf", ERROR, line="max_velocity: 5.0",
         message={"summary": "loosens the velocity limit of joint0",
                  "why": 'max_velocity 5 is above the URDF\'s velocity="2.61799" (', "how": "at most 2.61799"}),
    Case("limits_min_position_beyond_urdf", replace(LIMITS, "min_position: -3.054326191", "min_position: -3.5"),
         "limits.exceeds_urdf", ERROR, line="min_position: -3.5",
         message={"why": 'min_position -3.5 is below the URDF\'s lower="-3.05433"', "how": "at least -3.05433"}),
    Case("limits_effort_beyond_urdf", replace(LIMITS, "max_effort: 79.79", "max_effort: 120"),
         "limits.exceeds_urdf", ERROR, line="max_effort: 120", message={"summary": "effort limit of joint3"}),
    Case("limits_velocity_switched_off", replace(LIMITS, "has_velocity_limits: true", "has_velocity_limits: false"),
         "limits.removes_urdf", ERROR, line="has_velocity_limits: false",
         message={"summary": "removes the velocity limit of joint0", "why": 'velocity="2.61799"'}),
    Case("limits_position_switched_off", replace(LIMITS, "has_position_limits: true", "has_position_limits: false"),
         "limits.removes_urdf", ERROR, line="has_position_limits: false",
         message={"why": 'lower="-3.05433" upper="3.05433"'}),
    Case("limits_effort_switched_off", replace(LIMITS, "has_effort_limits: true", "has_effort_limits: false"),
         "limits.removes_urdf", ERROR, line="has_effort_limits: false", message={"why": 'effort="431.97"'}),
    Case("limits_unknown_key", replace(LIMITS, "    max_jerk: 30.0\n", "    max_jerk: 30.0\n    max_snap: 300.0\n"),
         "limits.unknown_key", WARNING, line="max_snap: 300.0"),
    Case("limits_no_jerk", replace(LIMITS, "    has_jerk_limits: true\n    max_jerk: 30.0\n", ""),
         "limits.incomplete", WARNING, line="joint0:", message={"why": "max_jerk"}),
    Case("rp2_limits_joint6_missing", yaml_entry(LIMITS, "joint6", ""), "limits.missing_joint",
         ERROR, message={"summary": "joint6"}, robot=RP2),
    # --- controllers.yaml (optional: a package without one gets the generated arm_controller)
    Case("controllers_unknown_joint", write(CONTROLLERS, controllers_yaml([*JOINTS[:5], "joint_5"])),
         "controllers.unknown_joint", ERROR, line="- joint_5"),
    Case("controllers_yaml_syntax", write(CONTROLLERS, controllers_yaml(JOINTS) + "  bad: [\n"),
         "controllers.yaml", ERROR),
    Case("controllers_not_mapping", write(CONTROLLERS, "- joint_trajectory_controller\n"),
         "controllers.structure", ERROR),
    # --- SRDF
    Case("srdf_group_unknown_link", srdf_insert('  <group name="gripper">\n    <link name="finger"/>\n  </group>\n'),
         "srdf.unknown_link", ERROR, line='<link name="finger"/>'),
    Case("srdf_group_unknown_joint", srdf_insert('  <group name="wrist">\n    <joint name="joint9"/>\n  </group>\n'),
         "srdf.unknown_joint", ERROR, line='<joint name="joint9"/>'),
    Case("srdf_group_unknown_subgroup", srdf_insert('  <group name="all">\n    <group name="hand"/>\n  </group>\n'),
         "srdf.unknown_group", ERROR, line='<group name="hand"/>'),
    Case("srdf_chain_unknown_tip", replace(SRDF, 'tip_link="tcp"', 'tip_link="tool0"'), "srdf.chain", ERROR,
         line='tip_link="tool0"', message={"why": "tool0"}),
    Case("srdf_chain_swapped", replace(SRDF, 'base_link="link0" tip_link="tcp"', 'base_link="tcp" tip_link="link0"'),
         "srdf.chain", ERROR, line='base_link="tcp"', message={"summary": "not connected"}),
    Case("srdf_state_unknown_group", replace(SRDF, 'group_state name="home" group="arm"',
                                             'group_state name="home" group="manipulator"'),
         "srdf.unknown_group", ERROR, line='group="manipulator"'),
    Case("srdf_state_unknown_joint", replace(SRDF, '<joint name="joint5"', '<joint name="joint6"'),
         "srdf.state_unknown_joint", ERROR, line='<joint name="joint6"'),
    Case("srdf_state_out_of_limits", srdf_state_value("joint2", "-1.570796", "-4.0"), "srdf.state_out_of_limits", ERROR,
         line='value="-4.0"'),
    Case("srdf_state_not_a_number", srdf_state_value("joint3", "0", "up"), "srdf.state_out_of_limits", ERROR,
         line='value="up"'),
    Case("srdf_state_nan", srdf_state_value("joint3", "0", "nan"), "srdf.state_out_of_limits", ERROR,
         line='value="nan"'),
    Case("srdf_collision_unknown_link", replace(SRDF, 'link2="tcp"', 'link2="gripper"'),
         "srdf.collision_unknown_link", ERROR, line='link2="gripper"', message={"why": "gripper"}),
    Case("srdf_passive_joint_unknown", srdf_insert('  <passive_joint name="gripper_joint"/>\n'),
         "srdf.passive_unknown_joint", ERROR, line='<passive_joint name="gripper_joint"/>',
         message={"why": "gripper_joint"}),
    Case("srdf_broken_xml", replace(SRDF, "</group_state>", "</group-state>"), "srdf.xml", ERROR),
    Case("srdf_too_large", padded(SRDF, 17), "srdf.xml", ERROR,
         message={"summary": "File too large", "what": "at most 16.0 MiB", "why": "holds 17.0 MiB"}),
    Case("srdf_robot_name_differs", replace(SRDF, '<robot name="indy7_v2">', '<robot name="indy7">'),
         "srdf.robot_name", WARNING),
    # --- kinematics.yaml
    Case("kinematics_unknown_group", replace(KINEMATICS, "arm:", "manipulator:"), "kinematics.unknown_group", ERROR,
         line="manipulator:"),
    Case("kinematics_without_srdf", delete(SRDF), "kinematics.without_srdf", WARNING),
    Case("kinematics_unknown_solver", replace(KINEMATICS, "KDLKinematicsPlugin", "KDLKinematics"),
         "kinematics.solver_unknown", WARNING, line="arm:"),
    Case("kinematics_yaml_syntax", replace(KINEMATICS, "  kinematics_solver_timeout: 0.05",
                                           "  kinematics_solver_timeout: [0.05"), "kinematics.yaml", ERROR),
    Case("kinematics_not_mapping", write(KINEMATICS, "- arm\n"), "kinematics.structure", ERROR),
    # --- PLEM_COMPAT_VERSION
    Case("compat_missing", delete(COMPAT), "compat.missing", ERROR),
    Case("compat_not_semver", write(COMPAT, "1.0\n"), "compat.semver", ERROR, message={"why": "'1.0'"}),
    Case("compat_other_major", write(COMPAT, "2.0.0\n"), "compat.major", ERROR),
    Case("compat_newer_minor", write(COMPAT, "1.5.0\n"), "compat.minor_newer", WARNING),
    # --- meshes: a missing visual mesh leaves a part out of the view, a missing collision mesh disables planning
    Case("mesh_missing_file", replace(URDF, '<cylinder radius="0.075" length="0.0775"/>',
                                      '<mesh filename="package://indy7_v2_description/meshes/link0.stl"/>'),
         "urdf.collision_mesh_missing", WARNING,
         message={"summary": "Planning is disabled: 1 collision mesh not found", "why": "meshes/link0.stl"}),
    Case("mesh_missing_package", visual_mesh("package://indy_meshes/link0.stl"), "urdf.mesh_missing", WARNING,
         message={"summary": "indy_meshes", "what": "a visual mesh"}),
]


# ---------------------------------------------------------------- running a case

def make_package(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, robot: str = "indy7_v2") -> Path:
    """A copy of the built-in package that shadows it on the package search path (so `$(find)` sees the copy)."""
    folder = tmp_path / "packages"
    folder.mkdir(exist_ok=True)
    monkeypatch.setenv("PLEM_PACKAGE_PATH", str(folder))
    return copy_builtin(robot, folder)


def run_validation(root: Path, **kwargs: Any) -> ValidationReport:
    """validate_package, failing the test on any exception (it reports problems; it only raises for no package)."""
    try:
        return validate_package(root, **kwargs)
    except PlemError as error:
        pytest.fail(f"validate_package raised {type(error).__name__} instead of reporting:\n{error}")
    except Exception as error:  # noqa: BLE001 - the point of the corpus
        pytest.fail(f"non-PlemError escaped validate_package: {type(error).__name__}: {error}")


def line_of(path: Path, needle: str) -> int:
    lines = path.read_text(encoding="utf-8").splitlines()
    return next(number for number, text in enumerate(lines, 1) if needle in text)


def describe(problems: list[Problem]) -> str:
    return "\n".join(f"  {p.severity.value} {p.code} {p.location}: {p.summary} | {p.why}" for p in problems) or "  none"


def test_case_ids_are_unique():
    ids = [case.id for case in CASES]
    assert len(ids) == len(set(ids)) and len(ids) >= 45


@pytest.mark.parametrize("robot", ["indy7_v2", RP2])
def test_unmutated_copy_has_no_problems(tmp_path, monkeypatch, robot):
    report = run_validation(make_package(tmp_path, monkeypatch, robot))
    assert report.findings.problems == [], describe(report.findings.problems)
    assert report.passed(strict=True)


def test_valid_controllers_yaml_adds_no_problems(tmp_path, monkeypatch):
    """So that the controllers cases fail for their mutation, not for the file as such."""
    root = make_package(tmp_path, monkeypatch)
    write(CONTROLLERS, controllers_yaml(JOINTS))(root)
    report = run_validation(root)
    assert report.findings.problems == [], describe(report.findings.problems)


@pytest.mark.parametrize("case", CASES, ids=lambda case: case.id)
def test_broken_package_is_reported(tmp_path, monkeypatch, case: Case):
    root = make_package(tmp_path, monkeypatch, case.robot)
    case.mutate(root)
    report = run_validation(root, **case.kwargs)
    problems = report.findings.problems
    matching = [p for p in problems if p.code == case.code]
    assert matching, f"expected {case.code}, found:\n{describe(problems)}"
    assert any(p.severity is case.severity for p in matching), f"expected {case.severity.value}:\n{describe(matching)}"
    matching = [p for p in matching if p.severity is case.severity]
    for name, expected in case.message.items():
        assert any(expected in getattr(p, name) for p in matching), \
            f"no {case.code} has {expected!r} in its {name}:\n{describe(matching)}"
    if case.line is not None:
        located = [p for p in matching if p.file is not None and p.file.is_file()]
        assert located, f"{case.code} names no file:\n{describe(matching)}"
        expected_line = line_of(located[0].file, case.line)
        assert any(p.line == expected_line for p in located), \
            f"expected {case.code} at {located[0].file.name}:{expected_line}:\n{describe(matching)}"
    if case.severity is ERROR:
        assert not report.passed()
    else:
        assert report.findings.errors == [], f"a warning case must not cause errors:\n{describe(problems)}"
        assert report.passed() and not report.passed(strict=True)


@pytest.mark.parametrize("rel, mutation, code, needle", [
    (LIMITS, replace(LIMITS, "    max_velocity: 2.617993878\n", "    max_velocity: 2.617993878: 1\n"), "limits.yaml",
     "max_velocity: 2.617993878: 1"),
    (KINEMATICS, replace(KINEMATICS, "kinematics_solver_attempts: 3", "kinematics_solver_attempts: 3: 4"),
     "kinematics.yaml", "kinematics_solver_attempts: 3: 4"),
    (CONTROLLERS, write(CONTROLLERS, controllers_yaml(JOINTS).replace("update_rate: 1000", "update_rate: 1000: 1")),
     "controllers.yaml", "update_rate: 1000: 1"),
], ids=["joint_limits", "kinematics", "controllers"])
def test_yaml_syntax_error_names_file_and_line(tmp_path, monkeypatch, rel, mutation, code, needle):
    """A YAML syntax error carries the file and the 1-based line in the problem itself, not only in its text."""
    root = make_package(tmp_path, monkeypatch)
    mutation(root)
    problem = next(p for p in run_validation(root).findings.problems if p.code == code)
    line = line_of(root / rel, needle)
    assert f"{rel}:{line}:" in problem.why
    assert problem.file == root / rel
    assert problem.location == f"{root / rel}:{line}"


def test_drive_parameters_are_checked_at_startup_and_named_by_file_and_line(tmp_path, monkeypatch):
    """Launch refuses a malformed drive parameter before the bus opens; the bus's own reading names the same line."""
    root = make_package(tmp_path, monkeypatch)
    drive_param("gear_ratio", "121", "-121", joint=1)(root)
    report = run_validation(root, stage=Stage.STARTUP)
    (problem,) = report.findings.errors
    line = line_of(root / ROS2_CONTROL, ">-121<")
    assert (problem.code, problem.location) == ("drive.invalid", f"{root / ROS2_CONTROL}:{line}")
    with pytest.raises(ConfigError) as caught:
        drive_parameters(report.urdf, JOINTS, sources=(report.files.ros2_control, report.files.urdf))
    assert caught.value.why.startswith(f"{root / ROS2_CONTROL}:{line}: ") and "joint1" in caught.value.summary


def test_drive_parameters_from_xacro_properties(tmp_path, monkeypatch):
    """Values xacro computes count as written: a property shared by the wrist joints reaches every one of them."""
    root = make_package(tmp_path, monkeypatch)
    together(replace(ROS2_CONTROL, "<ros2_control ", '<xacro:property name="wrist_gear" value="${100 + 1}"/>\n'
                                                     "    <ros2_control "),
             replace(ROS2_CONTROL, '<param name="gear_ratio">101</param>',
                     '<param name="gear_ratio">${wrist_gear}</param>', count=-1))(root)
    report = run_validation(root)
    assert report.findings.problems == [], describe(report.findings.problems)
    assert [d.gear_ratio for d in drive_parameters(report.urdf, JOINTS)] == [121.0] * 3 + [101.0] * 3


ALL_AT_ONCE = ["compat_other_major", "two_root_links", "mesh_missing_file", "ros2_control_wrong_plugin",
               "ros2_control_unknown_interface", "limits_negative_velocity", "limits_unknown_key",
               "controllers_unknown_joint", "srdf_collision_unknown_link", "srdf_state_out_of_limits",
               "kinematics_unknown_solver"]


def test_every_problem_is_reported_in_one_pass(tmp_path, monkeypatch):
    """Validation collects everything: eleven independent mutations give eleven codes in one report."""
    cases = [case for case in CASES if case.id in ALL_AT_ONCE]
    assert len(cases) == len(ALL_AT_ONCE)
    root = make_package(tmp_path, monkeypatch)
    together(*(case.mutate for case in cases))(root)
    report = run_validation(root)
    found = {(p.code, p.severity) for p in report.findings.problems}
    missing = [case.id for case in cases if (case.code, case.severity) not in found]
    assert not missing, f"not reported: {missing}\n{describe(report.findings.problems)}"
    assert not report.passed()


@pytest.mark.parametrize("package", ["no_such_description", "./no_such_description", "", "a" * 300],
                         ids=["name", "relative_path", "empty_name", "overlong_name"])
def test_missing_package_raises_plem_error(tmp_path, monkeypatch, package):
    """Not finding the package is the one case validate_package raises for (an empty name is no package either)."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(PackageNotFoundError):
        validate_package(package)
