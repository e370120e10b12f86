"""MoveIt's messages (moveit_msgs 2.6) as plem's planning values, and plem's values as MoveIt's messages.

Robot states become joint positions in the arm's order, goal constraints plem goals, collision objects scene
objects; plans, states and scene objects become messages again. A request field plem does not support is
refused with a PlanningError that names it, carries a MoveIt error code and says what to send instead: it is
never ignored. Links are named as in the URDF (with or without the robot's tf frame prefix, or "world" for
the root); the frames of headers plem sends are tf frames (the link with the prefix).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

from plem.control.trajectory import JointTrajectory
from plem.errors import MoveItCode, PlanningError, PlemError
from plem.middleware.goals import seconds
from plem.middleware.types import InterfaceLibrary
from plem.planning.goals import Goal, JointGoal, PlanOptions, PoseGoal
from plem.planning.poses import IDENTITY, Pose
from plem.planning.protocol import MAX_PLANNING_TIME_S

#: What MoveIt errors name as their source.
SOURCE = "plem"
#: MoveIt's planning time when a request gives none (allowed_planning_time <= 0), as MoveIt's planners take it.
DEFAULT_PLANNING_TIME_S = 1.0


def refused(field: str, why: str, how: str, code: MoveItCode = MoveItCode.FAILURE, what: str = "") -> PlanningError:
    """The error for a request field (or value) plem does not support."""
    return PlanningError(f"{field} is not supported", what=what or f"a request without {field}", why=why, how=how,
                         code=code)


def error_code(library: InterfaceLibrary, error: PlemError | None = None) -> Any:
    """moveit_msgs/MoveItErrorCodes: SUCCESS, or the error's code (FAILURE for errors without one) with its
    WHAT/WHY/HOW text."""
    if error is None:
        return library.new("moveit_msgs/msg/MoveItErrorCodes", val=int(MoveItCode.SUCCESS), source=SOURCE)
    code = error.code if isinstance(error, PlanningError) else MoveItCode.FAILURE
    return library.new("moveit_msgs/msg/MoveItErrorCodes", val=int(code), message=error.render(), source=SOURCE)


# -- poses, durations ------------------------------------------------------------------------------------
def pose_from_message(message: Any) -> Pose:
    """geometry_msgs/Pose as a Pose; an all-zero quaternion (an orientation left unset) is the identity."""
    p, q = message.position, message.orientation
    orientation = (q.x, q.y, q.z, q.w) if any((q.x, q.y, q.z, q.w)) else IDENTITY
    return Pose((p.x, p.y, p.z), orientation)


def pose_message(library: InterfaceLibrary, pose: Pose) -> Any:
    """A Pose as geometry_msgs/Pose."""
    (x, y, z), (qx, qy, qz, qw) = pose.position, pose.orientation
    return library.new("geometry_msgs/msg/Pose", position=library.new("geometry_msgs/msg/Point", x=x, y=y, z=z),
                       orientation=library.new("geometry_msgs/msg/Quaternion", x=qx, y=qy, z=qz, w=qw))


def duration_message(library: InterfaceLibrary, value: float) -> Any:
    """builtin_interfaces/Duration of `value` seconds, to the nanosecond."""
    sec, nanosec = divmod(round(value * 1e9), 1_000_000_000)
    return library.new("builtin_interfaces/msg/Duration", sec=sec, nanosec=nanosec)


# -- robot states ----------------------------------------------------------------------------------------
def state_positions(state: Any, joint_names: Sequence[str], current: Callable[[], Sequence[float]],
                    what: str) -> list[float]:
    """The joint positions (arm order) of moveit_msgs/RobotState `state`: the arm's current ones for an empty
    state, those given otherwise (joints left out keep their current values)."""
    multi = state.multi_dof_joint_state
    if multi.joint_names or multi.transforms or multi.twist or multi.wrench:
        raise refused(f"{what}.multi_dof_joint_state", "the arm has no multi-DOF joints",
                      f"leave {what}.multi_dof_joint_state empty", MoveItCode.INVALID_ROBOT_STATE)
    if state.attached_collision_objects:
        raise refused(f"{what}.attached_collision_objects", "plem plans with the planning scene's attached objects",
                      "attach objects with the apply_planning_scene service (robot_state.attached_collision_objects "
                      f"of the scene), and leave {what}.attached_collision_objects empty",
                      MoveItCode.INVALID_ROBOT_STATE)
    names, values = list(state.joint_state.name), list(state.joint_state.position)
    if not names and not values:
        return [float(value) for value in current()]
    unknown = [name for name in names if name not in joint_names]
    if len(names) != len(values) or unknown or len(set(names)) != len(names):
        why = (f"unknown joints: {', '.join(unknown)}" if unknown else
               f"{len(names)} names and {len(values)} positions" if len(names) != len(values) else
               "a joint is named twice")
        raise PlanningError(f"{what} is not a state of the arm", what=f"{what}.joint_state: names of the arm's joints "
                            f"({', '.join(joint_names)}) and a position for each", why=why,
                            how=f"name each joint once with its position in {what}.joint_state, or leave it empty "
                                "for the arm's current state", code=MoveItCode.INVALID_ROBOT_STATE)
    given = dict(zip(names, map(float, values), strict=True))
    start = [0.0] * len(joint_names) if len(given) == len(joint_names) else [float(v) for v in current()]
    return [given.get(name, value) for name, value in zip(joint_names, start, strict=True)]


def state_message(library: InterfaceLibrary, joint_names: Sequence[str], positions: Sequence[float],
                  attached: Sequence[Any] = ()) -> Any:
    """moveit_msgs/RobotState of the arm at `positions`, holding `attached` (AttachedCollisionObject messages)."""
    joints = library.new("sensor_msgs/msg/JointState", name=list(joint_names), position=[float(v) for v in positions])
    return library.new("moveit_msgs/msg/RobotState", joint_state=joints, attached_collision_objects=list(attached))


# -- motion plan requests --------------------------------------------------------------------------------
def constraints_empty(constraints: Any) -> bool:
    """Whether a moveit_msgs/Constraints constrains nothing."""
    return not (constraints.joint_constraints or constraints.position_constraints
                or constraints.orientation_constraints or constraints.visibility_constraints)


def check_motion_request(request: Any) -> None:
    """Refuse what a MotionPlanRequest may ask that plem does not plan: constraints along the path, reference
    trajectories, another pipeline, a Cartesian speed limit."""
    if not constraints_empty(request.path_constraints):
        raise refused("path_constraints", "plem plans in joint space without constraints along the path",
                      "leave path_constraints empty; for a straight tool path use compute_cartesian_path")
    if request.trajectory_constraints.constraints:
        raise refused("trajectory_constraints", "plem plans to one goal at a time",
                      "leave trajectory_constraints empty and plan each segment with its own request")
    if request.reference_trajectories:
        raise refused("reference_trajectories", "plem's OMPL planners take no reference trajectory",
                      "leave reference_trajectories empty")
    if request.pipeline_id not in ("", "ompl"):
        raise refused(f"pipeline_id {request.pipeline_id!r}", "plem plans with OMPL only",
                      "set pipeline_id to 'ompl' or leave it empty")
    _check_cartesian_speed(request)


def check_cartesian_request(request: Any) -> None:
    """Refuse what a GetCartesianPath request may ask that plem does not do: path constraints, absolute jump
    thresholds, a Cartesian speed limit; and a request without waypoints."""
    if not constraints_empty(request.path_constraints):
        raise refused("path_constraints", "plem's Cartesian paths keep to the straight lines alone",
                      "leave path_constraints empty")
    if request.prismatic_jump_threshold or request.revolute_jump_threshold:
        raise refused("prismatic_jump_threshold and revolute_jump_threshold", "plem's jump threshold is relative "
                      "(jump_threshold, as in MoveIt 2)", "leave them at 0 and set jump_threshold")
    _check_cartesian_speed(request)
    if not request.waypoints:
        raise PlanningError("a Cartesian path needs waypoints", what="at least one pose in waypoints",
                            why="waypoints is empty", how="give the poses the link is to move through",
                            code=MoveItCode.INVALID_GOAL_CONSTRAINTS)


def _check_cartesian_speed(request: Any) -> None:
    if request.max_cartesian_speed > 0.0:
        raise refused("max_cartesian_speed", "plans are timed within the joint limits only",
                      "leave max_cartesian_speed at 0 and scale with max_velocity_scaling_factor")


def goals_from_constraints(constraints: Sequence[Any]) -> list[Goal]:
    """The goals of a MotionPlanRequest's goal_constraints: each entry is one goal, any of which may be reached."""
    if not constraints:
        raise PlanningError("the request has no goal", what="goal_constraints with at least one entry",
                            why="goal_constraints is empty",
                            how="give joint constraints (a joint goal) or a position and orientation constraint on "
                                "one link (a pose goal)", code=MoveItCode.INVALID_GOAL_CONSTRAINTS)
    return [_goal(entry, f"goal_constraints[{index}]") for index, entry in enumerate(constraints)]


