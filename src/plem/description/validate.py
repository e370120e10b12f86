"""Validation of a description package: every rule of the protocol, all problems reported at once.

The same checks serve three stages, as the protocol's timing table says: LAUNCH (files exist, YAML and
XML parse, the URDF renders), STARTUP (adds ros2_control tags and drive parameters, joint count and types,
joint_limits.yaml within the URDF's limits) and FULL (adds every other cross-file consistency check; what
`plem validate` runs).
"""

from __future__ import annotations

import math
import os
from bisect import bisect_left
from dataclasses import dataclass, field
from enum import IntEnum
from functools import cached_property
from pathlib import Path

from lxml import etree

from plem.core.config.yaml_document import YamlDocument
from plem.core.files import size_text
from plem.core.paths import pinned_packages, resolve_package_uri
from plem.description.compat import check_compat_version
from plem.description.discover import ROS2_CONTROL_SUFFIX, DescriptionFiles, discover
from plem.description.drives import (
    REQUIRED,
    ParamSources,
    check_drive_parameters,
    declares_drive_parameters,
    param_line,
)
from plem.description.hardware import (
    BUILTIN_PLUGIN,
    HARDWARE_ENTRY_POINTS,
    SIMULATION_PLUGINS,
    HardwareBlocks,
    is_plem_plugin,
    sort_blocks,
)
from plem.description.limits import UNITS, HardLimit, JointLimit, derivation, loosened, read_joint_limits, tighten
from plem.description.model import (
    ACTUATED_TYPES,
    LESS_TESTED_TYPES,
    SHAPES,
    Inertial,
    Joint,
    Quantity,
    SrdfModel,
    UrdfModel,
    XacroSources,
    parse_srdf,
    parse_urdf,
    parse_xml,
    read_xml_file,
    rendered_line_note,
)
from plem.description.package_yaml import read_package_yaml
from plem.description.parameter_ranges import (
    KINEMATICS_RANGES,
    SOLVER_DEFAULTS,
    kinematics_value_problem,
    update_rate_error,
)
from plem.description.problems import DescriptionError, Findings
from plem.description.render import XacroArgumentsError, render_xacro
from plem.errors import ConfigError, PlemError
from plem.ipc.request_bounds import MAX_NAME_CHARS, truncated
from plem.robot.config import SUPPORTED_DOF, ros_token_problem

KNOWN_INTERFACES = ("position", "velocity", "acceleration", "effort")
KNOWN_SOLVERS = ("kdl_kinematics_plugin/KDLKinematicsPlugin", "trac_ik_kinematics_plugin/TRAC_IKKinematicsPlugin",
                 "pick_ik/PickIkPlugin", "bio_ik/BioIKKinematicsPlugin",
                 "cached_ik_kinematics_plugin/CachedKDLKinematicsPlugin")
JOINT_TYPES = ("revolute", "prismatic", "continuous", "fixed", "floating", "planar")
PREFIX_SENTINEL = "plemprefix_"
#: A link heavier than this many times the median of the other links' masses is warned as implausible.
MASS_RATIO_WARNING = 50.0
#: An arm heavier than this (kg) in all is warned as implausible.
TOTAL_MASS_WARNING = 1000.0
#: A link whose radius of gyration (sqrt of its largest principal moment over its mass) exceeds this (m) is warned.
GYRATION_WARNING = 2.0
#: Least length of a joint axis before it counts as zero.
MIN_AXIS_NORM = 1e-9
#: Most links and joints a description may have: a 7-axis arm with its tool and sensor frames has a few dozen.
MAX_LINKS = 1000
MAX_JOINTS = 1000
#: Largest size of a shape and largest offset of an <origin> (m): an arm's parts and frames are within metres.
MAX_LENGTH_M = 100.0
#: Largest mesh file (a detailed CAD export of an arm's link is a few MiB; the view and the planner read each whole).
MAX_MESH_BYTES = 64 * 2**20
#: How messages name the limits the URDF's <limit> sets.
LIMIT_NAMES = {"min_position": "lower position", "max_position": "upper position", "max_velocity": "velocity",
               "max_effort": "effort"}


class Stage(IntEnum):
    """How far validation goes; each stage runs the checks of the ones before it."""

    LAUNCH = 1
    STARTUP = 2
    FULL = 3


@dataclass
class ValidationReport:
    """What validation found, plus the parsed pieces so launch need not parse them again."""

    files: DescriptionFiles
    findings: Findings
    stage: Stage
    urdf_xml: str | None = None
    urdf: UrdfModel | None = None
    prefixed: UrdfModel | None = None
    srdf: SrdfModel | None = None
    #: The SRDF as published on robot_description_semantic (rendered when it is a xacro).
    srdf_xml: str | None = None
    #: The limits the driver enforces: joint_limits.yaml tightened by the URDF's <limit> (see limits.tighten).
    limits: dict[str, JointLimit] = field(default_factory=dict)
    #: joint_limits.yaml as written.
    file_limits: dict[str, JointLimit] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    #: Why this robot cannot plan though it has an SRDF (a collision mesh is missing), or None.
    planning_disabled: PlemError | None = None

    @cached_property
    def urdf_sources(self) -> XacroSources:
        """Where the URDF's links and joints are written in the package's URDF xacro file."""
        return XacroSources([self.files.urdf])

    @property
    def dof(self) -> int | None:
        """The number of actuated joints, or None when the URDF did not render."""
        return len(self.urdf.actuated_joints) if self.urdf else None

    def passed(self, strict: bool = False) -> bool:
        """No errors (and, when strict, no warnings)."""
        return not self.findings.errors and not (strict and self.findings.warnings)


def validate_package(package: str | os.PathLike[str], *, stage: Stage = Stage.FULL,
                     urdf_file: str | os.PathLike[str] | None = None,
                     srdf_file: str | os.PathLike[str] | None = None) -> ValidationReport:
    """Run every check up to `stage` and collect all problems; raises only when the package is not found."""
    files = discover(package, urdf_file, srdf_file)
    with pinned_packages({files.name: files.root}):
        return _validate(files, stage)


def _validate(files: DescriptionFiles, stage: Stage) -> ValidationReport:
    report = ValidationReport(files=files, findings=files.findings, stage=stage)
    found = report.findings
    if files.name != files.root.name:
        report.notes.append(f"package.xml names this package {files.name!r}, its folder is {files.root.name!r}: "
                            f"plem finds it by {files.name!r}, as colcon does")
    check_compat_version(files.compat_version, files.root, found)
    _render_urdf(report)
    _check_limits_file(report)
    _check_srdf(report)
    if stage >= Stage.STARTUP:  # values that would stop a running component, whatever the URDF holds
        _check_controller_values(report)
        _check_kinematics_values(report)
    urdf, source = report.urdf, files.urdf
    if urdf is None or source is None:
        return report  # no URDF, or it did not render: already reported, and every later check reads it
    if stage >= Stage.STARTUP:
        _check_names(urdf, source, found)
        _check_tree(urdf, source, found)
        _check_joint_types(urdf, source, found)
        _check_urdf_values(report, urdf, source)
        _check_quantities(report, urdf, source)
        _check_ros2_control(report, urdf, source)
        _check_limits_against_urdf(report, urdf)   # a file that loosens the URDF's limits never starts a robot
        _check_meshes(report, urdf, source)        # a missing collision mesh disables planning at launch
    if stage >= Stage.FULL:
        _check_controllers(report, urdf)
        if report.srdf is not None and files.srdf is not None:
            _check_srdf_against_urdf(report, urdf, report.srdf, files.srdf)
        _check_kinematics(report)
    return report


