"""Poses as users give them: a position in metres and a unit quaternion (x, y, z, w), checked on construction."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from plem.errors import MoveItCode, PlanningError

IDENTITY = (0.0, 0.0, 0.0, 1.0)
#: Largest coordinate of a position (m): far beyond any arm's reach, small enough that its square stays finite.
MAX_COORDINATE_M = 1000.0


def _invalid(summary: str, what: str, why: str, how: str) -> PlanningError:
    return PlanningError(summary, what=what, why=why, how=how, code=MoveItCode.INVALID_GOAL_CONSTRAINTS)


def _numbers(label: str, value: Any, count: int) -> tuple[float, ...]:
    if (not isinstance(value, Sequence) or isinstance(value, str) or len(value) != count
            or not all(isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) for v in value)):
        raise _invalid(f"{label} is not {count} finite numbers", what=f"{label} as {count} finite numbers",
                       why=f"{label} is {str(value)[:80]}", how=f"give {label} as {count} numbers")
    return tuple(float(v) for v in value)


@dataclass(frozen=True)
class Pose:
    """A position (x, y, z) in metres and an orientation as a unit quaternion (x, y, z, w), normalised here."""

    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    orientation: tuple[float, float, float, float] = IDENTITY

    def __post_init__(self) -> None:
        position = _numbers("position", self.position, 3)
        if max(map(abs, position)) > MAX_COORDINATE_M:
            raise _invalid("the position is out of range", what=f"coordinates within ±{MAX_COORDINATE_M:g} m",
                           why=f"position {position} m",
                           how="give the position in metres, in a frame near the robot (--frame, header.frame_id)")
        object.__setattr__(self, "position", position)
        quaternion = _numbers("orientation", self.orientation, 4)
        norm = math.hypot(*quaternion)
        if norm < 1e-9:
            raise _invalid("the orientation is a zero quaternion", what="a unit quaternion x y z w",
                           why=f"orientation {quaternion} has no direction",
                           how="give the orientation as a unit quaternion; 0 0 0 1 keeps the frame's axes")
        object.__setattr__(self, "orientation", tuple(v / norm for v in quaternion))

    @classmethod
    def of(cls, values: Sequence[float]) -> Pose:
        """From x y z (identity orientation) or x y z qx qy qz qw, as the command line takes them."""
        if len(values) not in (3, 7):
            raise _invalid("a pose is x y z or x y z qx qy qz qw",
                           what="3 numbers (position, m) or 7 (position, then a quaternion x y z w)",
                           why=f"got {len(values)} numbers", how="give the position and optionally the orientation")
        return cls(tuple(values[:3]), tuple(values[3:]) if len(values) == 7 else IDENTITY)  # type: ignore[arg-type]

    def to_json(self) -> dict[str, list[float]]:
        """Plain lists, for a JSON request."""
        return {"position": list(self.position), "orientation": list(self.orientation)}

    @classmethod
    def from_json(cls, value: Any) -> Pose:
        """The inverse of `to_json`; anything else raises PlanningError."""
        if not isinstance(value, dict):
            raise _invalid("a pose is not an object", what="{position: [x, y, z], orientation: [x, y, z, w]}",
                           why=f"got {type(value).__name__}", how="send a pose object")
        return cls(value.get("position"), value.get("orientation", IDENTITY))  # type: ignore[arg-type]
