"""Planning groups: the SRDF's groups resolved to the arm's joints, with kinematics.yaml's solver settings.

A group is a chain (base link to tip link), a list of joints or links, or other groups. Its IK link is the
chain's tip, or for a joint list the link at the end of its last joint (followed through fixed joints
while the tree does not branch, so a tool frame such as `tcp` is reached).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from plem.description.generate import SOLVER_DEFAULTS
from plem.description.model import SrdfGroup, SrdfModel, UrdfModel
from plem.description.package_yaml import read_package_yaml
from plem.description.validate import KNOWN_SOLVERS
from plem.errors import ConfigError
from plem.planning.goals import MAX_IK_TIMEOUT_S

#: The solver plem runs for every known kinematics_solver name.
SOLVER = "plem/pinocchio (damped least squares, random restarts)"


@dataclass(frozen=True)
class KinematicsSettings:
    """kinematics.yaml's settings of one group; `solver` is the name as written (recorded, then mapped)."""

    solver: str = "kdl_kinematics_plugin/KDLKinematicsPlugin"
    timeout_s: float = float(SOLVER_DEFAULTS["kinematics_solver_timeout"])
    search_resolution: float = float(SOLVER_DEFAULTS["kinematics_solver_search_resolution"])
    attempts: int | None = None

    @property
    def budget_s(self) -> float:
        """The time one IK request may take: the timeout, times the attempts where a package still sets them, at
        most MAX_IK_TIMEOUT_S."""
        return min(self.timeout_s * (self.attempts or 1), MAX_IK_TIMEOUT_S)


@dataclass(frozen=True)
class PlanningGroup:
    """One SRDF group: its joints in the arm's order, its base and IK link, and its solver settings."""

    name: str
    joints: tuple[str, ...]
    base_link: str
    tip_link: str
    settings: KinematicsSettings = field(default_factory=KinematicsSettings)


def read_groups(srdf: SrdfModel, urdf: UrdfModel, arm_joints: tuple[str, ...], kinematics: Path | None
                ) -> tuple[dict[str, PlanningGroup], list[str]]:
    """The SRDF's groups that move some of the arm's joints, and warnings (unknown solvers, skipped groups)."""
    settings, warnings = _read_settings(kinematics)
    groups: dict[str, PlanningGroup] = {}
    root = urdf.roots()[0] if urdf.roots() else ""
    for name, group in srdf.groups.items():
        joints = _group_joints(srdf, urdf, group, set())
        ordered = tuple(joint for joint in arm_joints if joint in joints)
        if not ordered:
            warnings.append(f"SRDF group {name!r} moves none of the arm's joints; it cannot be planned for")
            continue
        chain = group.chains[0] if group.chains else None
        base = chain[0] if chain else root
        tip = chain[1] if chain else end_link(urdf, ordered[-1])
        groups[name] = PlanningGroup(name, ordered, base, tip, settings.get(name, KinematicsSettings()))
    for name in settings:
        if name not in groups:
            warnings.append(f"kinematics.yaml configures {name!r}, which is not a planning group of the SRDF")
    return groups, warnings


def _group_joints(srdf: SrdfModel, urdf: UrdfModel, group: SrdfGroup, seen: set[str]) -> set[str]:
    """Every actuated joint a group names: through its chains, joints, links (their parent joints) and subgroups."""
    if group.name in seen:
        return set()
    seen.add(group.name)
    joints = {name for name, _ in group.joints}
    for base, tip, _ in group.chains:
        joints.update(joint.name for joint in urdf.chain(base, tip) or [])
    for link, _ in group.links:
        parent = urdf.parent_of(link)
        if parent is not None:
            joints.add(parent.name)
    for subgroup, _ in group.subgroups:
        if subgroup in srdf.groups:
            joints |= _group_joints(srdf, urdf, srdf.groups[subgroup], seen)
    return {name for name in joints if name in urdf.joints and urdf.joints[name].actuated}


def end_link(urdf: UrdfModel, joint: str) -> str:
    """The child link of `joint`, followed down fixed joints while exactly one leaves each link."""
    link = urdf.joints[joint].child or ""  # validation guarantees every joint a child
    while True:
        below = [j for j in urdf.joints.values() if j.parent == link]
        if len(below) != 1 or below[0].actuated or below[0].child is None:
            return link
        link = below[0].child


def _read_settings(path: Path | None) -> tuple[dict[str, KinematicsSettings], list[str]]:
    """kinematics.yaml per group; a value of the wrong kind is a ConfigError naming the file and line."""
    if path is None:
        return {}, []
    document = read_package_yaml(path, "kinematics.yaml")
    warnings: list[str] = []
    settings: dict[str, KinematicsSettings] = {}
    root = document.root if isinstance(document.root, dict) else {}
    for group, body in root.items():
        if not isinstance(body, dict):
            continue
        solver = str(body.get("kinematics_solver", KinematicsSettings.solver))
        if solver not in KNOWN_SOLVERS:
            warnings.append(f"kinematics.yaml: group {group!r} names the unknown solver {solver!r}; "
                            f"plem's own solver is used ({SOLVER})")
        settings[str(group)] = KinematicsSettings(
            solver,
            _positive(body, "kinematics_solver_timeout", KinematicsSettings.timeout_s, path, document.line(group)),
            _positive(body, "kinematics_solver_search_resolution", KinematicsSettings.search_resolution, path,
                      document.line(group)),
            int(_positive(body, "kinematics_solver_attempts", 1, path, document.line(group)))
            if "kinematics_solver_attempts" in body else None)
    return settings, warnings


def _positive(body: dict[str, object], key: str, default: float, path: Path, line: int | None) -> float:
    value = body.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value) or value <= 0:
        raise ConfigError(f"kinematics.yaml: {key} is not a positive number",
                          what=f"{key}: a number above 0", why=f"{path}:{line or '?'}: {key} is {value!r}",
                          how=f"set {key} to a positive number (e.g. {default}) or remove it")
    return float(value)
