"""Motion sequences as users give them: joint (PTP), straight-line (LIN) and circular (CIRC) items with a blend
radius each, and the tool's speed limits for their Cartesian parts (Pilz's cartesian_limits names).

Plain data with JSON forms: the client sends a sequence to the planner, which builds, checks and times it
(plem.planning.tool_paths, plem.planning.path_timing).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from plem.errors import MoveItCode, PlanningError
from plem.planning.poses import Pose

#: Largest blend radius (m): far beyond any arm's reach.
MAX_BLEND_M = 10.0
#: Most items a sequence may hold, which bounds its cost.
MAX_ITEMS = 1000

JointTarget = str | Sequence[float] | Mapping[str, float] | Pose


def _invalid(summary: str, what: str, why: str, how: str) -> PlanningError:
    return PlanningError(summary, what=what, why=why, how=how, code=MoveItCode.INVALID_GOAL_CONSTRAINTS)


def _blend(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not 0.0 <= value <= MAX_BLEND_M:
        raise _invalid(f"the blend radius of {where} is out of range", what=f"a blend radius in [0, {MAX_BLEND_M:g}] m "
                       "(0: the arm stops there)", why=f"blend = {str(value)[:80]}",
                       how="give blend in metres, e.g. blend=0.05, or 0 to stop at the point")
    return float(value)


@dataclass(frozen=True)
class Joint:
    """A joint-space move (Pilz's PTP, ur_rtde's moveJ): to joint positions (a list in joint order, {joint: rad},
    a named state such as 'home') or to a pose of the tool reached by IK; `blend` (m of tool travel) rounds the
    corner at its end instead of stopping there."""

    target: JointTarget
    blend: float = 0.0
    frame: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "blend", _blend(self.blend, "a Joint item"))


@dataclass(frozen=True)
class Linear:
    """A straight tool path to `pose` in `frame` (Pilz's LIN, ur_rtde's moveL), the orientation turning by slerp;
    `blend` (m) rounds the corner at its end instead of stopping there."""

    pose: Pose
    blend: float = 0.0
    frame: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "blend", _blend(self.blend, "a Linear item"))


@dataclass(frozen=True)
class Circular:
    """An arc of the tool to `pose` (Pilz's CIRC, ur_rtde's moveC): through the position of `via` (Pilz's interim)
    or around `center`; exactly one of them. The orientation turns by slerp from start to `pose`."""

    pose: Pose
    via: Pose | Sequence[float] | None = None
    center: Pose | Sequence[float] | None = None
    blend: float = 0.0
    frame: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "blend", _blend(self.blend, "a Circular item"))
        if (self.via is None) == (self.center is None):
            raise _invalid("a circular move needs via or center", what="exactly one of via (a point on the arc) and "
                           "center (the arc's centre)", why="both were given" if self.via is not None else
                           "neither was given", how="give Circular(pose, via=...) or Circular(pose, center=...)")
        position_of(self.via if self.via is not None else self.center)  # x y z or a Pose, else refused here

    @property
    def point(self) -> tuple[float, float, float]:
        """The via point or the centre, as a position."""
        given = self.via if self.via is not None else self.center
        return position_of(given)

    @property
    def kind(self) -> str:
        """'via' or 'center' (Pilz's path constraint names: interim, center)."""
        return "via" if self.via is not None else "center"


Item = Joint | Linear | Circular


@dataclass(frozen=True)
class ToolLimits:
    """The tool's speed limits on straight and circular moves and their blends (Pilz's cartesian_limits.yaml names;
    translational defaults are ur_rtde's moveL defaults). Joint (PTP) moves keep the joint limits alone, as in Pilz."""

    max_trans_vel: float = 0.25
    max_trans_acc: float = 1.2
    max_rot_vel: float = 1.57
    max_rot_acc: float = 3.14

    def __post_init__(self) -> None:
        for name in ("max_trans_vel", "max_trans_acc", "max_rot_vel", "max_rot_acc"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float) or not 0.0 < value <= 100.0:
                raise _invalid(f"{name} is out of range", what=f"{name} in (0, 100] (m/s, m/s², rad/s, rad/s²)",
                               why=f"{name} = {str(value)[:80]}", how=f"give {name} above 0, e.g. ToolLimits()'s "
                               f"default {getattr(ToolLimits, name)}")
            object.__setattr__(self, name, float(value))

    def scaled(self, velocity: float, acceleration: float) -> ToolLimits:
        """The limits times the plan's velocity and acceleration scales."""
        return ToolLimits(self.max_trans_vel * velocity, self.max_trans_acc * acceleration,
                          self.max_rot_vel * velocity, self.max_rot_acc * acceleration)

    def to_json(self) -> dict[str, float]:
        """The four limits by name."""
        return {"max_trans_vel": self.max_trans_vel, "max_trans_acc": self.max_trans_acc,
                "max_rot_vel": self.max_rot_vel, "max_rot_acc": self.max_rot_acc}

    @classmethod
    def from_json(cls, value: Any) -> ToolLimits:
        """The inverse of `to_json` (absent keys keep their defaults); anything else raises PlanningError."""
        if value is None:
            return cls()
        if not isinstance(value, dict) or set(value) - set(cls().to_json()):
            raise _invalid("the tool limits are not understood", what="{max_trans_vel, max_trans_acc, max_rot_vel, "
                           "max_rot_acc}", why=str(value)[:200], how="name only those limits")
        return cls(**value)


def position_of(value: Pose | Sequence[float] | None) -> tuple[float, float, float]:
    """A position given as a Pose or as x y z."""
    if isinstance(value, Pose):
        return value.position
    return Pose(tuple(value) if isinstance(value, Sequence) else value).position  # type: ignore[arg-type]


def item_json(item: Item) -> dict[str, Any]:
    """An item as JSON, tagged with Pilz's planner id (PTP, LIN, CIRC)."""
    if isinstance(item, Joint):
        target: Any = item.target
        if isinstance(target, Pose):
            target = {"pose": target.to_json()}
        elif isinstance(target, Mapping):
            target = {"joints": {str(k): float(v) for k, v in target.items()}}
        elif not isinstance(target, str):
            target = [float(v) for v in target]
        return {"type": "PTP", "target": target, "blend": item.blend, "frame": item.frame}
    if isinstance(item, Linear):
        return {"type": "LIN", "pose": item.pose.to_json(), "blend": item.blend, "frame": item.frame}
    return {"type": "CIRC", "pose": item.pose.to_json(), item.kind: list(item.point), "blend": item.blend,
            "frame": item.frame}


def item_from_json(value: Any, index: int) -> Item:
    """The inverse of `item_json`; anything else raises PlanningError naming the item."""
    if not isinstance(value, dict) or value.get("type") not in ("PTP", "LIN", "CIRC"):
        raise _invalid(f"item {index} of the sequence is not understood", what="items of type PTP, LIN or CIRC",
                       why=f"item {index}: {str(value)[:160]}", how="build items with Joint, Linear and Circular")
    blend, frame = value.get("blend", 0.0), value.get("frame", "")
    if not isinstance(frame, str):
        raise _invalid(f"the frame of item {index} is not a name", what="a link name", why=str(frame)[:80],
                       how="give the frame as text")
    if value["type"] == "LIN":
        return Linear(Pose.from_json(value.get("pose")), blend, frame)
    if value["type"] == "CIRC":
        return Circular(Pose.from_json(value.get("pose")), value.get("via"), value.get("center"), blend, frame)
    target = value.get("target")
    if isinstance(target, dict) and "pose" in target:
        target = Pose.from_json(target["pose"])
    elif isinstance(target, dict) and isinstance(target.get("joints"), dict):
        joints = target["joints"]
        if not all(isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
                   for v in joints.values()):
            raise _invalid(f"the joint target of item {index} is not numbers", what="{joint: rad}",
                           why=str(joints)[:160], how="give finite positions in rad")
        target = {str(k): float(v) for k, v in joints.items()}
    elif isinstance(target, list):
        if not all(isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) for v in target):
            raise _invalid(f"the joint target of item {index} is not numbers", what="positions in rad",
                           why=str(target)[:160], how="give finite positions in rad")
    elif not isinstance(target, str):
        raise _invalid(f"the joint target of item {index} is not understood",
                       what="positions, {joint: rad}, a named state or a pose", why=str(target)[:160],
                       how="build the item with Joint(...)")
    return Joint(target, blend, frame)


def items_from_json(value: Any) -> list[Item]:
    """A sequence's items from JSON: at least one, at most MAX_ITEMS."""
    if not isinstance(value, list) or not 1 <= len(value) <= MAX_ITEMS:
        raise _invalid("the sequence is empty or too long", what=f"1 to {MAX_ITEMS} items",
                       why=f"got {len(value) if isinstance(value, list) else type(value).__name__}",
                       how="give the items to move through in a list")
    return [item_from_json(item, index) for index, item in enumerate(value)]
