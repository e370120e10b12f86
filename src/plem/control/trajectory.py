"""ROS 2 JointTrajectory goals: the message, the tolerances they run under and the result they end with.

Semantics follow trajectory_msgs/JointTrajectory and control_msgs/FollowJointTrajectory as ros2_control's
joint_trajectory_controller implements them; the spline itself lives in `plem.control.spline`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from enum import Enum, IntEnum
from typing import Any

import numpy as np

from plem.control.spline import JointNamesRejected, Spline
from plem.core import arguments
from plem.errors import CommandRejected

__all__ = ["DEFAULT_GOAL_TIME", "ErrorCode", "JointNamesRejected", "JointTrajectory", "Spline", "TrajectoryOutcome",
           "TrajectoryPoint", "TrajectoryResult", "TrajectoryTolerances"]

#: Seconds allowed after the last point to settle inside the goal tolerance, when a goal gives 0.
DEFAULT_GOAL_TIME = 1.0
POINT_KEYS = ("positions", "time_from_start", "velocities", "accelerations")
#: The resolution of time_from_start (builtin_interfaces/Duration counts nanoseconds): a point is at 0 or at least
#: this late; a time between the two is no time a ROS message can carry, and no time a cycle can resolve.
TIME_RESOLUTION_S = 1e-9


@dataclass(frozen=True)
class TrajectoryPoint:
    """One waypoint: positions (rad) reached time_from_start s after activation, optional velocities/accelerations."""

    positions: tuple[float, ...]
    time_from_start: float
    velocities: tuple[float, ...] | None = None
    accelerations: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        """Numbers as floats in tuples, whatever sequence of numbers was given; anything else is an ArgumentError."""
        object.__setattr__(self, "positions", arguments.reals(self.positions, "positions"))
        object.__setattr__(self, "time_from_start", arguments.real(self.time_from_start, "time_from_start"))
        for name in ("velocities", "accelerations"):
            object.__setattr__(self, name, arguments.optional_reals(getattr(self, name), name))


@dataclass(frozen=True)
class JointTrajectory:
    """Waypoints for named joints; columns follow joint_names, which may be in any order."""

    joint_names: tuple[str, ...]
    points: tuple[TrajectoryPoint, ...]

    def __post_init__(self) -> None:
        """Names as strings and points as TrajectoryPoints, in tuples; anything else is an ArgumentError."""
        names = arguments.items(self.joint_names, "joint_names", "a list of joint names")
        object.__setattr__(self, "joint_names", tuple(arguments.text(name, "a joint name") for name in names))
        points = arguments.items(self.points, "points", "a list of TrajectoryPoint")
        object.__setattr__(self, "points", tuple(
            arguments.instance(point, TrajectoryPoint, f"point {index}", "a TrajectoryPoint")
            for index, point in enumerate(points)))

    def check_times(self) -> None:
        """Refuse a point above 0 s but earlier than TIME_RESOLUTION_S, before anything is fitted to it."""
        for index, point in enumerate(self.points):
            if 0.0 < point.time_from_start < TIME_RESOLUTION_S:
                raise CommandRejected(
                    f"point {index} is {point.time_from_start:.3g} s after the start",
                    what=f"time_from_start 0 (where the arm is) or at least {TIME_RESOLUTION_S:g} s "
                         "(builtin_interfaces/Duration counts nanoseconds)",
                    why=f"point {index} has time_from_start {point.time_from_start!r} s",
                    how="send 0 for a point where the arm already is, or the time the arm may take to get there")

    @classmethod
    def from_lists(cls, joint_names: Sequence[str],
                   points: Iterable[Mapping[str, Any] | TrajectoryPoint]) -> JointTrajectory:
        """From plain lists and dicts, as scripts and JSON give them; unknown keys are rejected to catch typos."""
        if isinstance(points, (str, bytes, Mapping)) or not isinstance(points, Iterable):
            raise arguments.refused("points", "a list of points (dicts or TrajectoryPoint)", points)
        converted = []
        for index, point in enumerate(points):
            if isinstance(point, TrajectoryPoint):
                converted.append(point)
                continue
            arguments.instance(point, Mapping, f"point {index}", "a dict or a TrajectoryPoint")
            unknown = sorted(set(point) - set(POINT_KEYS))
            absent = [key for key in POINT_KEYS[:2] if key not in point]
            if unknown or absent:
                raise CommandRejected(
                    f"point {index} is not a trajectory point",
                    what=f"keys {', '.join(POINT_KEYS[:2])} and optionally {', '.join(POINT_KEYS[2:])}",
                    why="; ".join(filter(None, [f"unknown keys: {', '.join(unknown)}" if unknown else "",
                                                f"missing: {', '.join(absent)}" if absent else ""])),
                    how="spell the keys as in trajectory_msgs/JointTrajectoryPoint (effort is not supported)")
            try:
                converted.append(TrajectoryPoint(positions=point["positions"], time_from_start=point["time_from_start"],
                                                 velocities=point.get("velocities"),
                                                 accelerations=point.get("accelerations")))
            except arguments.ArgumentError as error:
                raise arguments.ArgumentError(f"point {index} holds something other than numbers: {error.summary}",
                                              what=error.what, why=error.why, how=error.how) from None
        return cls(arguments.items(joint_names, "joint_names", "a list of joint names"), tuple(converted))


@dataclass(frozen=True, eq=False)
class TrajectoryTolerances:
    """What a running trajectory is held to: per-joint path and goal position tolerances (rad), settle time, rest.

    As in joint_trajectory_controller, a tolerance of 0 (or less) leaves that joint unchecked; it is stored as
    +inf so a check is one comparison. None leaves every joint unchecked, the controller's default. A
    goal_time of 0, which ROS reads as "wait forever" (controller) or "use the default" (action goal), becomes
    DEFAULT_GOAL_TIME so that every goal ends; pass math.inf to wait forever on purpose.
    """

    path: np.ndarray | None = None
    goal: np.ndarray | None = None
    goal_time: float = DEFAULT_GOAL_TIME
    stopped_velocity_tolerance: float = 0.01

    def __post_init__(self) -> None:
        for name in ("path", "goal"):
            value = getattr(self, name)
            if value is None:
                continue
            array = np.array(arguments.reals(value, f"the {name} tolerance"), dtype=float)
            if np.isnan(array).any():
                raise CommandRejected(f"the {name} tolerance contains NaN", what="a number per joint (rad)",
                                      why=f"{name} tolerance = {array.tolist()}",
                                      how="send 0 for joints that should not be checked")
            array[array <= 0.0] = math.inf
            array.flags.writeable = False
            object.__setattr__(self, name, array)
        object.__setattr__(self, "goal_time", arguments.real(self.goal_time, "goal_time"))
        object.__setattr__(self, "stopped_velocity_tolerance",
                           arguments.real(self.stopped_velocity_tolerance, "stopped_velocity_tolerance"))
        if not self.goal_time >= 0.0:
            raise CommandRejected("the goal time tolerance is negative or NaN", what="seconds >= 0",
                                  why=f"goal_time = {self.goal_time}", how="send 0 for the default")
        if self.goal_time == 0.0:
            object.__setattr__(self, "goal_time", DEFAULT_GOAL_TIME)
        if not self.stopped_velocity_tolerance > 0.0:
            raise CommandRejected("the stopped velocity tolerance is not positive", what="rad/s > 0",
                                  why=f"stopped_velocity_tolerance = {self.stopped_velocity_tolerance}",
                                  how="leave it at the default 0.01 rad/s")


class TrajectoryOutcome(Enum):
    """How a trajectory goal ended (the action's terminal state; REJECTED means it never started)."""

    SUCCEEDED = "succeeded"
    ABORTED = "aborted"
    PREEMPTED = "preempted"
    REJECTED = "rejected"
    CANCELED = "canceled"


class ErrorCode(IntEnum):
    """control_msgs/action/FollowJointTrajectory Result.error_code values."""

    SUCCESSFUL = 0
    INVALID_GOAL = -1
    INVALID_JOINTS = -2
    OLD_HEADER_TIMESTAMP = -3
    PATH_TOLERANCE_VIOLATED = -4
    GOAL_TOLERANCE_VIOLATED = -5


@dataclass(frozen=True)
class TrajectoryResult:
    """The end of a goal: outcome, a readable message and the FollowJointTrajectory error code."""

    outcome: TrajectoryOutcome
    message: str
    error_code: int

    @classmethod
    def succeeded(cls) -> TrajectoryResult:
        """Reached the last point and settled inside the goal tolerance."""
        return cls(TrajectoryOutcome.SUCCEEDED, "goal reached", ErrorCode.SUCCESSFUL)

    @classmethod
    def rejected(cls, error: CommandRejected) -> TrajectoryResult:
        """Refused before moving: INVALID_JOINTS for joint-name problems, INVALID_GOAL for anything else."""
        code = ErrorCode.INVALID_JOINTS if isinstance(error, JointNamesRejected) else ErrorCode.INVALID_GOAL
        return cls(TrajectoryOutcome.REJECTED, error.render(), code)

    @classmethod
    def preempted(cls) -> TrajectoryResult:
        """Replaced by a newer goal; the code is INVALID_GOAL, as joint_trajectory_controller reports it."""
        return cls(TrajectoryOutcome.PREEMPTED, "goal replaced by a newer goal", ErrorCode.INVALID_GOAL)

    @classmethod
    def canceled(cls) -> TrajectoryResult:
        """Canceled by the client; the arm holds where it was."""
        return cls(TrajectoryOutcome.CANCELED, "goal canceled; holding position", ErrorCode.SUCCESSFUL)
