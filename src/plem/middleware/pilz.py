"""pilz_industrial_motion_planner's requests, planned by plem's sequences: the planner ids PTP, LIN and CIRC in a
MotionPlanRequest (plan_kinematic_path) and MotionSequenceRequest (plan_sequence_path).

PTP is a joint-space move to the goal (joint constraints, or a pose reached by IK); LIN a straight tool path to the
goal pose (or to the pose of a joint goal); CIRC an arc through the point of path_constraints named "interim" or
around the one named "center" (the position of its first position constraint's primitive pose), as Pilz takes
them. A sequence's items are one request each with a blend radius; only the first may give a start state.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from plem.errors import MoveItCode, PlanningError
from plem.middleware.moveit_messages import constraints_empty, goals_from_constraints, pose_from_message, refused
from plem.planning.goals import JointGoal, NamedGoal, PoseGoal
from plem.planning.planner import ITEM_IDS, Planner
from plem.planning.poses import Pose
from plem.planning.sequence import Circular, Item, Joint, Linear

#: Pilz's planner ids.
PILZ_IDS = tuple(ITEM_IDS.values())
#: The pipeline names a Pilz request may give.
PIPELINES = ("", "pilz_industrial_motion_planner")


def is_pilz(request: Any) -> bool:
    """Whether a MotionPlanRequest asks for one of Pilz's planners."""
    return str(request.planner_id) in PILZ_IDS


def pilz_item(planner: Planner, start: Sequence[float], request: Any, blend: float, where: str) -> tuple[Item, str]:
    """The sequence item of one Pilz MotionPlanRequest (its link too), from the arm at `start` (for a LIN to a joint
    goal, whose pose is the goal's FK)."""
    kind = str(request.planner_id)
    if kind not in PILZ_IDS:
        raise refused(f"{where}.planner_id {kind!r}", "a sequence's items are Pilz motions",
                      "set planner_id to PTP, LIN or CIRC", MoveItCode.INVALID_GOAL_CONSTRAINTS)
    if request.pipeline_id not in PIPELINES:
        raise refused(f"{where}.pipeline_id {request.pipeline_id!r}", "PTP, LIN and CIRC are Pilz's planners",
                      "set pipeline_id to 'pilz_industrial_motion_planner' or leave it empty")
    if request.trajectory_constraints.constraints or request.reference_trajectories:
        raise refused(f"{where}: trajectory_constraints or reference_trajectories", "Pilz's planners take neither",
                      "leave them empty")
    goals = goals_from_constraints(list(request.goal_constraints))
    if len(goals) != 1:
        raise refused(f"{where}: {len(goals)} goal_constraints entries", "a Pilz motion has one goal",
                      "give one goal_constraints entry", MoveItCode.INVALID_GOAL_CONSTRAINTS)
    goal = goals[0]
    link = goal.link if isinstance(goal, PoseGoal) else ""
    if kind != "CIRC" and not constraints_empty(request.path_constraints):
        raise refused(f"{where}.path_constraints", f"{kind} takes none (CIRC takes its interim or center point there)",
                      "leave path_constraints empty")
    if kind == "PTP":
        return Joint(_joint_target(goal), blend, goal.frame if isinstance(goal, PoseGoal) else ""), link
    pose, frame = _pose(planner, start, goal, where)
    if kind == "LIN":
        return Linear(pose, blend, frame), link
    name = str(request.path_constraints.name)
    points = request.path_constraints.position_constraints
    if name not in ("interim", "center") or len(points) != 1 or len(points[0].constraint_region.primitive_poses) != 1:
        raise PlanningError(f"{where} is a CIRC without its interim or center point",
                            what="path_constraints named 'interim' or 'center' with one position constraint whose "
                                 "constraint_region has one primitive pose: the point",
                            why=f"path_constraints.name is {name!r} with {len(points)} position constraints",
                            how="give the arc's interim (a point on it) or center as Pilz's CIRC takes it",
                            code=MoveItCode.INVALID_GOAL_CONSTRAINTS)
    point = pose_from_message(points[0].constraint_region.primitive_poses[0]).position
    return (Circular(pose, via=point, blend=blend, frame=frame) if name == "interim"
            else Circular(pose, center=point, blend=blend, frame=frame)), link


def _joint_target(goal: JointGoal | NamedGoal | PoseGoal) -> Any:
    if isinstance(goal, JointGoal):
        return dict(goal.positions)
    if isinstance(goal, NamedGoal):
        return goal.name
    return goal.pose


def _pose(planner: Planner, start: Sequence[float], goal: JointGoal | NamedGoal | PoseGoal, where: str
          ) -> tuple[Pose, str]:
    """A LIN or CIRC goal's pose and frame: a full pose goal as given, a joint goal's tool pose."""
    if isinstance(goal, PoseGoal):
        if goal.position_only:
            raise refused(f"{where}: a position without orientation", "LIN and CIRC move to a full pose",
                          "add an orientation constraint on the link", MoveItCode.INVALID_GOAL_CONSTRAINTS)
        return goal.pose, goal.frame
    positions = list(start)
    if isinstance(goal, JointGoal):
        for name, value in goal.positions.items():
            if name not in planner.joint_names:
                raise refused(f"{where}: joint {name!r}", "the goal names the arm's joints",
                              f"name joints of the arm ({', '.join(planner.joint_names)})",
                              MoveItCode.INVALID_GOAL_CONSTRAINTS)
            positions[planner.joint_names.index(name)] = value
    tip = planner.group().tip_link
    return planner.fk(positions, [tip])[tip], ""