def _goal(constraints: Any, where: str) -> Goal:
    def invalid(why: str, how: str) -> PlanningError:
        return PlanningError(f"{where} is not a goal plem plans to",
                             what="joint constraints alone, or one position constraint (and at most one orientation "
                                  "constraint) on one link", why=why, how=how,
                             code=MoveItCode.INVALID_GOAL_CONSTRAINTS)

    if constraints.visibility_constraints:
        raise invalid("it has visibility constraints, which plem does not plan to",
                      f"leave {where}.visibility_constraints empty")
    joints, positions, orientations = (constraints.joint_constraints, constraints.position_constraints,
                                       constraints.orientation_constraints)
    if joints and (positions or orientations):
        raise invalid("it mixes joint constraints with position or orientation constraints",
                      "give a joint goal or a pose goal in each goal_constraints entry")
    if joints:
        return JointGoal({joint.joint_name: float(joint.position) for joint in joints})
    if len(positions) != 1 or len(orientations) > 1:
        raise invalid(f"{len(positions)} position and {len(orientations)} orientation constraints",
                      "constrain one link with one position constraint and at most one orientation constraint")
    target = positions[0]
    offset = target.target_point_offset
    if any((offset.x, offset.y, offset.z)):
        raise invalid("target_point_offset is not zero",
                      "give the target of the link's origin (offset 0), or constrain a link at the point, such as the "
                      "tool frame")
    region = target.constraint_region
    if len(region.primitive_poses) != 1:
        raise invalid(f"the constraint region has {len(region.primitive_poses)} primitive poses",
                      "give one primitive (e.g. a small sphere) whose pose is the target position")
    position = pose_from_message(region.primitive_poses[0]).position
    if not orientations:
        return PoseGoal(Pose(position), target.header.frame_id, target.link_name, position_only=True)
    turn = orientations[0]
    if turn.link_name != target.link_name or turn.header.frame_id != target.header.frame_id:
        raise invalid("the orientation constraint names another link or frame than the position constraint",
                      "give both constraints the same link_name and header.frame_id")
    q = turn.orientation
    return PoseGoal(Pose(position, (q.x, q.y, q.z, q.w)), target.header.frame_id, target.link_name)