def _render_urdf(report: ValidationReport) -> None:
    """Render once with a probe prefix; the no-argument URDF is that text with the probe replaced by the
    declared default, and the probe shows which names the prefix reaches (checked at start-up)."""
    files, found = report.files, report.findings
    if files.urdf is None:
        return
    try:
        default = _declared_prefix_default(files.urdf)
        probed = render_xacro(files.urdf, {"prefix": PREFIX_SENTINEL})
        if PREFIX_SENTINEL not in probed:
            report.urdf_xml = probed  # the prefix is unused: this is the no-argument rendering
        elif default is not None:
            report.urdf_xml = probed.replace(PREFIX_SENTINEL, default)
            report.prefixed = parse_urdf(probed, files.urdf)
        else:  # prefix used but declared elsewhere: render once more without arguments to be sure it can
            report.urdf_xml = render_xacro(files.urdf)
            report.prefixed = parse_urdf(probed, files.urdf)
        report.urdf = parse_urdf(report.urdf_xml, files.urdf)
        _check_counts(report)
    except XacroArgumentsError as error:
        found.add("urdf.xacro_args", error, files.urdf)
    except PlemError as error:
        found.add("urdf.xml" if error.summary.startswith("Invalid XML") else "urdf.render", error, files.urdf)


def _check_counts(report: ValidationReport) -> None:
    """At most MAX_LINKS links and MAX_JOINTS joints; a URDF with more is refused before any check walks it."""
    urdf, source = report.urdf, report.files.urdf
    if urdf is None or source is None:
        return
    over = [f"{len(items)} {kind}s (at most {limit})" for kind, items, limit in
            (("link", urdf.links, MAX_LINKS), ("joint", urdf.joints, MAX_JOINTS)) if len(items) > limit]
    if over:
        report.findings.error(
            "urdf.too_large", f"{source.name} has too many links or joints",
            what=f"a description of at most {MAX_LINKS} links and {MAX_JOINTS} joints (plem's limits): an arm with "
                 "its tool and sensor frames has a few dozen",
            why=f"the rendered URDF has {' and '.join(over)}",
            how=f"describe the arm alone in {source.name} (put the work cell's objects in the planning scene: "
                "`plem scene add`), or look for a macro that repeats links", file=source)
        report.urdf = report.prefixed = None


def _declared_prefix_default(urdf: Path) -> str | None:
    """The default of `<xacro:arg name="prefix">` in the top-level file, or None when it is not declared there."""
    try:
        root = parse_xml(_source_bytes(urdf), urdf)
    except PlemError:
        return None  # the render reports the XML problem
    for element in root.iter():
        if (isinstance(element.tag, str) and element.prefix == "xacro"
                and etree.QName(element).localname == "arg" and element.get("name") == "prefix"):
            return element.get("default")
    return None


def _source_bytes(path: Path) -> bytes:
    """A package file as plem reads XML (regular, at most MAX_XML_BYTES); empty when that fails, which the render
    of the same file has reported."""
    try:
        return read_xml_file(path, "xacro file")
    except PlemError:
        return b""


def _check_limits_file(report: ValidationReport) -> None:
    files = report.files
    if files.joint_limits is None:
        report.findings.error(
            "limits.missing_file", f"config/joint_limits.yaml is missing in '{files.name}'",
            what="config/joint_limits.yaml with position, velocity, acceleration (and jerk, effort) limits per joint",
            why=f"{files.root / 'config' / 'joint_limits.yaml'} does not exist",
            how="create it (see `plem create-description` for the format)", file=files.root / "config")
        return
    report.file_limits = read_joint_limits(files.joint_limits, report.findings)
    joints = report.urdf.joints if report.urdf is not None else {}
    report.limits = {name: tighten(limit, joints[name]) if name in joints else limit
                     for name, limit in report.file_limits.items()}


def _check_srdf(report: ValidationReport) -> None:
    files = report.files
    if files.srdf is None:
        report.notes.append("SRDF not found - MoveIt will not be started")
        return
    try:
        text = render_xacro(files.srdf) if files.srdf.name.endswith(".xacro") else read_xml_file(files.srdf, "SRDF")
        report.srdf = parse_srdf(text, files.srdf)
        report.srdf_xml = text if isinstance(text, str) else text.decode("utf-8", errors="replace")
    except PlemError as error:
        report.findings.add("srdf.xml", error, files.srdf)


def _check_tree(urdf: UrdfModel, source: Path, found: Findings) -> None:
    """Every element named, one root, every joint's links exist, each link has one parent at most, no cycles."""
    for kind, names in (("link", urdf.links), ("joint", urdf.joints)):
        if "" in names:
            found.error("urdf.name_missing", f"A <{kind}> has no name", what=f'every <{kind}> with a name="..."',
                        why=f"the rendered URDF has a <{kind}> without a name", how="add the missing name",
                        file=source)
    for joint in urdf.joints.values():
        for role, link in (("parent", joint.parent), ("child", joint.child)):
            if link not in urdf.links:
                found.error("urdf.joint_link_missing", f"Joint {joint.name} names a missing {role} link",
                            what=f"the {role} link of {joint.name} defined as a <link>",
                            why=f"{role} link {link!r} does not exist",
                            how=f"add <link name=\"{link}\"/> or fix the name", file=source)
    parents: dict[str, list[str]] = {}
    for joint in urdf.joints.values():
        parents.setdefault(joint.child or "", []).append(joint.name)
    for child, joints in parents.items():
        if len(joints) > 1:
            found.error("urdf.tree.multiple_parents", f"Link {child} has {len(joints)} parent joints",
                        what="a tree: every link is the child of at most one joint",
                        why=f"{child} is the child of {', '.join(joints)}", how="remove or re-parent the extra joints",
                        file=source)
    roots = urdf.roots()
    if len(roots) != 1 and urdf.links:
        found.error("urdf.tree.roots", f"The URDF has {len(roots)} root links",
                    what="exactly one root link (a single kinematic tree)",
                    why=f"root links: {', '.join(roots) or 'none (the joints form a cycle)'}",
                    how="connect every part to the base with a joint", file=source)
    cycle = _cycle(urdf)
    if cycle is not None:
        found.error("urdf.tree.cycle", "The URDF joints form a cycle",
                    what="a tree with no closed loops", why=f"following parents from {cycle[0]} returns to {cycle[1]}",
                    how="break the loop (URDF cannot describe closed chains)", file=source)


