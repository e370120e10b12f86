"""Parsed URDF and SRDF: the names, tree and limits the checks and the runtime need."""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any, cast

from lxml import etree

from plem.core.files import read_regular, size_text
from plem.description.problems import DescriptionError
from plem.errors import PlemError

ACTUATED_TYPES = ("revolute", "prismatic", "continuous")
LESS_TESTED_TYPES = ("prismatic", "continuous")
INERTIA_KEYS = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
#: The largest XML plem parses or lets xacro read from a package, per file and per rendered document. Real
#: descriptions are far smaller (meshes live in their own files); a larger one would take minutes to process.
MAX_XML_BYTES = 16 * 2**20
#: The numeric attributes of URDF elements below a link or joint that plem, the planner and the view read, with
#: the count of numbers each holds (the ones `<limit>`, `<axis>`, `<mass>` and `<inertia>` are read on their own).
QUANTITIES = {"origin": {"xyz": 3, "rpy": 3}, "box": {"size": 3}, "cylinder": {"radius": 1, "length": 1},
              "sphere": {"radius": 1}, "capsule": {"radius": 1, "length": 1}, "mesh": {"scale": 3},
              "dynamics": {"damping": 1, "friction": 1}}
#: The tags among QUANTITIES that give a shape's size.
SHAPES = ("box", "cylinder", "sphere", "capsule")
_SUBSTITUTION = re.compile(r"\$\{[^}]*\}|\$\([^)]*\)")
_JACOBI_SWEEPS = 50
_JACOBI_NEGLIGIBLE = 1e-20  # an off-diagonal entry of the scaled matrix this small moves no eigenvalue


def _float(value: str | None) -> float | None:
    """The number an attribute holds: None when the attribute is absent, NaN when it is not a number."""
    if value is None:
        return None
    try:
        return float(value)
    except ValueError:
        return math.nan


def _floats(value: str | None) -> tuple[float, ...] | None:
    """A space-separated vector attribute (`xyz="0 0 1"`): None when absent, NaN for each part that is no number."""
    return None if value is None else tuple(cast("float", _float(part)) for part in value.split())


def source_line(element: etree._Element) -> int | None:
    """The element's line in its source, None when unknown (lxml-stubs declares `sourceline` without a type)."""
    return cast("int | None", element.sourceline)


def _params(element: etree._Element | None) -> tuple[dict[str, str], dict[str, int | None]]:
    """The `<param name="...">text</param>` children of `element` by name (the last wins) and their lines."""
    tags = element.findall("param") if element is not None else []
    return ({tag.get("name") or "": (tag.text or "").strip() for tag in tags},
            {tag.get("name") or "": source_line(tag) for tag in tags})


def too_large(path: Path, size: int, *, rendered: bool) -> DescriptionError:
    """The error for description XML above MAX_XML_BYTES: the file at `path` holds `size` bytes, or (`rendered`)
    rendering it gives that much XML."""
    limit = size_text(MAX_XML_BYTES)
    if rendered:
        return DescriptionError(
            f"{path.name} renders to too much XML",
            what=f"a rendered description of at most {limit} (plem's limit for description XML)",
            why=f"rendering {path} gives {size_text(size)} of XML",
            how="look for a macro or expression that repeats text; meshes belong in their own files, not in the XML")
    return DescriptionError(
        f"{path.name} is too large",
        what=f"description files of at most {limit} each (plem's limit for description XML)",
        why=f"{path} holds {size_text(size)}",
        how="check that it is the file you meant; meshes belong in their own files, not in the XML")


def read_xml_file(path: Path, what: str) -> bytes:
    """The bytes of a description's XML file (`what`: "URDF", "SRDF", ...), when it is a regular file of at most
    MAX_XML_BYTES; a ConfigError saying what the file is or how large otherwise."""
    return read_regular(path, MAX_XML_BYTES, what)