def scaling(value: float, name: str) -> tuple[float, str]:
    """A scaling factor as MoveIt takes it: the value in (0, 1], anything else 1.0 (and a warning unless 0, the
    value of a field left unset)."""
    if 0.0 < value <= 1.0:
        return float(value), ""
    warning = "" if value == 0.0 else f"{name} {value} is not in (0, 1]; 1.0 is used, as MoveIt does"
    return 1.0, warning


def plan_options(request: Any, planning_time: float, avoid_collisions: bool = True) -> tuple[PlanOptions, list[str]]:
    """The PlanOptions of a MotionPlanRequest or GetCartesianPath request, and warnings about its values."""
    velocity, slow = scaling(request.max_velocity_scaling_factor, "max_velocity_scaling_factor")
    acceleration, soft = scaling(request.max_acceleration_scaling_factor, "max_acceleration_scaling_factor")
    timeout = planning_time if planning_time > 0.0 else DEFAULT_PLANNING_TIME_S
    if not timeout <= MAX_PLANNING_TIME_S:
        raise PlanningError("allowed_planning_time is too long", what=f"at most {MAX_PLANNING_TIME_S:g} s",
                            why=f"allowed_planning_time is {planning_time}",
                            how=f"set allowed_planning_time to {MAX_PLANNING_TIME_S:g} s or less",
                            code=MoveItCode.FAILURE)
    options = PlanOptions(request.group_name, getattr(request, "planner_id", ""), timeout, velocity, acceleration,
                          avoid_collisions)
    return options, [warning for warning in (slow, soft) if warning]


def trajectory_message(library: InterfaceLibrary, trajectory: JointTrajectory, frame_id: str) -> Any:
    """moveit_msgs/RobotTrajectory of a plan's trajectory: every point with positions, velocities, accelerations
    and its time, starting on receipt (header stamp 0)."""
    new = library.new
    points = [new("trajectory_msgs/msg/JointTrajectoryPoint", positions=list(point.positions),
                  velocities=list(point.velocities or ()), accelerations=list(point.accelerations or ()),
                  time_from_start=duration_message(library, point.time_from_start))
              for point in trajectory.points]
    joints = new("trajectory_msgs/msg/JointTrajectory", header=new("std_msgs/msg/Header", frame_id=frame_id),
                 joint_names=list(trajectory.joint_names), points=points)
    return new("moveit_msgs/msg/RobotTrajectory", joint_trajectory=joints)


# -- collision objects -----------------------------------------------------------------------------------


def timeout_of(duration: Any) -> float | None:
    """An IK request's timeout in seconds; None (kinematics.yaml's) when it is 0."""
    value = seconds(duration)
    return value if value > 0.0 else None


# -- planning scene changes ----------------------------------------------------------------------------
