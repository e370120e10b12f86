"""joint_limits.yaml: per-joint position, velocity, acceleration, jerk and effort limits (SI units).

The URDF's `<limit>` values are hard limits: joint_limits.yaml may tighten them, never loosen or remove them.
`tighten` gives the limits the driver enforces (the tighter of the two, whatever the file says, and the
acceleration and jerk limits neither gives, derived: see `derive_missing`);
`loosened` lists where the file tries to go beyond the URDF, which validation reports as errors.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from plem.core.config.yaml_document import YamlDocument
from plem.description.model import Joint
from plem.description.package_yaml import read_package_yaml
from plem.description.problems import Findings
from plem.errors import ConfigError

MAXIMA = ("max_velocity", "max_acceleration", "max_jerk", "max_effort")
FLAGS = {"max_velocity": "has_velocity_limits", "max_acceleration": "has_acceleration_limits",
         "max_jerk": "has_jerk_limits", "max_effort": "has_effort_limits"}
KNOWN_KEYS = {"has_position_limits", "min_position", "max_position", *MAXIMA, *FLAGS.values()}
UNITS = {"max_velocity": "rad/s", "max_acceleration": "rad/s²", "max_jerk": "rad/s³", "max_effort": "N·m"}
#: A joint without max_acceleration gets the one that takes it from rest to its velocity limit in this time (s).
FULL_SPEED_S = 0.5
#: A joint without max_jerk gets the one that takes it from 0 to its acceleration limit in this time (s).
FULL_ACCELERATION_S = 0.1
#: Each limit plem derives when a package leaves it out: the limit it is derived from, and the time above.
DERIVED_FROM = {"max_acceleration": ("max_velocity", FULL_SPEED_S),
                "max_jerk": ("max_acceleration", FULL_ACCELERATION_S)}


@dataclass(frozen=True)
class JointLimit:
    """Active limits of one joint; None where the file sets no such limit (or disables it)."""

    name: str
    min_position: float | None = None
    max_position: float | None = None
    max_velocity: float | None = None
    max_acceleration: float | None = None
    max_jerk: float | None = None
    max_effort: float | None = None
    line: int | None = None
    lines: Mapping[str, int] = field(default_factory=dict, compare=False)  # line of each key in the file
    disabled: frozenset[str] = frozenset()  # the has_*_limits keys the file sets to false
    derived: frozenset[str] = frozenset()  # the maxima plem derived because neither the file nor the URDF sets them

    def line_of(self, key: str) -> int | None:
        """The line of `key` in the joint's entry, or the entry's own line when the key is not written."""
        return self.lines.get(key, self.line)


@dataclass(frozen=True)
class HardLimit:
    """A limit the URDF `<limit>` sets: the JointLimit field holding it, the URDF attribute, the has_*_limits key
    that would turn it off, and whether it bounds from below (a larger value is then the tighter one)."""

    key: str
    attribute: str
    flag: str
    from_below: bool = False

    def urdf_value(self, joint: Joint) -> float | None:
        """The joint's URDF value of this limit, or None when the URDF sets none that can be enforced (absent,
        not finite, a velocity or effort that is not positive, or a position bound of a continuous joint)."""
        value: float | None = getattr(joint, self.attribute)
        if value is None or not math.isfinite(value):
            return None
        if self.flag == "has_position_limits":
            return None if joint.type == "continuous" else value
        return value if value > 0 else None

    def tighter(self, own: float, hard: float) -> float:
        """The stricter of a joint_limits.yaml value and the URDF's."""
        return max(own, hard) if self.from_below else min(own, hard)

    def looser(self, own: float, hard: float) -> bool:
        """Whether a joint_limits.yaml value goes beyond the URDF's (by more than rounding)."""
        slack = 1e-9 * max(1.0, abs(hard))
        return own < hard - slack if self.from_below else own > hard + slack


