"""The /tf and /tf_static transforms robot_state_publisher would send for a URDF and joint positions.

Lets the ROS bridge publish the robot's frames itself, so tf and RViz work without a robot_state_publisher node.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
from lxml import etree

from plem.description.model import parse_xml
from plem.errors import ConfigError
from plem.middleware.types import InterfaceLibrary

#: Joint types moved by a position: a rotation about, or a translation along, the joint's axis.
ROTATING = frozenset({"revolute", "continuous"})
SLIDING = frozenset({"prismatic"})
#: Joint types robot_state_publisher publishes on /tf_static. kdl_parser turns a planar joint into a fixed one;
#: floating joints are published by neither topic.
STATIC = frozenset({"fixed", "planar"})
SKIPPED = frozenset({"floating"})

_SOURCE = Path("robot_description")

Array = npt.NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class Transform:
    """One parent → child frame transform: translation in metres, rotation as a unit quaternion (x, y, z, w)."""

    parent: str
    child: str
    translation: tuple[float, float, float]
    rotation: tuple[float, float, float, float]


@dataclass(frozen=True, slots=True)
class _Joint:
    """What the transform of one URDF `<joint>` needs."""

    name: str
    type: str
    parent: str
    child: str
    xyz: tuple[float, float, float]
    rpy: tuple[float, float, float]
    axis: tuple[float, float, float]
    mimic: tuple[str, float, float] | None  # mimicked joint, multiplier, offset


def _invalid(joint: str, what: str, found: str) -> ConfigError:
    return ConfigError(
        f"Joint {joint!r} cannot be turned into a transform",
        what=what, why=f"joint {joint!r}: {found}",
        how="fix the joint in the URDF (or its xacro source) and render the description again",
    )


def _number(joint: str, text: str, what: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise _invalid(joint, what, f"found {text!r}")
    return value


def _triple(joint: str, element: etree._Element | None, attribute: str,
            default: tuple[float, float, float]) -> tuple[float, float, float]:
    """Three numbers from `attribute` of `element`, or `default` when either is absent."""
    if element is None or (text := element.get(attribute)) is None:
        return default
    what = f'three numbers in <{element.tag} {attribute}="...">'
    try:
        x, y, z = (float(part) for part in text.split())
    except ValueError:                                  # a word that is no number, or not three of them
        x = y = z = math.nan
    if not all(math.isfinite(value) for value in (x, y, z)):
        raise _invalid(joint, what, f"found {text!r}")
    return x, y, z


def _link(joint: str, element: etree._Element, tag: str) -> str:
    found = element.find(tag)
    name = found.get("link") if found is not None else None
    if not name:
        raise _invalid(joint, f'a <{tag} link="..."/> element', f"no <{tag}> link given")
    return name


def _joint(element: etree._Element) -> _Joint:
    """Read one `<joint>` element, with URDF's defaults for anything left out."""
    name = element.get("name") or ""
    kind = element.get("type") or ""
    if kind not in ROTATING | SLIDING | STATIC | SKIPPED:
        raise _invalid(name, "one of the URDF joint types", f"type {kind!r}")
    mimic = element.find("mimic")
    mimicked = None
    if mimic is not None and mimic.get("joint"):
        mimicked = (str(mimic.get("joint")),
                    _number(name, mimic.get("multiplier", "1"), "a number in <mimic multiplier>"),
                    _number(name, mimic.get("offset", "0"), "a number in <mimic offset>"))
    origin = element.find("origin")
    return _Joint(
        name=name, type=kind, parent=_link(name, element, "parent"), child=_link(name, element, "child"),
        xyz=_triple(name, origin, "xyz", (0.0, 0.0, 0.0)), rpy=_triple(name, origin, "rpy", (0.0, 0.0, 0.0)),
        axis=_triple(name, element.find("axis"), "xyz", (1.0, 0.0, 0.0)), mimic=mimicked,
    )


def _quaternion_rpy(roll: float, pitch: float, yaw: float) -> Array:
    """(x, y, z, w) of URDF's fixed-axis roll, pitch, yaw: Rz(yaw)·Ry(pitch)·Rx(roll)."""
    sr, cr = math.sin(roll / 2), math.cos(roll / 2)
    sp, cp = math.sin(pitch / 2), math.cos(pitch / 2)
    sy, cy = math.sin(yaw / 2), math.cos(yaw / 2)
    return np.array([sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
                     cr * cp * sy - sr * sp * cy, cr * cp * cy + sr * sp * sy])