def _cycle(urdf: UrdfModel) -> tuple[str, str] | None:
    """(a link, the link its parents lead back to) for the first link in document order whose parents loop, or
    None; each link is walked once, so a URDF of any size takes time in proportion to it."""
    finished: set[str] = set()
    for link in urdf.links:
        walk: dict[str, None] = {}
        current: str | None = link
        while current is not None and current not in finished and current not in walk:
            walk[current] = None
            up = urdf.parent_of(current)
            current = up.parent if up is not None else None
        finished.update(walk)
        if current is not None and current in walk:
            return link, current
    return None


def _name_problem(name: str) -> str | None:
    """Why a link or joint name cannot be used as a tf frame or in a message, or None: 1 to MAX_NAME_CHARS
    printable characters without spaces (no control, format or bidirectional-override characters)."""
    if not 0 < len(name) <= MAX_NAME_CHARS:
        return f"it has {len(name)} characters; at most {MAX_NAME_CHARS} are allowed" if name else None
    if not name.isprintable() or any(character.isspace() for character in name):
        return "it holds spaces or invisible characters (control, format or bidirectional ones)"
    return None


def _check_names(urdf: UrdfModel, source: Path, found: Findings) -> None:
    """Link and joint names fit tf frames and messages; the names of actuated joints, which every trajectory,
    controller and ros2_control interface carries, are ROS 2 name tokens."""
    actuated = {joint.name for joint in urdf.actuated_joints}
    actuated |= {hw.name for block in urdf.ros2_control for hw in block.joints}
    for kind, names in (("link", urdf.links), ("joint", urdf.joints)):
        for name in names:
            if not name:
                continue  # urdf.name_missing
            if kind == "joint" and name in actuated:
                problem = ros_token_problem(name, MAX_NAME_CHARS)
                rule = (f"actuated joint names as ROS 2 name tokens of at most {MAX_NAME_CHARS} characters: "
                        "letters, digits and single underscores, not starting with a digit")
            else:
                problem, rule = _name_problem(name), (f"{kind} names of 1 to {MAX_NAME_CHARS} printable characters "
                                                      "without spaces")
            if problem is not None:
                shown = truncated(ascii(name), 80)
                found.error("urdf.name", f"The URDF has an unusable {kind} name",
                            what=rule + " (trajectories, tf and ROS 2 tools carry them)",
                            why=f"{kind} {shown}: {problem}",
                            how=f"rename the {kind} in {source.name} (and wherever the package names it)",
                            file=source)


def _check_joint_types(urdf: UrdfModel, source: Path, found: Findings) -> None:
    for joint in urdf.joints.values():
        if joint.type not in JOINT_TYPES:
            found.error("urdf.joint_type", f"Joint {joint.name} has unknown type {joint.type!r}",
                        what=f"one of {', '.join(JOINT_TYPES)}", why=f"type is {joint.type!r}",
                        how="use revolute, prismatic, continuous or fixed", file=source)
        elif joint.type in ("floating", "planar"):
            found.error("urdf.joint_type", f"Joint {joint.name} is {joint.type}",
                        what="actuated joints of type revolute, prismatic or continuous (fixed joints are ignored)",
                        why=f"{joint.name} is a {joint.type} joint, which a serial arm driver cannot actuate",
                        how="model it as fixed, or as revolute/prismatic joints", file=source)
        elif joint.type in LESS_TESTED_TYPES:
            found.warning("joint.less_tested", f"Joint {joint.name} is {joint.type}",
                          what="revolute joints, which the RT driver is tuned for",
                          why=f"{joint.name} is {joint.type}: supported but less tested",
                          how="test motions of this joint carefully before production use", file=source)
        if joint.type in ("revolute", "prismatic") and joint.mimic is None and (
                joint.lower is None or joint.upper is None or joint.velocity is None):
            found.error("urdf.limit_missing", f"Joint {joint.name} has no complete <limit>",
                        what=f"<limit lower upper velocity effort> on every {joint.type} joint",
                        why=f"{joint.name} lacks " + ", ".join(
                            n for n, v in (("lower", joint.lower), ("upper", joint.upper), ("velocity", joint.velocity))
                            if v is None), how="add the missing attributes to its <limit>", file=source)
    dof = len(urdf.actuated_joints)
    if dof not in SUPPORTED_DOF:
        found.error("dof.unsupported", f"The arm has {dof} actuated joints",
                    what=f"{' or '.join(map(str, SUPPORTED_DOF))} actuated joints (revolute, prismatic, continuous)",
                    why=f"counted {dof}: {', '.join(j.name for j in urdf.actuated_joints) or 'none'}",
                    how="describe a 6- or 7-axis arm; other joint counts are outside plem's supported set",
                    file=source)


def _urdf_place(report: ValidationReport, tag: str, name: str, child: str,
                rendered_line: int | None) -> tuple[Path | None, int | None, str]:
    """Where `<child>` of the URDF's `<tag name>` is written: file, line (None when a macro hides it) and the note
    naming the rendered URDF's line in that case."""
    path, line = report.urdf_sources.place(tag, name, child)
    return path, line, rendered_line_note(line, rendered_line)


def _check_urdf_values(report: ValidationReport, urdf: UrdfModel, source: Path) -> None:
    """The numbers the driver and the dynamics rely on: joint limits finite (velocity and effort positive, lower
    below upper), axes not zero, masses and inertias physical; masses far out of proportion are warned."""
    found = report.findings
    for joint in urdf.joints.values():
        if joint.type not in ACTUATED_TYPES:
            continue
        bad = _bad_limit_values(joint)
        if bad:
            path, line, note = _urdf_place(report, "joint", joint.name, "limit", joint.limit_line)
            found.error("urdf.limit_value", f"Joint {joint.name} has an invalid <limit>",
                        what="finite <limit> values, lower below upper and velocity and effort above 0: the driver "
                             "enforces them as hard limits",
                        why="; ".join(bad) + note,
                        how="write the joint's real limits into its <limit> (rad or m, rad/s or m/s, N·m or N)",
                        file=path or source, line=line)
        axis = joint.axis
        if axis is not None and (len(axis) != 3 or not all(map(math.isfinite, axis))
                                 or not math.hypot(*axis) > MIN_AXIS_NORM):
            path, line, note = _urdf_place(report, "joint", joint.name, "axis", joint.axis_line)
            found.error("urdf.axis", f"Joint {joint.name} has no usable axis",
                        what="<axis xyz> with three finite numbers, not all zero: the direction the joint turns "
                             "about or slides along",
                        why=f'<axis xyz="{" ".join(f"{v:g}" for v in axis)}"> of {joint.name}' + note,
                        how='give the direction in the joint frame, e.g. <axis xyz="0 0 1"/>',
                        file=path or source, line=line)
    for link, inertial in urdf.inertials.items():
        bad = _bad_inertial(urdf, link, inertial)
        if bad:
            path, line, note = _urdf_place(report, "link", link, "inertial", inertial.line)
            found.error("urdf.inertial", f"Link {link} has invalid inertial data",
                        what="a finite mass above 0 kg (0 only for a massless frame fixed to another link, with zero "
                             "inertia) and a finite, positive semi-definite inertia: the dynamics run on them",
                        why="; ".join(bad) + note,
                        how="enter the link's mass (kg) and inertia about its centre of mass (kg·m²) from its CAD "
                            "model or data sheet", file=path or source, line=line)
    _check_masses_plausible(report, urdf, source)