def parse_xml(text: str | bytes, source: Path) -> etree._Element:
    """Parse XML keeping line numbers; syntax errors name the file and line, XML above MAX_XML_BYTES is refused."""
    data = text.encode("utf-8") if isinstance(text, str) else text
    if len(data) > MAX_XML_BYTES:
        raise too_large(source, len(data), rendered=True)
    try:
        root = etree.fromstring(data, parser=etree.XMLParser(remove_comments=True, resolve_entities=False,
                                                              no_network=True, load_dtd=False))
    except etree.XMLSyntaxError as error:
        raise DescriptionError(
            f"Invalid XML in {source.name}",
            what=f"well-formed XML in {source}",
            why=f"{source}:{error.lineno}: {error.msg}",
            how="fix the XML at that line (unclosed or mismatched tags, bad characters)",
        ) from None
    info = root.getroottree().docinfo
    doctype: str = getattr(info, "doctype", "")
    if doctype:
        dtd = info.internalDTD
        entities = [entity.name for entity in cast("Any", dtd).iterentities()] if dtd is not None else []
        raise dtd_refused(source, doctype + (f" with the entities {', '.join(map(str, entities))}" if entities else ""))
    return root


def dtd_refused(source: Path | str, doctype: str) -> DescriptionError:
    """The error for a description file that declares a DTD: entities could read files or expand without end
    in whichever parser reads robot_description next, and no URDF, SRDF or xacro needs one."""
    return DescriptionError(
        f"{Path(source).name} declares a DTD",
        what="description XML without <!DOCTYPE ...> or <!ENTITY ...> declarations: URDF, SRDF and xacro use none",
        why=f"{source} declares {' '.join(doctype.split())[:200]}",
        how=f"remove the <!DOCTYPE ...> block from {source} and write the entities' text in place (or as a "
            "xacro:property)")


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
    limit_line: int | None = None
    axis: tuple[float, ...] | None = None
    axis_line: int | None = None

    @property
    def actuated(self) -> bool:
        """Whether the driver commands it: revolute, prismatic or continuous, and not a mimic."""
        return self.type in ACTUATED_TYPES and self.mimic is None


@dataclass
class Inertial:
    """A link's `<inertial>`: mass (kg) and the six inertia values about the centre of mass (kg·m², by
    INERTIA_KEYS), each None where absent and NaN where not a number, with the line of `<inertial>`."""

    mass: float | None
    inertia: dict[str, float | None]
    line: int | None

    def principal_moments(self) -> list[float] | None:
        """The eigenvalues of the inertia matrix, smallest first; None unless all six values are finite numbers."""
        values = [self.inertia.get(key) for key in INERTIA_KEYS]
        if not all(value is not None and math.isfinite(value) for value in values):
            return None
        ixx, ixy, ixz, iyy, iyz, izz = cast("list[float]", values)
        return symmetric_eigenvalues([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])


def symmetric_eigenvalues(matrix: list[list[float]]) -> list[float]:
    """The eigenvalues of a symmetric 3×3 matrix of finite numbers, smallest first, by cyclic Jacobi rotations
    (accurate to rounding, as LAPACK's; numpy would cost more to import than the whole check)."""
    scale = max(abs(value) for row in matrix for value in row)
    if scale == 0.0:
        return [0.0, 0.0, 0.0]
    a = [[value / scale for value in row] for row in matrix]  # largest entry 1: no square overflows or vanishes
    for _ in range(_JACOBI_SWEEPS):
        rotated = False
        for p, q in ((0, 1), (0, 2), (1, 2)):
            if abs(a[p][q]) <= _JACOBI_NEGLIGIBLE:
                continue
            rotated = True
            theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q])
            tangent = math.copysign(1.0, theta) / (abs(theta) + math.hypot(theta, 1.0))
            cosine = 1.0 / math.hypot(tangent, 1.0)
            sine = tangent * cosine
            for row in a:
                row[p], row[q] = cosine * row[p] - sine * row[q], sine * row[p] + cosine * row[q]
            a[p], a[q] = ([cosine * x - sine * y for x, y in zip(a[p], a[q], strict=True)],
                          [sine * x + cosine * y for x, y in zip(a[p], a[q], strict=True)])
            a[p][q] = a[q][p] = 0.0  # what the rotation is chosen to give, without the rounding
        if not rotated:
            break
    return sorted(a[index][index] * scale for index in range(3))


