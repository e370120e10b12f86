"""Parsed URDF and SRDF: the names, tree and limits the checks and the runtime need."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import cast

from lxml import etree

from plem.description.problems import DescriptionError

ACTUATED_TYPES = ("revolute", "prismatic", "continuous")
LESS_TESTED_TYPES = ("prismatic", "continuous")


def _float(value: str | None) -> float | None:
    try:
        return float(value) if value is not None else None
    except ValueError:
        return None


def source_line(element: etree._Element) -> int | None:
    """The element's line in its source, None when unknown (lxml-stubs declares `sourceline` without a type)."""
    return cast("int | None", element.sourceline)


def _params(element: etree._Element | None) -> tuple[dict[str, str], dict[str, int | None]]:
    """The `<param name="...">text</param>` children of `element` by name (the last wins) and their lines."""
    tags = element.findall("param") if element is not None else []
    return ({tag.get("name") or "": (tag.text or "").strip() for tag in tags},
            {tag.get("name") or "": source_line(tag) for tag in tags})


def parse_xml(text: str | bytes, source: Path) -> etree._Element:
    """Parse XML keeping line numbers; syntax errors name the file and line."""
    data = text.encode("utf-8") if isinstance(text, str) else text
    try:
        return etree.fromstring(data, parser=etree.XMLParser(remove_comments=True, resolve_entities=False,
                                                              no_network=True))
    except etree.XMLSyntaxError as error:
        raise DescriptionError(
            f"Invalid XML in {source.name}",
            what=f"well-formed XML in {source}",
            why=f"{source}:{error.lineno}: {error.msg}",
            how="fix the XML at that line (unclosed or mismatched tags, bad characters)",
        ) from None


@dataclass
class Joint:
    """A URDF `<joint>`: its links, `<limit>` values (None where absent) and the joint it mimics."""

    name: str
    type: str
    parent: str | None
    child: str | None
    line: int | None
    lower: float | None = None
    upper: float | None = None
    velocity: float | None = None
    effort: float | None = None
    mimic: str | None = None

    @property
    def actuated(self) -> bool:
        """Whether the driver commands it: revolute, prismatic or continuous, and not a mimic."""
        return self.type in ACTUATED_TYPES and self.mimic is None


@dataclass
class HardwareJoint:
    """A `<joint>` of a `<ros2_control>` block; `params` are its `<param name>` texts (stripped), the last of a
    name winning as in ros2_control, and `param_lines` their lines in the rendered URDF."""

    name: str
    command_interfaces: list[str]
    state_interfaces: list[str]
    line: int | None
    params: dict[str, str] = field(default_factory=dict)
    param_lines: dict[str, int | None] = field(default_factory=dict)


@dataclass
class Ros2ControlBlock:
    """A `<ros2_control>` block; `params` and `param_lines` are those of its `<hardware>`, read as a joint's are."""

    name: str
    plugin: str | None
    joints: list[HardwareJoint]
    line: int | None
    params: dict[str, str] = field(default_factory=dict)
    param_lines: dict[str, int | None] = field(default_factory=dict)


@dataclass
class UrdfModel:
    """A rendered URDF: links, joints in document order, and its ros2_control blocks."""

    name: str
    links: dict[str, int | None]
    joints: dict[str, Joint]
    ros2_control: list[Ros2ControlBlock]
    meshes: list[tuple[str, int | None]] = field(default_factory=list)

    @property
    def actuated_joints(self) -> list[Joint]:
        """Joints that count toward DOF: revolute, prismatic, continuous (fixed and mimic excluded)."""
        return [j for j in self.joints.values() if j.actuated]

    def roots(self) -> list[str]:
        """Links that are no joint's child."""
        children = {j.child for j in self.joints.values()}
        return [link for link in self.links if link not in children]

    def parent_of(self, link: str) -> Joint | None:
        """The joint whose child is `link`, or None for a root."""
        return next((j for j in self.joints.values() if j.child == link), None)

    def chain(self, base: str, tip: str) -> list[Joint] | None:
        """Joints from `base` down to `tip`, or None when `tip` does not hang below `base`."""
        joints: list[Joint] = []
        link, seen = tip, set()
        while link != base:
            if link in seen:
                return None
            seen.add(link)
            joint = self.parent_of(link)
            if joint is None or joint.parent is None:
                return None
            joints.append(joint)
            link = joint.parent
        return list(reversed(joints))


