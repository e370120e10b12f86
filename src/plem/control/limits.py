"""Joint limits as arrays in the arm's joint order, and the checks that keep commands inside them.

Absent limits are +inf (or -inf for a lower bound), so every check is one vectorised comparison: a joint without
position limits (continuous) has the range (-inf, inf) and no position check.

An arm outside a joint's range (placed there while disabled, or with joint_limits.yaml tightened since) is never
trapped: a motion from there is checked against `reaching(start)`, the range widened to where the joint is, so
it may go back toward its range and into it, never farther out.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from plem.description.limits import UNITS, JointLimit
from plem.errors import CommandRejected, ConfigError

#: Names of the limit arrays, as used in messages.
KINDS = ("position", "velocity", "acceleration", "jerk", "effort")
#: The contact stop's default threshold: estimated external torque as a share of each joint's effort limit.
CONTACT_SHARE = 0.25


@dataclass(frozen=True)
class ArmLimits:
    """Position range and velocity/acceleration/jerk/effort maxima per joint (SI)."""

    joint_names: tuple[str, ...]
    min_position: np.ndarray
    max_position: np.ndarray
    max_velocity: np.ndarray
    max_acceleration: np.ndarray
    max_jerk: np.ndarray
    max_effort: np.ndarray
    #: Where a motion starts, for joints outside their range there (NaN for the others), and the ranges before
    #: `reaching` widened them to there.
    start_outside: np.ndarray | None = None
    own_range: tuple[np.ndarray, np.ndarray] | None = None

    @classmethod
    def from_joint_limits(cls, limits: Mapping[str, JointLimit], joint_names: Sequence[str]) -> ArmLimits:
        """Arrays in `joint_names` order; a joint missing from the file is a ConfigError."""
        missing = [name for name in joint_names if name not in limits]
        if missing:
            raise ConfigError("joint_limits.yaml has no limits for some joints",
                              what=f"an entry under joint_limits: for each of {', '.join(joint_names)}",
                              why=f"missing: {', '.join(missing)}",
                              how="add the joints to config/joint_limits.yaml of the description package")

        def column(attribute: str, absent: float) -> np.ndarray:
            values = [getattr(limits[name], attribute) for name in joint_names]
            return np.array([absent if v is None else v for v in values], dtype=float)

        return cls(tuple(joint_names), column("min_position", -math.inf), column("max_position", math.inf),
                   column("max_velocity", math.inf), column("max_acceleration", math.inf),
                   column("max_jerk", math.inf), column("max_effort", math.inf))

    @property
    def dof(self) -> int:
        """Number of joints."""
        return len(self.joint_names)

    def maximum(self, kind: str) -> np.ndarray:
        """The array of maxima for 'velocity', 'acceleration', 'jerk' or 'effort'."""
        maxima: np.ndarray = getattr(self, f"max_{kind}")
        return maxima

    def check_vector(self, values: Sequence[float] | np.ndarray, what: str) -> np.ndarray:
        """`values` as a float array of length dof with finite entries, else CommandRejected."""
        try:
            array = np.asarray(values, dtype=float).reshape(-1)
        except (TypeError, ValueError, OverflowError) as error:   # OverflowError: an int beyond a float's range
            raise CommandRejected(f"{what} is not a list of numbers", what=f"{self.dof} numbers, one per joint",
                                  why=str(error), how=f"pass {what} as {self.dof} floats") from error
        if array.size != self.dof:
            raise CommandRejected(f"{what} has {array.size} values for {self.dof} joints",
                                  what=f"one value per joint ({', '.join(self.joint_names)})",
                                  why=f"got {array.size}", how=f"pass exactly {self.dof} values")
        bad = [self.joint_names[i] for i in np.flatnonzero(~np.isfinite(array))]
        if bad:
            raise CommandRejected(f"{what} contains NaN or infinity", what="finite numbers only",
                                  why=f"not finite for {', '.join(bad)}", how="send finite values")
        return array

    def reaching(self, start: Sequence[float] | np.ndarray) -> ArmLimits:
        """These limits for a motion from `start`: a joint outside its range there may be anywhere between where it
        is and its range (back toward it, never farther out); the others keep their range."""
        start = np.asarray(start, dtype=float)
        outside = (start < self.min_position) | (start > self.max_position)
        if not outside.any():
            return self
        return replace(self, min_position=np.minimum(self.min_position, start),
                       max_position=np.maximum(self.max_position, start),
                       start_outside=np.where(outside, start, np.nan),
                       own_range=(self.min_position, self.max_position))

    def check_positions(self, positions: np.ndarray, what: str, tolerance: float = 0.0) -> None:
        """Reject positions more than `tolerance` outside [min_position, max_position], naming the joint and value."""
        low = positions < self.min_position - tolerance
        high = positions > self.max_position + tolerance
        if low.any() or high.any():
            i = int(np.flatnonzero(low | high)[0])
            raise self.position_refused(i, float(positions[i]), what, "min" if low[i] else "max")

    def position_refused(self, i: int, position: float, what: str, side: str) -> CommandRejected:
        """The refusal of joint `i` at `position` beyond its `side` ('min' or 'max') bound, worded for `what`; for a
        joint that starts outside its range, it says so and how to bring it back."""
        name, low, high = self.joint_names[i], float(self.min_position[i]), float(self.max_position[i])
        bound = low if side == "min" else high
        start = math.nan if self.start_outside is None else float(self.start_outside[i])
        if self.own_range is None or math.isnan(start):
            return CommandRejected(
                f"{what} is outside the position limits of {name}",
                what=f"{name} within [{low:.6g}, {high:.6g}] rad",
                why=f"{name} = {position:.6g} rad is beyond its {side}_position {bound:.6g} rad",
                how="choose a target inside the joint's range (config/joint_limits.yaml)")
        own_low, own_high = float(self.own_range[0][i]), float(self.own_range[1][i])
        return CommandRejected(
            f"{what} takes {name} farther outside its position limits",
            what=f"{name} between where it is ({start:.6g} rad, outside its range) and its range "
                 f"[{own_low:.6g}, {own_high:.6g}] rad: back toward the range, never farther out",
            why=f"{what} asks for {name} = {position:.6g} rad, beyond {bound:.6g} rad",
            how=f"send a motion that brings {name} back into [{own_low:.6g}, {own_high:.6g}] rad (e.g. plem move --to "
                "with a target inside every range), with every other joint inside its own range")


def limit_exceeded(kind: str, joint: str, value: float, limit: float, where: str) -> CommandRejected:
    """The rejection for a derivative beyond its maximum, worded the same everywhere."""
    unit = UNITS.get(f"max_{kind}", "")
    return CommandRejected(
        f"{where} exceeds the {kind} limit of {joint}",
        what=f"|{kind}| of {joint} at most {limit:.6g} {unit}",
        why=f"{where} needs {abs(value):.6g} {unit}",
        how="slow the motion down (later time_from_start, or a smaller speed_scale)")
