"""What a plan is asked for and what it gives: goals, options and the resulting plan (plain data)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from plem.control.trajectory import JointTrajectory
from plem.errors import MoveItCode, PlanningError
from plem.planning.poses import Pose

#: Default planning time (s), as MoveIt's allowed_planning_time.
PLANNING_TIME_S = 5.0
#: Longest planning time a plan or Cartesian path may ask for (s): the planner serves one request at a time.
MAX_PLANNING_TIME_S = 60.0
#: Longest time one IK request may ask for (s), and the most a kinematics.yaml timeout gives one.
MAX_IK_TIMEOUT_S = 10.0


@dataclass(frozen=True)
class JointGoal:
    """Target positions by joint name; joints left out keep their start positions."""

    positions: dict[str, float]


@dataclass(frozen=True)
class NamedGoal:
    """A named state: an SRDF group_state such as 'home' (its own spelling, or one differing only in case), or
    'zero' (see plem.planning.named_states)."""

    name: str


@dataclass(frozen=True)
class PoseGoal:
    """A pose of `link` (the group's tip when empty) in `frame` (the root link when empty): full, or position only."""

    pose: Pose
    frame: str = ""
    link: str = ""
    position_only: bool = False


Goal = JointGoal | NamedGoal | PoseGoal


@dataclass(frozen=True)
class PlanOptions:
    """How to plan: the group ('' for the first), OMPL planner, time budget and the share of the limits to use."""

    group: str = ""
    planner_id: str = ""
    timeout_s: float = PLANNING_TIME_S
    velocity_scale: float = 1.0
    acceleration_scale: float = 1.0
    avoid_collisions: bool = True


@dataclass(frozen=True)
class Plan:
    """A timed, checked motion and how it came about."""

    trajectory: JointTrajectory
    duration_s: float
    planning_time_s: float
    planner: str
    path_states: int
    path_length: float
    checked_states: int
    fraction: float = 1.0

    def summary(self) -> str:
        """One line: what the plan is and what was checked."""
        share = f", {self.fraction:.0%} of the path" if self.fraction < 1.0 else ""
        return (f"{self.planner}: {self.duration_s:.3f} s motion through {self.path_states} states "
                f"({self.path_length:.3f} rad in joint space{share}), planned in {self.planning_time_s * 1e3:.0f} ms; "
                f"{self.checked_states} states re-checked: no collision, every limit kept")


def goal_of(target: Goal | Pose | str | Sequence[float] | Mapping[str, float], joint_names: Sequence[str],
            frame: str = "") -> Goal:
    """What a user passes as a target, as a goal: a pose (in `frame`), a named state, positions in joint order or
    by name."""
    if isinstance(target, JointGoal | NamedGoal | PoseGoal):
        return target
    if isinstance(target, Pose):
        return PoseGoal(target, frame)
    if isinstance(target, str):
        return NamedGoal(target)
    if isinstance(target, Mapping):
        return JointGoal({str(name): float(value) for name, value in target.items()})
    values = [float(value) for value in target]
    if len(values) != len(joint_names):
        raise PlanningError(f"{len(values)} positions for {len(joint_names)} joints",
                            what=f"one position per joint ({', '.join(joint_names)})", why=f"got {len(values)}",
                            how="give every joint's position, or a dict of the joints to move",
                            code=MoveItCode.INVALID_GOAL_CONSTRAINTS)
    return JointGoal(dict(zip(joint_names, values, strict=True)))
