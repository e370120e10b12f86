"""Drive parameters of a description package: per actuated joint, what turns encoder counts into joint angles
and identifies the drive on the bus.

They are ros2_control `<param>` tags in each `<joint>` of the package's `<ros2_control>` block:

    <param name="encoder_resolution">65536</param>   counts per motor revolution, a positive integer
    <param name="gear_ratio">121</param>             motor revolutions per joint revolution, a positive number
    <param name="direction">1</param>                1, or -1 when the drive counts opposite to the URDF axis
    <param name="vendor_id">0x0000066F</param>       optional EtherCAT identity, each an unsigned 32-bit
    <param name="product_code">0x00000001</param>    integer in hex or decimal
    <param name="revision">0x00010000</param>
    <param name="rated_torque">1.27</param>          optional: the motor's rated torque in N·m (0x6076 / 1000)

`drive_parameters` hands them to the bus; `check_drive_parameters` gives the validator the same problems,
found by the same parsers. xacro drops line numbers, so `ParamSources` finds where a joint's parameters are
written in the package's xacro files.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from lxml import etree

from plem.description.hardware import sort_blocks
from plem.description.model import HardwareJoint, UrdfModel, XacroSources, rendered_line_note, source_line
from plem.errors import ConfigError

U32_MAX = 0xFFFF_FFFF
_DECIMAL = re.compile(r"[+-]?[0-9]{1,32}")
_HEX = re.compile(r"0[xX][0-9a-fA-F]{1,32}")
_HARDWARE_TAGS = ("param", "command_interface", "state_interface")


def _positive_int(text: str) -> int | None:
    value = int(text) if _DECIMAL.fullmatch(text) else 0
    return value if value > 0 else None


def _positive_number(text: str) -> float | None:
    try:
        value = float(text)
    except ValueError:
        return None
    return value if math.isfinite(value) and value > 0 else None


def _direction(text: str) -> int | None:
    value = int(text) if _DECIMAL.fullmatch(text) else 0
    return value if value in (1, -1) else None


def _u32(text: str) -> int | None:
    if _HEX.fullmatch(text):
        value = int(text, 16)
    elif _DECIMAL.fullmatch(text) and text[0].isdigit():
        value = int(text)
    else:
        return None
    return value if value <= U32_MAX else None


@dataclass(frozen=True)
class ParamKind:
    """How one drive parameter is read: its parser (None for a malformed text), its meaning, an example value
    and where the true value is found."""

    parse: Callable[[str], int | float | None]
    meaning: str
    example: str
    source: str


_IDENTITY = "an unsigned 32-bit integer in hex (0x...) or decimal"
PARAMS: dict[str, ParamKind] = {
    "encoder_resolution": ParamKind(_positive_int, "encoder counts per motor revolution, a positive integer",
                                    "65536", "the drive's or encoder's documentation"),
    "gear_ratio": ParamKind(_positive_number, "motor revolutions per joint revolution, a positive finite number",
                            "121", "the gearbox's documentation"),
    "direction": ParamKind(_direction, "1, or -1 when the drive counts opposite to the URDF joint axis", "1",
                           "a slow test move: -1 when the joint turns against its URDF <axis>"),
    "vendor_id": ParamKind(_u32, f"the drive's EtherCAT vendor id, {_IDENTITY}", "0x0000066F",
                           "the drive's ESI file"),
    "product_code": ParamKind(_u32, f"the drive's EtherCAT product code, {_IDENTITY}", "0x00000001",
                              "the drive's ESI file"),
    "revision": ParamKind(_u32, f"the drive's EtherCAT revision number, {_IDENTITY}", "0x00010000",
                          "the drive's ESI file"),
    "rated_torque": ParamKind(_positive_number, "the motor's rated torque in N·m, a positive finite number (the "
                              "drive's torque objects count thousandths of it)", "1.27",
                              "the drive's or motor's documentation (object 0x6076, in mN·m)"),
}
REQUIRED = ("encoder_resolution", "gear_ratio", "direction")


@dataclass(frozen=True)
class DriveParameters:
    """One joint's drive: encoder counts per motor revolution, gearing, counting direction and, optionally, the
    EtherCAT identity (vendor id, product code, revision) the drive must report and the motor's rated torque (N·m;
    when absent the drive's 0x6076 gives it)."""

    encoder_resolution: int
    gear_ratio: float
    direction: int
    vendor_id: int | None = None
    product_code: int | None = None
    revision: int | None = None
    rated_torque: float | None = None

    @property
    def counts_per_radian(self) -> float:
        """Encoder counts per radian at the joint output (positive; `direction` gives the sign)."""
        return self.encoder_resolution * self.gear_ratio / (2 * math.pi)

    @property
    def signed_counts_per_radian(self) -> float:
        """Counts per radian in the drive's counting direction: joint angle × this = counts."""
        return self.direction * self.counts_per_radian