def _check_quantities(report: ValidationReport, urdf: UrdfModel, source: Path) -> None:
    """Every <origin>, shape, mesh scale and <dynamics> number finite and of the count its attribute takes; shape
    sizes above 0 and offsets and sizes at most MAX_LENGTH_M (the planner and the view build geometry from them).
    One problem per value, naming every link or joint holding it (a macro repeats a value in many)."""
    bad: dict[tuple[str, str, str], list[Quantity]] = {}
    for quantity in urdf.quantities:
        problem = _quantity_problem(quantity)
        if problem is not None:
            bad.setdefault((quantity.written, quantity.attribute, problem), []).append(quantity)
    for (written, attribute, problem), quantities in bad.items():
        first = quantities[0]
        path, line, _ = _urdf_place(report, first.kind, first.name, first.tag, None)
        owners = ", ".join(f"{q.kind} {truncated(ascii(q.name), 60)}" for q in quantities[:10])
        more = f" and {len(quantities) - 10} more" if len(quantities) > 10 else ""
        report.findings.error(
            "urdf.value", f"The URDF has an unusable <{first.tag} {attribute}>",
            what=f"<{first.tag} {attribute}> with {first.expected} finite number{'s' if first.expected > 1 else ''}; "
                 f"shape sizes above 0 and sizes and offsets at most {MAX_LENGTH_M:g} m",
            why=f"{truncated(written, 200)} in {owners}{more}: {problem}",
            how=f"write the real value (metres, radians) in {(path or source).name}", file=path or source, line=line)


def _quantity_problem(quantity: Quantity) -> str | None:
    """What is wrong with one URDF number, or None."""
    values = quantity.values
    if len(values) != quantity.expected:
        return f"it holds {len(values)} numbers, not {quantity.expected}"
    if not all(map(math.isfinite, values)):
        return "it is not finite (nan, inf or beyond ±1.8e308)"
    if quantity.tag in SHAPES and not all(0.0 < value <= MAX_LENGTH_M for value in values):
        return f"a size must be above 0 and at most {MAX_LENGTH_M:g} m"
    if quantity.attribute == "xyz" and not all(abs(value) <= MAX_LENGTH_M for value in values):
        return f"an offset must be at most {MAX_LENGTH_M:g} m in each direction"
    if quantity.tag == "mesh" and not all(0.0 < abs(value) <= MAX_LENGTH_M for value in values):
        return f"a scale must be non-zero and at most {MAX_LENGTH_M:g} in size"
    return None


def _bad_limit_values(joint: Joint) -> list[str]:
    """What is wrong with the numbers of a joint's `<limit>` (position bounds are ignored on continuous joints)."""
    names = ("velocity", "effort") if joint.type == "continuous" else ("lower", "upper", "velocity", "effort")
    bad = []
    for name in names:
        value: float | None = getattr(joint, name)
        if value is None:
            continue
        if not math.isfinite(value):
            bad.append(f'{name}="{value:g}" is not a finite number')
        elif name in ("velocity", "effort") and value <= 0:
            bad.append(f'{name}="{value:g}" is not above 0')
    lower, upper = joint.lower, joint.upper
    if "lower" in names and lower is not None and upper is not None and lower >= upper:
        bad.append(f'lower="{lower:g}" is not below upper="{upper:g}"')
    return bad


def _bad_inertial(urdf: UrdfModel, link: str, inertial: Inertial) -> list[str]:
    """What is wrong with a link's mass and inertia."""
    bad = []
    mass, inertia = inertial.mass, inertial.inertia
    bad += [f"<inertia> lacks {key}" for key, value in inertia.items() if value is None]
    bad += [f'{key}="{value:g}" is not a finite number' for key, value in inertia.items()
            if value is not None and not math.isfinite(value)]
    moments = inertial.principal_moments()
    if moments is not None and moments[0] < -1e-9 * max(1.0, sum(moments)):
        negative = [f"{key}={inertia[key]:g}" for key in ("ixx", "iyy", "izz") if (inertia[key] or 0.0) < 0]
        bad.append("the inertia is not positive semi-definite (" + (
            f"negative diagonal {', '.join(negative)}" if negative else f"smallest principal moment {moments[0]:.3g}")
            + ")")
    parent = urdf.parent_of(link)
    if mass is None:
        bad.append("its <inertial> has no <mass value>")
    elif not math.isfinite(mass) or mass < 0:
        bad.append(f'mass value="{mass:g}" is not a finite number of 0 kg or more')
    elif mass == 0 and parent is not None and parent.type in ACTUATED_TYPES:
        bad.append(f"mass is 0 kg, yet joint {parent.name} moves it")
    elif mass == 0 and any(inertia.values()):
        bad.append("mass is 0 kg with a non-zero inertia")
    return bad


def _median_without(ordered: list[float], value: float) -> float:
    """The median of sorted `ordered` with one `value` (which it holds) left out, in constant time."""
    skip = bisect_left(ordered, value)

    def other(index: int) -> float:
        return ordered[index if index < skip else index + 1]

    count = len(ordered) - 1
    middle = count // 2
    return other(middle) if count % 2 else (other(middle - 1) + other(middle)) / 2