HARD_LIMITS = (HardLimit("min_position", "lower", "has_position_limits", from_below=True),
               HardLimit("max_position", "upper", "has_position_limits"),
               HardLimit("max_velocity", "velocity", "has_velocity_limits"),
               HardLimit("max_effort", "effort", "has_effort_limits"))


def tighten(limit: JointLimit | None, joint: Joint) -> JointLimit:
    """The limits the driver and the planner enforce on `joint`: each URDF `<limit>` value, or the joint_limits.yaml
    value where that is stricter; limits the URDF does not set (acceleration, jerk) as the file gives them, else
    derived (`derive_missing`)."""
    base = limit if limit is not None else JointLimit(joint.name)
    values: dict[str, Any] = {}
    for hard in HARD_LIMITS:
        urdf = hard.urdf_value(joint)
        if urdf is not None:
            own: float | None = getattr(base, hard.key)
            values[hard.key] = urdf if own is None else hard.tighter(own, urdf)
    return derive_missing(replace(base, **values))


def derive_missing(limit: JointLimit) -> JointLimit:
    """`limit` with the acceleration and jerk limits it lacks derived, so that every motion is jerk-limited:
    max_acceleration = max_velocity / FULL_SPEED_S and max_jerk = max_acceleration / FULL_ACCELERATION_S (the
    proportions of the description package protocol's example limits). `derived` names what was derived; a joint
    without a velocity limit gets no acceleration limit from it."""
    values: dict[str, Any] = {}
    for key, (source, seconds) in DERIVED_FROM.items():
        base: float | None = values.get(source, getattr(limit, source))
        if getattr(limit, key) is None and base is not None:
            values[key] = base / seconds
    return replace(limit, derived=limit.derived | frozenset(values), **values) if values else limit


def derivation(key: str) -> str:
    """How plem derives the limit `key` when a package leaves it out, in words (e.g. 'max_velocity / 0.5 s')."""
    source, seconds = DERIVED_FROM[key]
    return f"{source} / {seconds:g} s"


def derived_limits_note(limits: Mapping[str, JointLimit]) -> str:
    """One sentence stating the limits plem derived for these joints and their values ('' when none were)."""
    parts = []
    for key in DERIVED_FROM:
        joints = [limit for limit in limits.values() if key in limit.derived]
        if joints:
            values = ", ".join(f"{limit.name} {getattr(limit, key):.4g}" for limit in joints)
            parts.append(f"{key} = {derivation(key)} ({values} {UNITS[key]})")
    if not parts:
        return ""
    return ("joint_limits.yaml and the URDF leave out some limits, so plem derives them and the driver and the planner "
            "both enforce them: " + "; ".join(parts) + ". Add them to config/joint_limits.yaml to set your own")


def loosened(limit: JointLimit, joint: Joint) -> list[tuple[HardLimit, float | None, float]]:
    """Where joint_limits.yaml goes beyond the URDF's `<limit>` of `joint`: (limit, the file's value or None when
    its has_*_limits: false removes the limit, the URDF's value); a removed position range is listed once."""
    found: list[tuple[HardLimit, float | None, float]] = []
    for hard in HARD_LIMITS:
        urdf = hard.urdf_value(joint)
        if urdf is None:
            continue
        own: float | None = getattr(limit, hard.key)
        if hard.flag in limit.disabled:
            if all(other.flag != hard.flag for other, _, _ in found):
                found.append((hard, None, urdf))
        elif own is not None and hard.looser(own, urdf):
            found.append((hard, own, urdf))
    return found