@dataclass(frozen=True)
class Quantity:
    """A numeric attribute of the URDF (`<origin xyz>`, `<cylinder radius>`, ...): the link or joint it is in
    (`kind` "link" or "joint", and its name), what it holds (NaN for a part that is no number) and how many numbers
    it should hold."""

    kind: str
    name: str
    tag: str
    attribute: str
    values: tuple[float, ...]
    expected: int
    line: int | None

    @property
    def written(self) -> str:
        """How messages show it: '<cylinder radius="-1">'."""
        return f'<{self.tag} {self.attribute}="{" ".join(f"{v:g}" for v in self.values)}">'


def _quantities(kind: str, element: etree._Element) -> list[Quantity]:
    """Every QUANTITIES attribute in `element` and below it, as written."""
    found = []
    for tag, attributes in QUANTITIES.items():
        for child in element.iter(tag):
            for attribute, count in attributes.items():
                values = _floats(child.get(attribute))
                if values is not None:
                    found.append(Quantity(kind, element.get("name") or "", tag, attribute, values, count,
                                          source_line(child)))
    return found


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
    """A rendered URDF: links, joints in document order, the links' inertial data and its ros2_control blocks;
    `meshes` are every mesh reference (file name, line), `collision_meshes` those of `<collision>` (link, file name)."""

    name: str
    links: dict[str, int | None]
    joints: dict[str, Joint]
    ros2_control: list[Ros2ControlBlock]
    meshes: list[tuple[str, int | None]] = field(default_factory=list)
    inertials: dict[str, Inertial] = field(default_factory=dict)
    collision_meshes: list[tuple[str, str]] = field(default_factory=list)
    quantities: list[Quantity] = field(default_factory=list)

    @property
    def actuated_joints(self) -> list[Joint]:
        """Joints that count toward DOF: revolute, prismatic, continuous (fixed and mimic excluded)."""
        return [j for j in self.joints.values() if j.actuated]

    @cached_property
    def _parent_joints(self) -> dict[str, Joint]:
        """Each link that is a joint's child, with that joint (the first in document order)."""
        parents: dict[str, Joint] = {}
        for joint in self.joints.values():
            if joint.child is not None:
                parents.setdefault(joint.child, joint)
        return parents

    def roots(self) -> list[str]:
        """Links that are no joint's child."""
        return [link for link in self.links if link not in self._parent_joints]

    def parent_of(self, link: str) -> Joint | None:
        """The joint whose child is `link`, or None for a root."""
        return self._parent_joints.get(link)

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
        limit, axis = el.find("limit"), el.find("axis")
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
            limit_line=source_line(limit) if limit is not None else None,
            axis=_floats(axis.get("xyz")) if axis is not None else None,
            axis_line=source_line(axis) if axis is not None else None,
        )
    inertials = {link.get("name") or "": _inertial(inertial) for link in root.findall("link")
                 if (inertial := link.find("inertial")) is not None}
    blocks = [_ros2_control(block) for block in root.findall("ros2_control")]
    meshes = [(mesh.get("filename") or "", source_line(mesh)) for mesh in root.iter("mesh")]
    collision_meshes = [(link.get("name") or "", mesh.get("filename") or "") for link in root.findall("link")
                        for mesh in link.findall("collision/geometry/mesh")]
    quantities = [quantity for kind in ("link", "joint") for element in root.findall(kind)
                  for quantity in _quantities(kind, element)]
    return UrdfModel(name=root.get("name") or "", links=links, joints=joints, ros2_control=blocks, meshes=meshes,
                     inertials=inertials, collision_meshes=collision_meshes, quantities=quantities)


