"""The JSON forms of planning requests and results, as clients and the planner process exchange them."""

from __future__ import annotations

import math
from typing import Any

from plem.control.trajectory import JointTrajectory
from plem.errors import MoveItCode, PlanningError
from plem.planning.goals import MAX_PLANNING_TIME_S, Goal, JointGoal, NamedGoal, Plan, PlanOptions, PoseGoal
from plem.planning.poses import Pose

__all__ = ["MAX_PLANNING_TIME_S", "flag", "goal_from_json", "goal_json", "number", "options_from_json", "options_json",
           "plan_from_json", "plan_json", "text"]


def _invalid(summary: str, what: str, why: str) -> PlanningError:
    return PlanningError(summary, what=what, why=why, how="send the field as WHAT says (plem's client and CLI do)",
                         code=MoveItCode.INVALID_GOAL_CONSTRAINTS)


def goal_json(goal: Goal) -> dict[str, Any]:
    """A goal as JSON: {'joints': {...}}, {'named': 'home'} or {'pose': {...}, 'link': ..., 'position_only': ...}."""
    if isinstance(goal, JointGoal):
        return {"joints": dict(goal.positions)}
    if isinstance(goal, NamedGoal):
        return {"named": goal.name}
    return {"pose": goal.pose.to_json(), "frame": goal.frame, "link": goal.link, "position_only": goal.position_only}


def goal_from_json(value: Any) -> Goal:
    """The inverse of `goal_json`; anything else raises PlanningError."""
    if isinstance(value, dict) and isinstance(value.get("joints"), dict):
        joints = value["joints"]
        if not all(isinstance(k, str) and isinstance(v, int | float) and math.isfinite(v) for k, v in joints.items()):
            raise _invalid("joint goals must be finite numbers by joint name", "{joint: rad, ...}", repr(joints)[:200])
        return JointGoal({k: float(v) for k, v in joints.items()})
    if isinstance(value, dict) and isinstance(value.get("named"), str):
        return NamedGoal(value["named"])
    if isinstance(value, dict) and "pose" in value:
        return PoseGoal(Pose.from_json(value["pose"]), text(value, "frame"), text(value, "link"),
                        flag(value, "position_only", False))
    raise _invalid("the goal is not understood", "joints, named or pose", repr(value)[:200])


def options_json(options: PlanOptions) -> dict[str, Any]:
    """Planning options as JSON."""
    return {"group": options.group, "planner_id": options.planner_id, "timeout_s": options.timeout_s,
            "velocity_scale": options.velocity_scale, "acceleration_scale": options.acceleration_scale,
            "avoid_collisions": options.avoid_collisions}


def options_from_json(value: Any) -> PlanOptions:
    """Planning options from JSON (absent keys keep their defaults); out-of-range values raise PlanningError."""
    if value is None:
        value = {}
    if not isinstance(value, dict):
        raise _invalid("the planning options are not an object", "options as {timeout_s: s, velocity_scale: ...}",
                       f"got {type(value).__name__}")
    defaults = PlanOptions()
    timeout = number(value, "timeout_s", defaults.timeout_s, 0.0, MAX_PLANNING_TIME_S)
    velocity = number(value, "velocity_scale", 1.0, 0.0, 1.0)
    acceleration = number(value, "acceleration_scale", 1.0, 0.0, 1.0)
    return PlanOptions(text(value, "group"), text(value, "planner_id"), timeout, velocity, acceleration,
                       flag(value, "avoid_collisions", True))


def text(value: dict[str, Any], key: str) -> str:
    """A text field of a request ('' when absent); anything but text raises PlanningError."""
    found = value.get(key, "")
    if not isinstance(found, str) or len(found) > 1000:
        raise _invalid(f"{key} is not a name", "a name (text)", f"{key} = {str(found)[:80]}")
    return found


def flag(value: dict[str, Any], key: str, default: bool) -> bool:
    """A yes/no field of a request (`default` when absent); anything but true or false raises PlanningError."""
    found = value.get(key, default)
    if not isinstance(found, bool):
        raise _invalid(f"{key} is not true or false", f"{key}: true or false", f"{key} = {str(found)[:80]}")
    return found


def number(value: dict[str, Any], key: str, default: float, low: float, high: float, *,
           low_included: bool = False) -> float:
    """A number of a request in (low, high], or [low, high] with `low_included` (`default` when absent); anything
    else raises PlanningError."""
    found = value.get(key, default)
    bounds = f"{'[' if low_included else '('}{low:g}, {high:g}]"
    if isinstance(found, bool) or not isinstance(found, int | float):
        raise _invalid(f"{key} is not a number", f"{key}: a number in {bounds}",
                       f"{key} = {str(found)[:80]} ({type(found).__name__})")
    inside = low <= found <= high if low_included else low < found <= high
    if not inside:
        raise PlanningError(f"{key} is out of range", what=f"{key} in {bounds}", why=f"{key} = {found!r}"[:200],
                            how=f"set {key} between {low:g} and {high:g}", code=MoveItCode.INVALID_GOAL_CONSTRAINTS)
    return float(found)


def plan_json(plan: Plan) -> dict[str, Any]:
    """A plan as JSON: its trajectory's points and what was measured and checked."""
    return {"joint_names": list(plan.trajectory.joint_names),
            "points": [{"positions": list(p.positions), "velocities": list(p.velocities or ()),
                        "accelerations": list(p.accelerations or ()), "time_from_start": p.time_from_start}
                       for p in plan.trajectory.points],
            "duration_s": plan.duration_s, "planning_time_s": plan.planning_time_s, "planner": plan.planner,
            "path_states": plan.path_states, "path_length": plan.path_length,
            "checked_states": plan.checked_states, "fraction": plan.fraction}


def plan_from_json(value: dict[str, Any]) -> Plan:
    """The inverse of `plan_json`."""
    trajectory = JointTrajectory.from_lists(value["joint_names"], value["points"])
    return Plan(trajectory, float(value["duration_s"]), float(value["planning_time_s"]), str(value["planner"]),
                int(value["path_states"]), float(value["path_length"]), int(value["checked_states"]),
                float(value["fraction"]))