def param_line(name: str, value: str | None = None) -> str:
    """The XML line declaring parameter `name` (with its example value unless one is given)."""
    return f'<param name="{name}">{PARAMS[name].example if value is None else value}</param>'


@dataclass(frozen=True)
class ParamProblem:
    """One problem with the drive parameters of a ros2_control joint, worded for the user. `param` is None when
    the problem is the joint's (parameters missing); `line` is the line in the rendered URDF."""

    code: str
    error: bool
    joint: str
    param: str | None
    summary: str
    what: str
    why: str
    how: str
    line: int | None

    def why_at(self, source_line: int | None) -> str:
        """`why`, pointing at the rendered URDF's line when the line in the package's files is not known."""
        return self.why + rendered_line_note(source_line, self.line)

    def as_config_error(self, sources: ParamSources) -> ConfigError:
        """The problem as the error a user sees, placed in the package's files where `sources` can tell."""
        path, line = sources.locate(self.joint, self.param)
        place = f"{path}:{line}: " if path and line else f"{path}: " if path else ""
        return ConfigError(self.summary, what=self.what, why=place + self.why_at(line), how=self.how)


def _invalid(joint: HardwareJoint, name: str) -> ParamProblem:
    kind, text = PARAMS[name], joint.params[name]
    return ParamProblem(
        "drive.invalid", True, joint.name, name, f"Invalid drive parameter {name} of joint {joint.name}",
        what=f"{name}: {kind.meaning}", why=f'<param name="{name}"> of joint {joint.name} is {text!r}',
        how=f"write it as {param_line(name)}, with the value from {kind.source}", line=joint.param_lines.get(name))


def _incomplete(joint: HardwareJoint, missing: list[str], declaring: str, listed: bool) -> ParamProblem:
    """Required parameters missing from `joint` (`listed`: the joint is in the ros2_control block at all)."""
    present = [name for name in REQUIRED if name in joint.params]
    lines = "\n".join(param_line(name) for name in missing)
    if present:
        why = f"joint {joint.name} declares only {', '.join(present)}"
    else:
        why = f"joint {joint.name} {'declares none of them' if listed else 'is not in <ros2_control>'}, while " \
              f"joint {declaring} declares drive parameters"
    if listed:
        how = f'add inside <joint name="{joint.name}"> of the <ros2_control> block, with its drive\'s values:\n{lines}'
    else:
        how = f'add to the <ros2_control> block, with its drive\'s values:\n' \
              f'<joint name="{joint.name}">\n{lines}\n</joint>'
    return ParamProblem(
        "drive.incomplete", True, joint.name, None,
        f"Joint {joint.name} lacks drive parameter{'s' if len(missing) > 1 else ''} {', '.join(missing)}",
        what=f"{', '.join(REQUIRED)} on every joint of <ros2_control> once one joint declares drive parameters",
        why=why, how=how, line=joint.line)