def _inertial(element: etree._Element) -> Inertial:
    """One `<inertial>`: its `<mass value>` and `<inertia ixx=... izz=...>`."""
    mass, inertia = element.find("mass"), element.find("inertia")
    return Inertial(mass=_float(mass.get("value")) if mass is not None else None,
                    inertia={key: _float(inertia.get(key)) for key in INERTIA_KEYS} if inertia is not None else {},
                    line=source_line(element))


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


def rendered_line_note(source_line: int | None, rendered_line: int | None) -> str:
    """' (line N of the rendered URDF)' when only the rendered line of a problem is known, else ''."""
    return f" (line {rendered_line} of the rendered URDF)" if source_line is None and rendered_line else ""


def _parse_source(path: Path) -> etree._Element | None:
    """The XML of a package file, or None when it is no regular file, is too large, unreadable or broken (the
    render reports the last three)."""
    try:
        return parse_xml(read_xml_file(path, "xacro file"), path)
    except (OSError, ValueError, PlemError):
        return None


def _wildcard_match(pieces: list[str], name: str) -> bool:
    """Whether `name` is pieces[0], anything, pieces[1], ..., anything, pieces[-1] (a glob with `*` only)."""
    if len(pieces) == 1:
        return name == pieces[0]
    first, *middle, last = pieces
    end = len(name) - len(last)
    if end < len(first) or not name.startswith(first) or not name.endswith(last):
        return False
    position = len(first)
    for piece in middle:
        position = name.find(piece, position, end)
        if position < 0:
            return False
        position += len(piece)
    return True


class XacroSources:
    """Where elements of a rendered URDF are written in a package's xacro files, to point problems at a line.

    xacro drops line numbers, so a rendered element is matched back by tag and name: the source element whose
    name, with `${...}` and `$(...)` read as wildcards, is the only one to match gives the file and line.
    Otherwise (a name built by a macro from its arguments, say) the first file is named without a line.
    """

    def __init__(self, paths: Sequence[Path | None]) -> None:
        self.paths = [path for path in paths if path is not None]
        self.default = self.paths[0] if self.paths else None

    @cached_property
    def _roots(self) -> list[tuple[Path, etree._Element]]:
        """Each file that parses, with its root element."""
        return [(path, root) for path in self.paths if (root := _parse_source(path)) is not None]

    def find(self, tag: str, name: str, accept: Callable[[etree._Element], bool]
             ) -> tuple[Path | None, etree._Element | None]:
        """The file and source element of the rendered `<tag name="name">` among the elements `accept` lets
        through, or (the first file, None) when no single one matches."""
        matches = [(path, element) for path, root in self._roots for element in root.iter(tag)
                   if accept(element) and _wildcard_match(_SUBSTITUTION.split(element.get("name") or ""), name)]
        return matches[0] if len(matches) == 1 else (self.default, None)

    def place(self, tag: str, name: str, child: str) -> tuple[Path | None, int | None]:
        """File and line of the first `<child>` inside the source of the rendered `<tag name="name">` (the
        element's own line when the source has no such child, as when a macro writes it)."""
        path, element = self.find(tag, name, _is_kinematic if tag == "joint" else _any_element)
        if element is None:
            return path, None
        found = element.find(f".//{child}")
        return path, source_line(found if found is not None else element)


def _is_kinematic(element: etree._Element) -> bool:
    """A URDF `<joint type=...>`, not a `<joint>` of a ros2_control block (which has no type)."""
    return element.get("type") is not None


def _any_element(element: etree._Element) -> bool:
    """Every element qualifies."""
    return True


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
    """A parsed SRDF: planning groups by name, named poses, the link pairs excluded from collision checks and the
    joints declared passive (not actuated, so never planned for), each with its line."""

    name: str
    groups: dict[str, SrdfGroup]
    group_states: list[GroupState]
    disabled_collisions: list[tuple[str, str, int | None]]
    passive_joints: list[tuple[str, int | None]] = field(default_factory=list)

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
    passive = [(el.get("name") or "", source_line(el)) for el in root.findall("passive_joint")]
    return SrdfModel(name=root.get("name") or "", groups=groups, group_states=states, disabled_collisions=disabled,
                     passive_joints=passive)