def _check_masses_plausible(report: ValidationReport, urdf: UrdfModel, source: Path) -> None:
    """Warn about a total mass or a link mass far beyond what an arm weighs, and an inertia too large for its
    mass: usually a unit slip (g for kg) or a typo."""
    found = report.findings
    masses = {link: inertial.mass for link, inertial in urdf.inertials.items()
              if inertial.mass is not None and math.isfinite(inertial.mass) and inertial.mass > 0}
    total = sum(masses.values())
    if total > TOTAL_MASS_WARNING:
        heaviest = sorted(masses, key=lambda link: -masses[link])[:3]
        found.warning("urdf.inertial_implausible", f"The arm weighs {total:g} kg",
                      what=f"link masses that add up to what an arm weighs (warned above {TOTAL_MASS_WARNING:g} kg)",
                      why=f"the masses add up to {total:g} kg; heaviest: "
                          + ", ".join(f"{link} {masses[link]:g} kg" for link in heaviest),
                      how="check the values and their unit (kg)", file=source)
    ordered = sorted(masses.values())
    for link, mass in masses.items():
        typical = _median_without(ordered, mass) if len(ordered) >= 3 else None
        if typical is not None and mass > MASS_RATIO_WARNING * typical:
            path, line, note = _urdf_place(report, "link", link, "inertial", urdf.inertials[link].line)
            found.warning("urdf.inertial_implausible", f"Link {link} weighs {mass:g} kg",
                          what=f"link masses in proportion (warned above {MASS_RATIO_WARNING:g} times the median of "
                               "the other links)",
                          why=f"{link} has {mass:g} kg, {mass / typical:.0f} times the median {typical:g} kg of the "
                              "other links" + note,
                          how="check the value and its unit (kg)", file=path or source, line=line)
        moments = urdf.inertials[link].principal_moments()
        if moments is not None:
            gyration = math.sqrt(max(moments[-1], 0.0) / mass)
            if gyration > GYRATION_WARNING:
                path, line, note = _urdf_place(report, "link", link, "inertial", urdf.inertials[link].line)
                found.warning("urdf.inertial_implausible", f"Link {link} has an inertia too large for its mass",
                              what=f"an inertia that fits the link's size (radius of gyration, √(I/m), up to "
                                   f"{GYRATION_WARNING:g} m)",
                              why=f"{link}: {mass:g} kg with a largest principal moment of "
                                  f"{gyration ** 2 * mass:g} kg·m², a radius of gyration of {gyration:.3g} m" + note,
                              how="check the inertia values and their unit (kg·m², about the centre of mass)",
                              file=path or source, line=line)


def _check_ros2_control(report: ValidationReport, urdf: UrdfModel, source: Path) -> None:
    files, found = report.files, report.findings
    if not urdf.ros2_control:
        found.error("ros2_control.missing", "No <ros2_control> tag in the URDF",
                    what="a <ros2_control> block declaring the hardware plugin and every actuated joint",
                    why=f"the rendered {source.name} has none" + (
                        f"; {files.ros2_control.name} exists but is not included or its macro is not called"
                        if files.ros2_control else ""),
                    how="include the macro and call it in the URDF:\n"
                        f'<xacro:include filename="$(find {files.name})/urdf/NAME{ROS2_CONTROL_SUFFIX}"/>\n'
                        '<xacro:NAME_ros2_control prefix="$(arg prefix)"/>', file=source)
        return
    declared: dict[str, object] = {}
    blocks = sort_blocks(urdf.ros2_control)
    _check_blocks(report, blocks, source)
    for block in blocks.driven:
        for hw in block.joints:
            declared[hw.name] = hw
            if hw.name not in urdf.joints:
                found.error("ros2_control.unknown_joint", f"<ros2_control> declares unknown joint {hw.name}",
                            what="joints in <ros2_control> that exist in the URDF", why=f"no URDF joint {hw.name!r}",
                            how="fix the joint name (check the prefix)", file=source)
            if not hw.command_interfaces or "position" not in hw.state_interfaces:
                found.error("ros2_control.interfaces", f"Joint {hw.name} lacks interfaces in <ros2_control>",
                            what="at least one command_interface and a position state_interface per joint",
                            why=f"command: {hw.command_interfaces or 'none'}, state: {hw.state_interfaces or 'none'}",
                            how='add <command_interface name="position"/> and <state_interface name="position"/>',
                            file=source)
            unknown = [i for i in hw.command_interfaces + hw.state_interfaces if i not in KNOWN_INTERFACES]
            if unknown:
                found.warning("ros2_control.unknown_interface", f"Joint {hw.name} has unknown interfaces",
                              what=f"interfaces among {', '.join(KNOWN_INTERFACES)}", why=f"found {', '.join(unknown)}",
                              how="remove them or fix their names; plem ignores them", file=source)
    for joint in urdf.actuated_joints:
        if joint.name not in declared:
            found.error("ros2_control.joint_missing", f"Actuated joint {joint.name} is not in <ros2_control>",
                        what="every actuated joint declared in <ros2_control> with its interfaces",
                        why=f"{joint.name} ({joint.type}) is missing", how=f'add <joint name="{joint.name}"> with '
                                                                           "command and state interfaces", file=source)
    _check_drive_parameters(report, urdf, [joint.name for joint in urdf.actuated_joints if joint.name in declared])
    _check_prefix(report, source)


def _check_blocks(report: ValidationReport, blocks: HardwareBlocks, source: Path) -> None:
    """Exactly one ros2_control block plem drives (see plem.description.hardware); the others are warned as ignored."""
    found, driven = report.findings, blocks.driven
    plugins = ", ".join(f"{block.name!r} ({block.plugin})" for block in driven)
    if not blocks.simulated and not is_plem_plugin(driven[0].plugin):
        for block in driven:
            found.error("ros2_control.plugin", f"Unknown hardware plugin in <ros2_control name=\"{block.name}\">",
                        what=f"a <ros2_control> block with <plugin>{BUILTIN_PLUGIN}</plugin> or a plugin registered "
                             f"under the '{HARDWARE_ENTRY_POINTS}' entry-point group (or, to run on plem's simulated "
                             f"arm, {' or '.join(SIMULATION_PLUGINS)})",
                        why=f"plugin is {block.plugin!r}",
                        how=f"use {BUILTIN_PLUGIN}, or add a block of your own with it beside the upstream one (plem "
                            f"ignores the other), or install the package that provides {block.plugin!r} as a "
                            f"{HARDWARE_ENTRY_POINTS} entry point", file=source)
        return
    if len(driven) > 1:
        found.error("ros2_control.several_blocks", f"{len(driven)} <ros2_control> blocks for plem to drive",
                    what="exactly one <ros2_control> block naming plem's plugin (or, without one, one simulation "
                         "block)",
                    why=f"found {plugins}", how="keep one of them in the URDF plem renders", file=source)
    if blocks.simulated:
        found.warning("ros2_control.simulated",
                      f"<ros2_control name=\"{driven[0].name}\"> runs on plem's simulated arm",
                      what=f"a <ros2_control> block with <plugin>{BUILTIN_PLUGIN}</plugin> to drive the arm's hardware",
                      why=f"its plugin is {driven[0].plugin}, ros2_control's simulation plugin, and no block names "
                          "plem's",
                      how="launch with bus:=mock (the default); to drive the hardware, add a block with "
                          f"<plugin>{BUILTIN_PLUGIN}</plugin> and drive parameters", file=source)
    for block in blocks.ignored:
        found.warning("ros2_control.ignored_block", f"<ros2_control name=\"{block.name}\"> is ignored",
                      what="one <ros2_control> block plem drives; other blocks (an upstream macro's own driver) are "
                           "left out",
                      why=f"its plugin is {block.plugin!r}; plem drives {plugins}",
                      how="nothing, if this is the upstream macro's block; to silence this, keep it out of the URDF "
                          "(often an argument of the upstream macro)", file=source)