def _number(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    return float(value)


def read_joint_limits(path: Path, found: Findings) -> dict[str, JointLimit]:
    """Parse and check the file on its own (cross-checks with the URDF live in the validator)."""
    try:
        document = read_package_yaml(path, "joint_limits.yaml")
    except ConfigError as error:
        found.add("limits.yaml", error, path)
        return {}
    root = document.root
    section = root.get("joint_limits") if isinstance(root, dict) else None
    if not isinstance(section, dict):
        found.error("limits.structure", "joint_limits.yaml has no joint_limits mapping",
                    what="a top-level key joint_limits: with one entry per joint",
                    why="the file's top level is " + (f"keys {', '.join(map(str, root))}" if isinstance(root, dict)
                                                      else type(root).__name__),
                    how="put the per-joint entries under joint_limits:", file=path, line=1)
        return {}
    limits: dict[str, JointLimit] = {}
    for name, entry in section.items():
        line = document.line("joint_limits", name)
        if not isinstance(entry, dict):
            found.error("limits.structure", f"Limits of {name} are not a mapping",
                        what=f"joint_limits.{name} with keys such as max_velocity", why=f"found {entry!r}",
                        how="give the joint's limits as key: value pairs", file=path, line=line)
            continue
        limits[str(name)] = _read_joint(str(name), entry, document, path, found)
    return limits


def _read_joint(name: str, entry: dict[Any, Any], document: YamlDocument, path: Path, found: Findings) -> JointLimit:
    line = document.line("joint_limits", name)

    def line_of(key: str) -> int:
        return document.line("joint_limits", name, key) if key in entry else line

    values: dict[str, float] = {}
    for key, raw in entry.items():
        if key not in KNOWN_KEYS:
            found.warning("limits.unknown_key", f"Unknown key {key} for {name}",
                          what=f"keys among {', '.join(sorted(KNOWN_KEYS))}",
                          why=f"joint_limits.{name}.{key} is not one", how="remove it or fix its spelling", file=path,
                          line=line_of(key))
        elif key.startswith("has_"):
            if not isinstance(raw, bool):
                found.error("limits.type", f"{key} of {name} must be true or false",
                            what=f"joint_limits.{name}.{key}: true or false", why=f"found {raw!r}",
                            how="write true or false", file=path, line=line_of(key))
        else:
            number = _number(raw)
            if number is None or not math.isfinite(number):
                found.error("limits.type", f"{key} of {name} is not a number",
                            what=f"joint_limits.{name}.{key} as a finite number", why=f"found {raw!r}",
                            how="write a plain number (radians, rad/s, rad/s², rad/s³, N·m)", file=path,
                            line=line_of(key))
            else:
                values[key] = number
    for key in MAXIMA:
        if entry.get(FLAGS[key]) is False:
            values.pop(key, None)
        elif key in values and values[key] <= 0:
            found.error("limits.nonpositive", f"{key} of {name} must be positive",
                        what=f"joint_limits.{name}.{key} > 0 ({UNITS[key]})", why=f"found {values[key]:g}",
                        how=f"set a positive {key}, or has_{key.removeprefix('max_')}_limits: false", file=path,
                        line=line_of(key))
            values.pop(key)
    lower, upper = values.get("min_position"), values.get("max_position")
    position_on = entry.get("has_position_limits", lower is not None or upper is not None)
    if position_on is True and (lower is None or upper is None):
        found.error("limits.position_missing", f"Position limits of {name} are incomplete",
                    what=f"min_position and max_position for {name} (has_position_limits is true)",
                    why=f"missing {'min_position' if lower is None else 'max_position'}",
                    how="add both, or set has_position_limits: false for an unlimited joint", file=path, line=line)
    if position_on is True and lower is not None and upper is not None and not lower < upper:
        found.error("limits.min_max", f"min_position of {name} is not below max_position",
                    what="min_position < max_position", why=f"min_position {lower:g} >= max_position {upper:g}",
                    how="swap or correct the two values", file=path, line=line_of("min_position"))
    if position_on is not True:
        lower = upper = None
    return JointLimit(name, lower, upper, values.get("max_velocity"), values.get("max_acceleration"),
                      values.get("max_jerk"), values.get("max_effort"), line,
                      lines={str(key): line_of(key) for key in entry},
                      disabled=frozenset(str(key) for key, raw in entry.items()
                                         if str(key).startswith("has_") and raw is False))