def parse_urdf(text: str, source: Path) -> UrdfModel:
    """Read a rendered URDF; XML errors and a root other than `<robot>` raise a DescriptionError naming `source`."""
    root = parse_xml(text, source)
    if root.tag != "robot":
        raise DescriptionError(
            f"{source.name} is not a URDF",
            what="a <robot> root element", why=f"{source}: the root element is <{root.tag}>",
            how="make <robot name=\"...\"> the top element",
        )
    links = {el.get("name") or "": source_line(el) for el in root.findall("link")}
    joints: dict[str, Joint] = {}
    for el in root.findall("joint"):
        limit = el.find("limit")
        parent, child, mimic = el.find("parent"), el.find("child"), el.find("mimic")
        joints[el.get("name") or ""] = Joint(
            name=el.get("name") or "", type=el.get("type") or "", line=source_line(el),
            parent=parent.get("link") if parent is not None else None,
            child=child.get("link") if child is not None else None,
            lower=_float(limit.get("lower")) if limit is not None else None,
            upper=_float(limit.get("upper")) if limit is not None else None,
            velocity=_float(limit.get("velocity")) if limit is not None else None,
            effort=_float(limit.get("effort")) if limit is not None else None,
            mimic=mimic.get("joint") if mimic is not None else None,
        )
    blocks = [_ros2_control(block) for block in root.findall("ros2_control")]
    meshes = [(mesh.get("filename") or "", source_line(mesh)) for mesh in root.iter("mesh")]
    return UrdfModel(name=root.get("name") or "", links=links, joints=joints, ros2_control=blocks, meshes=meshes)


def _ros2_control(block: etree._Element) -> Ros2ControlBlock:
    """One `<ros2_control>` block: its hardware plugin and parameters, and its joints."""
    params, param_lines = _params(block.find("hardware"))
    return Ros2ControlBlock(
        name=block.get("name") or "", line=source_line(block),
        plugin=(block.findtext("hardware/plugin") or "").strip() or None,
        joints=[HardwareJoint(j.get("name") or "", [c.get("name") or "" for c in j.findall("command_interface")],
                              [s.get("name") or "" for s in j.findall("state_interface")], source_line(j), *_params(j))
                for j in block.findall("joint")],
        params=params, param_lines=param_lines,
    )


@dataclass
class SrdfGroup:
    """An SRDF planning `<group>`: its links, joints, chains and subgroups, each with its line."""

    name: str
    line: int | None
    links: list[tuple[str, int | None]] = field(default_factory=list)
    joints: list[tuple[str, int | None]] = field(default_factory=list)
    chains: list[tuple[str, str, int | None]] = field(default_factory=list)
    subgroups: list[tuple[str, int | None]] = field(default_factory=list)


@dataclass
class GroupState:
    """An SRDF `<group_state>`: a named pose of a group, as (joint, value or None if not a number, line)."""

    name: str
    group: str
    line: int | None
    values: list[tuple[str, float | None, int | None]]


@dataclass
class SrdfModel:
    """A parsed SRDF: planning groups by name, named poses and the link pairs excluded from collision checks."""

    name: str
    groups: dict[str, SrdfGroup]
    group_states: list[GroupState]
    disabled_collisions: list[tuple[str, str, int | None]]

    def poses(self, joint_names: Sequence[str]) -> dict[str, list[float]]:
        """Named joint poses (group_state) that give a value to every one of `joint_names`, in that order."""
        poses = {}
        for state in self.group_states:
            values = {name: value for name, value, _ in state.values if value is not None}
            if all(name in values for name in joint_names):
                poses[state.name] = [values[name] for name in joint_names]
        return poses


def parse_srdf(text: str | bytes, source: Path) -> SrdfModel:
    """Read an SRDF (rendered when it was a xacro); XML errors raise a DescriptionError naming `source`."""
    root = parse_xml(text, source)
    groups: dict[str, SrdfGroup] = {}
    for el in root.findall("group"):
        group = SrdfGroup(el.get("name") or "", source_line(el))
        group.links = [(c.get("name") or "", source_line(c)) for c in el.findall("link")]
        group.joints = [(c.get("name") or "", source_line(c)) for c in el.findall("joint")]
        group.chains = [(c.get("base_link") or "", c.get("tip_link") or "", source_line(c))
                        for c in el.findall("chain")]
        group.subgroups = [(c.get("name") or "", source_line(c)) for c in el.findall("group")]
        groups[group.name] = group
    states = [
        GroupState(el.get("name") or "", el.get("group") or "", source_line(el),
                   [(j.get("name") or "", _float(j.get("value")), source_line(j)) for j in el.findall("joint")])
        for el in root.findall("group_state")
    ]
    disabled = [(el.get("link1") or "", el.get("link2") or "", source_line(el))
                for el in root.findall("disable_collisions")]
    return SrdfModel(name=root.get("name") or "", groups=groups, group_states=states, disabled_collisions=disabled)