def _check_drive_parameters(report: ValidationReport, urdf: UrdfModel, joints: list[str]) -> None:
    """The drive parameters of the actuated joints in <ros2_control>: well-formed and complete, or none at all
    (a warning, since only bus:=ethercat needs them)."""
    files, found = report.files, report.findings
    sources = ParamSources((files.ros2_control, files.urdf))
    if not declares_drive_parameters(urdf):
        found.warning("drive.none", "No drive parameters in <ros2_control>",
                      what=f"{', '.join(REQUIRED)} as <param> tags of every <joint> in <ros2_control>",
                      why="no joint declares them: bus:=ethercat needs them to turn encoder counts into joint angles, "
                          "bus:=mock uses the model preset's encoder resolution and gearing (or plem's default)",
                      how="add to each <joint> of the ros2_control block, with the values of its drive:\n"
                          + "\n".join(param_line(name) for name in REQUIRED), file=sources.default)
    for problem in check_drive_parameters(urdf, joints):
        path, line = sources.locate(problem.joint, problem.param)
        record = found.error if problem.error else found.warning
        record(problem.code, problem.summary, what=problem.what, why=problem.why_at(line), how=problem.how,
               file=path, line=line)


def _check_prefix(report: ValidationReport, source: Path) -> None:
    """Rendering with prefix:=PROBE should rename every link, joint and ros2_control joint.

    Names that ignore it are a warning (an error under --strict): plem keeps robots apart by their namespace
    and tf prefix, so the prefix matters only when one URDF is to hold several arms, and a third-party arm
    wrapped as the protocol shows (`prefix=""` passed to its macro) must still validate.
    """
    files, found, prefixed = report.files, report.findings, report.prefixed
    if prefixed is None:
        found.warning("ros2_control.prefix", "The URDF ignores the prefix argument",
                      what="<xacro:arg name=\"prefix\" default=\"\"/> applied to every link and joint name and "
                           "passed to the ros2_control macro, so one URDF can hold several arms",
                      why=f"rendering {source.name} with prefix:={PREFIX_SENTINEL} changes no name",
                      how='declare <xacro:arg name="prefix" default=""/>, write names as $(arg prefix)NAME and pass '
                          'prefix="$(arg prefix)" to the ros2_control macro; without it this arm cannot share one '
                          "URDF with another (separate robots are kept apart by robot_id anyway)", file=source)
        return
    names = [*prefixed.links, *prefixed.joints]
    unchanged = [name for name in names if not name.startswith(PREFIX_SENTINEL)]
    if unchanged:
        found.warning("urdf.prefix", "Some link or joint names ignore the prefix argument",
                      what="every link and joint name written as $(arg prefix)NAME",
                      why=f"with prefix:={PREFIX_SENTINEL} these stay unchanged: {', '.join(unchanged)}",
                      how="prefix those names too, or two arms rendered into one URDF with different prefixes "
                          "will clash", file=source)
    hardware = [hw.name for block in sort_blocks(prefixed.ros2_control).driven for hw in block.joints]
    unchanged = [name for name in hardware if not name.startswith(PREFIX_SENTINEL)]
    if unchanged:
        found.warning("ros2_control.prefix", "The ros2_control macro ignores its prefix for some joints",
                      what="a macro with params=\"prefix:=''\" writing every joint as ${prefix}NAME",
                      why=f"with prefix:={PREFIX_SENTINEL} these stay unchanged: {', '.join(unchanged)}",
                      how="write the joint names as ${prefix}joint1 and so on, and call the macro with "
                          'prefix="$(arg prefix)"', file=files.ros2_control or source)
    if files.ros2_control and files.ros2_control.name.encode() not in _source_bytes(source):
        found.error("ros2_control.not_included", f"{files.ros2_control.name} is not included by the URDF",
                    what="the URDF includes its ros2_control xacro", why=f"{source.name} never names it",
                    how=f'<xacro:include filename="$(find {files.name})/urdf/{files.ros2_control.name}"/>',
                    file=source)


def _check_limits_against_urdf(report: ValidationReport, urdf: UrdfModel) -> None:
    files, found, limits = report.files, report.findings, report.file_limits
    if files.joint_limits is None or not limits and found.codes().count("limits.yaml"):
        return
    path = files.joint_limits
    actuated = {j.name: j for j in urdf.actuated_joints}
    for name, joint in actuated.items():
        if name not in limits:
            found.error("limits.missing_joint", f"joint_limits.yaml has no entry for {name}",
                        what="an entry for every actuated URDF joint", why=f"{name} is missing",
                        how=f"add joint_limits.{name} with min/max_position, max_velocity, max_acceleration",
                        file=path, line=read_package_yaml(path, "joint_limits.yaml").line("joint_limits"))
            continue
        _compare_with_urdf(report, limits[name], joint, path)
    for name, limit in limits.items():
        if name not in actuated:
            found.error("limits.extra_joint", f"joint_limits.yaml names {name}, which is not an actuated joint",
                        what="entries only for the URDF's actuated joints",
                        why=f"{name} is " + ("a fixed or mimic joint" if name in urdf.joints else "not in the URDF"),
                        how=f"remove joint_limits.{name} or fix the name", file=path, line=limit.line)


def _compare_with_urdf(report: ValidationReport, limit: JointLimit, joint: Joint, path: Path) -> None:
    """joint_limits.yaml may tighten the URDF's <limit>, never loosen or remove it (an error, although the driver
    enforces the URDF's value anyway); missing velocity, acceleration or jerk limits are warned."""
    found = report.findings
    changes = loosened(limit, joint)
    at = _limit_at(report, joint) if changes else ""
    for hard, own, urdf_value in changes:
        if own is None:
            _report_removed(found, joint, hard, at, path, limit.line_of(hard.flag))
            continue
        beyond, bound = ("below", "at least") if hard.from_below else ("above", "at most")
        found.error("limits.exceeds_urdf", f"joint_limits.yaml loosens the {LIMIT_NAMES[hard.key]} limit of "
                                           f"{joint.name}",
                    what="joint_limits.yaml within the URDF's <limit>: it may tighten a limit, never loosen it",
                    why=f"{hard.key} {own:g} is {beyond} the URDF's {hard.attribute}=\"{urdf_value:g}\" ({at})",
                    how=f"set joint_limits.{joint.name}.{hard.key} to {bound} {urdf_value:g}, or correct the URDF "
                        f"<limit> if the joint really allows more; the driver enforces {urdf_value:g} either way",
                    file=path, line=limit.line_of(hard.key))
    enforced = tighten(limit, joint)
    missing = [k for k in ("max_velocity", "max_acceleration", "max_jerk")
               if getattr(enforced, k) is None or k in enforced.derived]
    if missing:
        derived = "; ".join(f"{k} {getattr(enforced, k):.4g} {UNITS[k]} ({derivation(k)})"
                            for k in missing if k in enforced.derived)
        found.warning("limits.incomplete", f"{joint.name} has no {', '.join(missing)}",
                      what="velocity, acceleration and jerk limits for jerk-limited motion",
                      why=f"joint_limits.{joint.name} lacks {', '.join(missing)}",
                      how=f"add {', '.join(missing)} to joint_limits.{joint.name}"
                          + (f"; until then the driver and the planner enforce {derived}" if derived
                                        else ""), file=path, line=limit.line)