def _product(a: Array, b: Array) -> Array:
    """Hamilton product a ⊗ b of (x, y, z, w) quaternions, whose rotation matrix is R(a)·R(b)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array([aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz])


def _matrix(q: Array) -> Array:
    """The rotation matrix of a unit (x, y, z, w) quaternion."""
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _transform(parent: str, child: str, translation: Sequence[float], rotation: Sequence[float]) -> Transform:
    x, y, z = translation
    qx, qy, qz, qw = rotation
    return Transform(parent, child, (float(x), float(y), float(z)), (float(qx), float(qy), float(qz), float(qw)))


class TreeTransforms:
    """A URDF's joint transforms as robot_state_publisher computes them, frame names prefixed by `frame_prefix`.

    Everything independent of the joint positions is worked out here, so `moving()` costs a few array operations.
    """

    def __init__(self, urdf_text: str, frame_prefix: str = "") -> None:
        self.frame_prefix = frame_prefix
        root = parse_xml(urdf_text, _SOURCE)
        # Only <robot>'s own <joint> children: <ros2_control> and <transmission> hold <joint> elements too.
        # robot_state_publisher sends each topic's transforms in joint-name order.
        joints = sorted((_joint(element) for element in root.findall("joint")), key=lambda joint: joint.name)
        self._static = tuple(
            _transform(frame_prefix + joint.parent, frame_prefix + joint.child, joint.xyz,
                       _quaternion_rpy(*joint.rpy).tolist())
            for joint in joints if joint.type in STATIC)
        moving = [joint for joint in joints if joint.type in ROTATING | SLIDING]
        #: The joints whose positions `moving()` needs: every joint that moves and mimics no other.
        self.moving_joints: tuple[str, ...] = tuple(joint.name for joint in moving if joint.mimic is None)
        self._names = [joint.name for joint in moving]
        self._mimics = [joint.mimic for joint in moving]
        self._parents = [frame_prefix + joint.parent for joint in moving]
        self._children = [frame_prefix + joint.child for joint in moving]
        # Per moving joint: origin translation t0 and rotation q0, the translation per metre of position (d,
        # zero for rotating joints), the half angle per radian of position (h, zero for sliding joints) and
        # q0 ⊗ (axis, 0), so that the rotation at position v is cos(h·v)·q0 + sin(h·v)·(q0 ⊗ (axis, 0)).
        count = len(moving)
        self._t0, self._d = np.zeros((count, 3)), np.zeros((count, 3))
        self._q0, self._q_axis = np.zeros((count, 4)), np.zeros((count, 4))
        self._h = np.zeros(count)
        for row, joint in enumerate(moving):
            axis = np.array(joint.axis)
            length = float(np.linalg.norm(axis))
            if length == 0.0:
                raise _invalid(joint.name, 'a non-zero <axis xyz="..."/>', "the axis is 0 0 0")
            axis /= length
            q0 = _quaternion_rpy(*joint.rpy)
            self._t0[row], self._q0[row] = joint.xyz, q0
            if joint.type in ROTATING:
                self._h[row] = 0.5
                self._q_axis[row] = _product(q0, np.append(axis, 0.0))
            else:
                self._d[row] = _matrix(q0) @ axis

    def static(self) -> list[Transform]:
        """The fixed joints' transforms, which robot_state_publisher latches on /tf_static."""
        return list(self._static)

    def moving(self, positions: Mapping[str, float]) -> list[Transform]:
        """The moving joints' transforms at `positions` (joint name → radians or metres), as sent on /tf.

        A mimic joint follows its mimicked joint unless its own position is given, which then wins, as in
        robot_state_publisher; a joint with no position to go on is left out.
        """
        rows: list[int] = []
        values: list[float] = []
        for row, (name, mimic) in enumerate(zip(self._names, self._mimics, strict=True)):
            value = positions.get(name)
            if value is None and mimic is not None:
                source = positions.get(mimic[0])
                value = None if source is None else source * mimic[1] + mimic[2]
            if value is not None:
                rows.append(row)
                values.append(value)
        if not rows:
            return []
        v = np.asarray(values, dtype=np.float64)
        half = self._h[rows] * v
        rotations = np.cos(half)[:, None] * self._q0[rows] + np.sin(half)[:, None] * self._q_axis[rows]
        translations = self._t0[rows] + v[:, None] * self._d[rows]
        return [_transform(self._parents[row], self._children[row], translation, rotation)
                for row, translation, rotation in zip(rows, translations.tolist(), rotations.tolist(), strict=True)]


def tf_message(library: InterfaceLibrary, transforms: Sequence[Transform], stamp_ns: int) -> Any:
    """A tf2_msgs/msg/TFMessage holding `transforms`, all stamped `stamp_ns` nanoseconds since the epoch."""
    new = library.new
    return new("tf2_msgs/msg/TFMessage", transforms=[
        new("geometry_msgs/msg/TransformStamped",
            header=new("std_msgs/msg/Header", stamp=library.stamp(stamp_ns), frame_id=t.parent),
            child_frame_id=t.child,
            transform=new("geometry_msgs/msg/Transform",
                          translation=new("geometry_msgs/msg/Vector3", x=t.translation[0], y=t.translation[1],
                                          z=t.translation[2]),
                          rotation=new("geometry_msgs/msg/Quaternion", x=t.rotation[0], y=t.rotation[1],
                                       z=t.rotation[2], w=t.rotation[3])))
        for t in transforms])