def _unknown(joint: HardwareJoint, name: str) -> ParamProblem:
    return ParamProblem(
        "drive.unknown_param", False, joint.name, name, f"Joint {joint.name} has an unknown <param> {name!r}",
        what=f"<param> names plem reads: {', '.join(PARAMS)}",
        why=f'<param name="{name}"> of joint {joint.name} is none of them',
        how="fix the name if it is a misspelt drive parameter, otherwise remove it (plem ignores it)",
        line=joint.param_lines.get(name))


def declares_drive_parameters(urdf: UrdfModel) -> bool:
    """Whether any ros2_control joint has a drive parameter."""
    return any(name in PARAMS for block in sort_blocks(urdf.ros2_control).driven for joint in block.joints
               for name in joint.params)


def _read(urdf: UrdfModel, joint_names: Sequence[str]) -> tuple[list[dict[str, Any]], list[ParamProblem]]:
    """The parsed parameters of each of `joint_names` and every problem with them, in joint order."""
    hardware: dict[str, HardwareJoint] = {}
    for block in sort_blocks(urdf.ros2_control).driven:
        for joint in block.joints:
            hardware.setdefault(joint.name, joint)
    declaring = next((j.name for j in hardware.values() if any(name in PARAMS for name in j.params)), None)
    values: list[dict[str, Any]] = []
    problems: list[ParamProblem] = []
    for name in joint_names:
        listed = name in hardware
        joint = hardware[name] if listed else HardwareJoint(name, [], [], None)
        parsed = {key: PARAMS[key].parse(text) for key, text in joint.params.items() if key in PARAMS}
        problems += [_invalid(joint, key) if key in PARAMS else _unknown(joint, key)
                     for key in joint.params if key not in PARAMS or parsed[key] is None]
        missing = [key for key in REQUIRED if key not in joint.params]
        if declaring is not None and missing:
            problems.append(_incomplete(joint, missing, declaring, listed))
        values.append(parsed)
    return values, problems


def check_drive_parameters(urdf: UrdfModel, joint_names: Sequence[str]) -> list[ParamProblem]:
    """Every problem with the drive parameters of `joint_names`: malformed values and, when the package declares
    drive parameters at all, missing ones (errors); unknown `<param>` names (warnings)."""
    return _read(urdf, joint_names)[1]


def drive_parameters(urdf: UrdfModel, joint_names: Sequence[str], *,
                     sources: Sequence[Path | None] = ()) -> tuple[DriveParameters, ...] | None:
    """The drive parameters of each of `joint_names`, in that order; None when the package declares none.

    Raises ConfigError for the first malformed or missing value (`plem validate` lists them all). `sources`, the
    package's xacro files (ros2_control file first), let the message name the file and line to edit.
    """
    values, problems = _read(urdf, joint_names)
    error = next((problem for problem in problems if problem.error), None)
    if error is not None:
        raise error.as_config_error(ParamSources(sources))
    if not declares_drive_parameters(urdf):
        return None
    return tuple(DriveParameters(**joint) for joint in values)


def _is_hardware_joint(element: etree._Element) -> bool:
    """A `<joint>` of a ros2_control block: it has parameters or interfaces (a URDF joint of the same name has
    neither)."""
    return any(child.tag in _HARDWARE_TAGS for child in element)


class ParamSources(XacroSources):
    """Where the ros2_control joints are written in a package's xacro files, to point problems at a line.

    A rendered joint is matched back by name among the source `<joint>` elements with parameters or interfaces
    (see XacroSources); otherwise the first file is named without a line.
    """

    def locate(self, joint: str, param: str | None) -> tuple[Path | None, int | None]:
        """The file and line of `param` in the joint named `joint` after rendering (the joint's own line when it
        has no such parameter), or the first file and no line when the joint cannot be told apart."""
        path, element = self.find("joint", joint, _is_hardware_joint)
        if element is None:
            return path, None
        tags = [tag for tag in element.iter("param") if tag.get("name") == param] if param else []
        return path, source_line(tags[-1] if tags else element)


__all__ = ["PARAMS", "REQUIRED", "DriveParameters", "ParamProblem", "ParamSources", "check_drive_parameters",
           "declares_drive_parameters", "drive_parameters", "param_line"]