def _limit_at(report: ValidationReport, joint: Joint) -> str:
    """Where the joint's URDF <limit> is written, as `file:line` (or the file and the rendered URDF's line)."""
    path, line, note = _urdf_place(report, "joint", joint.name, "limit", joint.limit_line)
    return f"{path}:{line}" if line else f"{path}{note}"


def _report_removed(found: Findings, joint: Joint, hard: HardLimit, at: str, path: Path, line: int | None) -> None:
    """A has_*_limits: false that would switch off a limit the URDF sets."""
    kind = "position" if hard.flag == "has_position_limits" else LIMIT_NAMES[hard.key]
    urdf = (f'lower="{joint.lower:g}" upper="{joint.upper:g}"' if kind == "position"
            else f'{hard.attribute}="{getattr(joint, hard.attribute):g}"')
    found.error("limits.removes_urdf", f"joint_limits.yaml removes the {kind} limit of {joint.name}",
                what="joint_limits.yaml within the URDF's <limit>: it may tighten a limit, never remove it",
                why=f"{hard.flag}: false, while the URDF's <limit> sets {urdf} ({at})",
                how=f"set {hard.flag}: true with values within the URDF's (or leave them out to use the URDF's); the "
                    "driver enforces the URDF's limit either way", file=path, line=line)


def _check_meshes(report: ValidationReport, urdf: UrdfModel, source: Path) -> None:
    """Missing meshes are warnings: a visual one only leaves a part out of the view; a collision one disables
    planning for the robot (the planner checks collisions with it), and the rest of the robot runs."""
    found, missing = report.findings, {}
    for uri in dict.fromkeys(uri for uri, _ in urdf.meshes):
        try:
            path = resolve_package_uri(uri, base=source.parent)
        except PlemError as error:
            missing[uri] = error
            continue
        size = _file_size(path)
        if size > MAX_MESH_BYTES:
            found.error("urdf.mesh_too_large", f"Mesh {path.name} is too large",
                        what=f"mesh files of at most {size_text(MAX_MESH_BYTES)} (plem's limit): the view and the "
                             "planner read each one whole",
                        why=f"{uri} ({path}) holds {size_text(size)}",
                        how="export the mesh with fewer triangles (a decimated copy for <collision> is usual)",
                        file=source)
    colliding = [(link, uri) for link, uri in urdf.collision_meshes if uri in missing]
    for uri, problem in missing.items():
        if all(uri != used for _, used in colliding):
            found.warning("urdf.mesh_missing", problem.summary, what=f"{problem.what} (a visual mesh: the view "
                          "leaves the part out)", why=problem.why, how=problem.how, file=source)
    if colliding:
        disabled = report.planning_disabled = PlemError(
            f"Planning is disabled: {len(colliding)} collision mesh{'es' if len(colliding) > 1 else ''} not found",
            what="every <collision> mesh of the URDF as a file: the planner checks collisions with them",
            why="; ".join(f"link {link}: {missing[uri].why}" for link, uri in colliding),
            how="add the files, fix their names, or add the folder of the package holding them to PLEM_PACKAGE_PATH; "
                "until then the arm runs without the planner (as without an SRDF)")
        found.warning("urdf.collision_mesh_missing", disabled.summary, what=disabled.what, why=disabled.why,
                      how=disabled.how, file=source)


def _file_size(path: Path) -> int:
    """The size of a file in bytes; 0 when it cannot be read (a missing mesh is reported as missing)."""
    try:
        return path.stat().st_size
    except (OSError, ValueError):
        return 0


def _read_mapping(path: Path | None, area: str, found: Findings) -> YamlDocument | None:
    """An optional YAML config file whose top level must be a mapping; problems are recorded under `area`."""
    if path is None:
        return None
    try:
        document = read_package_yaml(path, f"{area}.yaml")
    except ConfigError as error:
        found.add(f"{area}.yaml", error, path)
        return None
    if not isinstance(document.root, dict):
        found.error(f"{area}.structure", f"{area}.yaml is not a mapping", what="names as top-level keys",
                    why=f"the file holds {type(document.root).__name__}", how="see the protocol's example",
                    file=path, line=1)
        return None
    return document


def _check_controllers(report: ValidationReport, urdf: UrdfModel) -> None:
    path, found = report.files.controllers, report.findings
    document = _read_mapping(path, "controllers", found)
    if document is None:
        return
    for controller, body in document.root.items():
        params = body.get("ros__parameters") if isinstance(body, dict) else None
        joints = params.get("joints") if isinstance(params, dict) else None
        if not isinstance(joints, list):
            continue
        for index, joint in enumerate(joints):
            if not isinstance(joint, str) or joint not in urdf.joints:
                found.error("controllers.unknown_joint", f"Controller {controller} names unknown joint {joint}",
                            what="controller joints that exist in the URDF", why=f"{joint!r} is not a URDF joint",
                            how="fix the name or remove it", file=path,
                            line=document.line(controller, "ros__parameters", "joints", index))


def _check_controller_values(report: ValidationReport) -> None:
    """controllers.yaml's controller names are ROS 2 node names and its update_rate a rate the loop can run."""
    path, found = report.files.controllers, report.findings
    document = _read_mapping(path, "controllers", Findings())  # unreadable: _check_controllers or the launch says
    if document is None or path is None:
        return
    for name, body in document.root.items():
        params = body.get("ros__parameters") if isinstance(body, dict) else None
        declared = [str(name)]
        if name == "controller_manager" and isinstance(params, dict):
            declared += [str(key) for key, value in params.items() if isinstance(value, dict) and "type" in value]
            rate = update_rate_error(params["update_rate"]) if "update_rate" in params else None
            if rate is not None:
                found.error("controllers.update_rate", rate.summary, what=rate.what, why=rate.why, how=rate.how,
                            file=path, line=document.line(name, "ros__parameters", "update_rate"))
        for controller in declared:
            problem = ros_token_problem(controller, MAX_NAME_CHARS)
            if problem is not None:
                found.error("controllers.name", "controllers.yaml has an unusable controller name",
                            what=f"controller names as ROS 2 node names of at most {MAX_NAME_CHARS} characters: "
                                 "letters, digits and single underscores, not starting with a digit",
                            why=f"{truncated(ascii(controller), 80)}: {problem}",
                            how="rename it, e.g. arm_controller", file=path, line=document.line(name))


def _check_kinematics_values(report: ValidationReport) -> None:
    """kinematics.yaml's solver timeout, search resolution and attempts are numbers within KINEMATICS_RANGES."""
    path, found = report.files.kinematics, report.findings
    document = _read_mapping(path, "kinematics", Findings())  # unreadable: _check_kinematics or the planner says
    if document is None or path is None:
        return
    for group, body in document.root.items():
        if not isinstance(body, dict):
            continue
        for key in KINEMATICS_RANGES:
            expected = kinematics_value_problem(key, body[key]) if key in body else None
            if expected is not None:
                found.error("kinematics.value", f"kinematics.yaml: {key} of {group} is out of range",
                            what=f"{key}: {expected}", why=f"{key} is {truncated(repr(body[key]), 80)}",
                            how=f"set {group}.{key} within that range, or remove it (plem uses "
                                f"{SOLVER_DEFAULTS[key]} then)", file=path, line=document.line(group, key))


def _check_srdf_against_urdf(report: ValidationReport, urdf: UrdfModel, srdf: SrdfModel, path: Path) -> None:
    found = report.findings
    lines = path.suffix == ".srdf"

    def at(line: int | None) -> int | None:
        return line if lines else None

    if srdf.name and srdf.name != urdf.name:
        found.warning("srdf.robot_name", "SRDF and URDF robot names differ", what="the same <robot name>",
                      why=f"SRDF {srdf.name!r}, URDF {urdf.name!r}", how="use the URDF's name in the SRDF", file=path)
    for group in srdf.groups.values():
        for link, line in group.links:
            if link not in urdf.links:
                found.error("srdf.unknown_link", f"Group {group.name} names unknown link {link}",
                            what="SRDF links that exist in the URDF", why=f"no URDF link {link!r}",
                            how="fix the name", file=path, line=at(line))
        for joint, line in group.joints:
            if joint not in urdf.joints:
                found.error("srdf.unknown_joint", f"Group {group.name} names unknown joint {joint}",
                            what="SRDF joints that exist in the URDF", why=f"no URDF joint {joint!r}",
                            how="fix the name", file=path, line=at(line))
        for sub, line in group.subgroups:
            if sub not in srdf.groups:
                found.error("srdf.unknown_group", f"Group {group.name} names unknown subgroup {sub}",
                            what="subgroups defined in the SRDF", why=f"no group {sub!r}", how="fix the name",
                            file=path, line=at(line))
        for base, tip, line in group.chains:
            missing = [name for name in (base, tip) if name not in urdf.links]
            if missing:
                found.error("srdf.chain", f"Chain of group {group.name} names unknown links",
                            what="base_link and tip_link that exist in the URDF", why=f"missing: {', '.join(missing)}",
                            how="fix the link names", file=path, line=at(line))
            elif urdf.chain(base, tip) is None:
                found.error("srdf.chain", f"Chain of group {group.name} is not connected",
                            what=f"tip_link {tip} below base_link {base} in the URDF tree",
                            why=f"{tip} does not hang below {base}", how="swap them or pick links on one branch",
                            file=path, line=at(line))
    for state in srdf.group_states:
        if state.group not in srdf.groups:
            found.error("srdf.unknown_group", f"group_state {state.name} names unknown group {state.group}",
                        what="group states of defined groups", why=f"no group {state.group!r}", how="fix the name",
                        file=path, line=at(state.line))
        for joint, value, line in state.values:
            if joint not in urdf.joints:
                found.error("srdf.state_unknown_joint", f"group_state {state.name} names unknown joint {joint}",
                            what="joints that exist in the URDF", why=f"no URDF joint {joint!r}", how="fix the name",
                            file=path, line=at(line))
                continue
            bounds = tighten(report.file_limits.get(joint), urdf.joints[joint])
            low, high = bounds.min_position, bounds.max_position
            if value is None or not math.isfinite(value) or (low is not None and value < low) or (
                    high is not None and value > high):
                found.error("srdf.state_out_of_limits", f"group_state {state.name}: {joint} is outside its limits",
                            what=f"a value within [{low:g}, {high:g}]" if low is not None and high is not None
                            else "a numeric value", why=f"{joint} = {value!r}", how="choose a value inside the limits",
                            file=path, line=at(line))
    for link1, link2, line in srdf.disabled_collisions:
        missing = [name for name in (link1, link2) if name not in urdf.links]
        if missing:
            found.error("srdf.collision_unknown_link", "disable_collisions names unknown links",
                        what="link1 and link2 that exist in the URDF", why=f"missing: {', '.join(missing)}",
                        how="fix or remove the entry", file=path, line=at(line))
    for joint, line in srdf.passive_joints:
        if joint not in urdf.joints:
            found.error("srdf.passive_unknown_joint", f"passive_joint names unknown joint {joint}",
                        what="<passive_joint name> naming a joint of the URDF",
                        why=f"no URDF joint {joint!r}",
                        how="fix the name, or remove the <passive_joint>", file=path, line=at(line))


def _check_kinematics(report: ValidationReport) -> None:
    path, found, srdf = report.files.kinematics, report.findings, report.srdf
    document = _read_mapping(path, "kinematics", found)
    if document is None:
        return
    if srdf is None and report.files.srdf is not None:
        return  # the SRDF itself is broken and already reported
    if srdf is None:
        found.warning("kinematics.without_srdf", "kinematics.yaml is unused without an SRDF",
                      what="an SRDF defining the groups kinematics.yaml configures",
                      why="the package has no SRDF, so planning will not start", how="add srdf/NAME.srdf or remove it",
                      file=path)
        return
    for group, body in document.root.items():
        line = document.line(group)
        if group not in srdf.groups:
            found.error("kinematics.unknown_group", f"kinematics.yaml configures unknown group {group}",
                        what=f"groups defined in the SRDF ({', '.join(srdf.groups) or 'none'})",
                        why=f"no SRDF group {group!r}", how="rename it to an SRDF group", file=path, line=line)
        solver = body.get("kinematics_solver") if isinstance(body, dict) else None
        if solver is not None and solver not in KNOWN_SOLVERS:
            found.warning("kinematics.solver_unknown", f"Unknown kinematics solver for {group}",
                          what=f"one of {', '.join(KNOWN_SOLVERS)}",
                          why=f"kinematics_solver is {solver!r}; plem solves IK with pinocchio and records the name",
                          how="check the plugin name", file=path, line=line)


def require_valid(package: str | os.PathLike[str], *, stage: Stage, urdf_file: str | os.PathLike[str] | None = None,
                  srdf_file: str | os.PathLike[str] | None = None) -> ValidationReport:
    """Validate and raise every error together (for launch and start-up), returning the report otherwise."""
    report = validate_package(package, stage=stage, urdf_file=urdf_file, srdf_file=srdf_file)
    report.findings.raise_errors(f"description package '{report.files.name}'")
    return report


__all__ = ["DescriptionError", "Stage", "ValidationReport", "require_valid", "validate_package"]
