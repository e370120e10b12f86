"""MoveIt's ROS 2 services and execute_trajectory action, answered by plem's planner under `/{robot_id}/`.

compute_ik, compute_fk, plan_kinematic_path, compute_cartesian_path, apply_planning_scene,
get_planning_scene and plan_sequence_path (pilz_industrial_motion_planner's sequence capability) take and give
moveit_msgs types, as move_group serves them; plan_kinematic_path plans Pilz's planner ids PTP, LIN and CIRC as
plem's sequences (plem.middleware.pilz), any other with OMPL; the node that holds them is
announced as `/{robot_id}/move_group`. Every call runs on the planner through `PlannerService.call`, one at a
time with plem's own clients. A request plem cannot serve as asked is answered with a MoveIt error code and the
WHAT/WHY/HOW text in `error_code.message`, and logged (to /rosout too); apply_planning_scene, whose reply holds
only `success`, is logged alone. execute_trajectory runs a trajectory through the robot client's
`execute_trajectory`, the command path every client uses, so the RT driver checks (and re-times) it as any other.

What plem does with MoveIt's options:
- scaling factors in (0, 1] scale the limits; any other value means 1.0, as in MoveIt;
- allowed_planning_time <= 0 means 1 s, as in MoveIt;
- num_planning_attempts (at least 1): plans are made up to that many times within allowed_planning_time and the
  fastest is returned (MoveIt runs them in parallel and keeps the best); a goal that fails is not tried again,
  as the planner already retries a plan whose dense re-check fails;
- several goal_constraints entries are alternatives: each is planned and the fastest plan returned;
- workspace_parameters bound MoveIt's sampling of floating joints only, which a fixed arm has none of.
The planning scene holds one shape per object, its pose being the shape's (in the root frame for world objects,
in the link's for attached ones); ADD, REMOVE, APPEND (to a new object), MOVE, attach and detach are applied
together or not at all.
"""

from __future__ import annotations

import dataclasses
import logging
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any

from cyclonedds.util import duration

from plem.bridge.client import RobotClient
from plem.errors import MoveItCode, PlanningError, PlemError
from plem.middleware.action import CANCELED, SUCCEEDED, ActionServer, Execution
from plem.middleware.goals import Finished, TrajectoryGoal, rejected_trajectory, trajectory_from_message
from plem.middleware.moveit_messages import (
    SOURCE,
    check_cartesian_request,
    check_motion_request,
    constraints_empty,
    error_code,
    goals_from_constraints,
    plan_options,
    pose_from_message,
    pose_message,
    refused,
    state_message,
    state_positions,
    timeout_of,
    trajectory_message,
)
from plem.middleware.moveit_scene import (
    ATTACHED_OBJECTS,
    OBJECT_COLORS,
    OBJECT_GEOMETRY,
    OBJECT_NAMES,
    ROBOT_STATE,
    SCENE_SETTINGS,
    apply_scene,
    check_scene_message,
    collision_object_message,
    frame_placement,
)
from plem.middleware.node import Node, ServiceServer
from plem.middleware.node_graph import NodeGraph, RosoutHandler
from plem.middleware.pilz import is_pilz, pilz_item
from plem.middleware.types import InterfaceLibrary
from plem.planning.goals import Goal, Plan, PlanOptions
from plem.planning.planner import Planner
from plem.planning.scene import WORLD
from plem.planning.service import PlannerService

_log = logging.getLogger("plem.planner.moveit")
EXECUTE = "moveit_msgs/action/ExecuteTrajectory"
#: The services, by name, with their moveit_msgs service type.
SERVICES = {"compute_ik": "GetPositionIK", "compute_fk": "GetPositionFK", "plan_kinematic_path": "GetMotionPlan",
            "compute_cartesian_path": "GetCartesianPath", "apply_planning_scene": "ApplyPlanningScene",
            "get_planning_scene": "GetPlanningScene", "plan_sequence_path": "GetMotionSequence"}
#: What execute_trajectory's result code is for each way the motion ended.
EXECUTION_CODES = {SUCCEEDED: MoveItCode.SUCCESS, CANCELED: MoveItCode.PREEMPTED}


class _Execution:
    """A running execute_trajectory goal: the trajectory goal plem runs, its end told as MoveIt tells it."""

    def __init__(self, goal: TrajectoryGoal | Finished, library: InterfaceLibrary) -> None:
        self.goal = goal
        self.library = library

    def poll(self) -> tuple[dict[str, Any] | None, tuple[int, dict[str, Any]] | None]:
        """Feedback 'MONITOR' (move_group's state while a motion runs); the end as SUCCESS, PREEMPTED or
        CONTROL_FAILED, with the reason."""
        _, end = self.goal.poll()
        if end is None:
            return {"state": "MONITOR"}, None
        status, result = end
        code = EXECUTION_CODES.get(status, MoveItCode.CONTROL_FAILED)
        if code is MoveItCode.CONTROL_FAILED:
            _log.warning("execute_trajectory: %s", result["error_string"])
        library = self.library
        return None, (status, {"error_code": library.new(
            "moveit_msgs/msg/MoveItErrorCodes", val=int(code), message=result["error_string"], source=SOURCE)})

    def cancel(self) -> bool:
        """Stop the arm smoothly (the driver's jerk-limited stop)."""
        return self.goal.cancel()


@dataclasses.dataclass
class _SceneExtras:
    """What MoveIt's scene holds besides shapes, kept here for get_planning_scene: its name, colors and types."""

    name: str = ""
    colors: dict[str, Any] = dataclasses.field(default_factory=dict)
    types: dict[str, Any] = dataclasses.field(default_factory=dict)


class MoveItServices:
    """MoveIt's planning services and execute_trajectory action for one robot, under `namespace`."""

    def __init__(self, node: Node, service: PlannerService, client: RobotClient, namespace: str, *,
                 trajectory_controller: str, robot_model: str) -> None:
        self.node = node
        self.library = node.library
        self.service = service
        self.client = client
        self.namespace = namespace
        self.trajectory_controller = trajectory_controller
        self.robot_model = robot_model
        self.extras = _SceneExtras()
        self.servers = {name: node.service(f"{namespace}/{name}", f"moveit_msgs/srv/{kind}")
                        for name, kind in SERVICES.items()}
        self.execute = ActionServer(node, f"{namespace}/execute_trajectory", EXECUTE, self._start_execution)
        new = self.library.new
        self._handlers: dict[str, tuple[Callable[[Any], dict[str, Any]], Callable[[Any], dict[str, Any]]]] = {
            "compute_ik": (self._ik, lambda code: {"error_code": code}),
            "compute_fk": (self._fk, lambda code: {"error_code": code}),
            "plan_kinematic_path": (self._plan, lambda code: {"motion_plan_response": new(
                "moveit_msgs/msg/MotionPlanResponse", error_code=code)}),
            "compute_cartesian_path": (self._cartesian, lambda code: {"error_code": code}),
            "apply_planning_scene": (self._apply_scene, lambda code: {"success": False}),
            "get_planning_scene": (self._get_scene, lambda code: {}),
            "plan_sequence_path": (self._sequence, lambda code: {"response": new(
                "moveit_msgs/msg/MotionSequenceResponse", error_code=code)}),
        }
        self.graph = NodeGraph(node)
        move_group = self.graph.add(namespace, "move_group", *self.servers.values(), self.execute)
        self._rosout = RosoutHandler(self.graph, move_group)
        _log.addHandler(self._rosout)
        self.graph.announce()

    # -- serving ----------------------------------------------------------------------------------------
    def spin_services(self, stop: threading.Event, period: float = 0.05) -> None:
        """Answer the planning services until `stop` (one request at a time; a plan may take seconds)."""
        waitset = self.node.waitset(self.servers.values())
        while not stop.is_set():
            waitset.wait(duration(seconds=period))
            try:
                for name, server in self.servers.items():
                    for request in server.take():
                        self._answer(name, server, request)
                    server.flush()
            except Exception as error:  # noqa: BLE001 - one bad request must not end the services for everyone
                _log.error("a MoveIt service request could not be answered (%s: %s); serving goes on",
                           type(error).__name__, error)

    def spin_execution(self, stop: threading.Event, period: float = 0.01) -> None:
        """Serve execute_trajectory until `stop`: goals, cancels, results and feedback."""
        waitset = self.node.waitset(self.execute.services)
        while not stop.is_set():
            waitset.wait(duration(seconds=period))
            try:
                self.execute.spin_once()
            except Exception as error:  # noqa: BLE001 - one bad goal must not end execution for everyone
                _log.error("an execute_trajectory request could not be handled (%s: %s); serving goes on",
                           type(error).__name__, error)

    def close(self) -> None:
        """Stop sending log records to /rosout (before the node closes)."""
        _log.removeHandler(self._rosout)

    def _answer(self, name: str, server: ServiceServer, request: Any) -> None:
        """Reply to one request: its answer, or its failure with the error code and message."""
        handle, fail = self._handlers[name]
        try:
            fields = handle(request)
        except PlemError as error:
            _log.warning("%s: %s", name, error.log_text())
            fields = fail(error_code(self.library, error))
        except Exception as error:  # noqa: BLE001 - a request that trips over a bug is answered, not dropped
            _log.error("%s failed (%s: %s)", name, type(error).__name__, error)
            fields = fail(error_code(self.library, PlanningError(
                f"{name} failed", what="an answer", why=f"{type(error).__name__}: {error}"[:300],
                how="report this with the request that caused it", code=MoveItCode.FAILURE)))
        server.reply(request, **fields)

    def _current(self) -> list[float]:
        """The arm's joint positions now, in its joint order."""
        return [float(value) for value in self.client.live_state().position]

    def _frame(self, planner: Planner, link: str = "") -> str:
        """The tf frame of a link (the root link for ''), as headers name frames."""
        return planner.frame_prefix + (link or planner.root_link)

    # -- kinematics -------------------------------------------------------------------------------------
    def _ik(self, request: Any) -> dict[str, Any]:
        ik = request.ik_request
        if not constraints_empty(ik.constraints):
            raise refused("ik_request.constraints", "plem's IK solves for the pose alone",
                          "leave constraints empty and check the solution yourself")
        poses, links = list(ik.pose_stamped_vector), list(ik.ik_link_names)
        if len(poses) > 1 or (links and len(links) != len(poses)):
            raise refused("several IK links (ik_link_names, pose_stamped_vector)", "plem solves for one link's pose",
                          "give one pose in pose_stamped and its link in ik_link_name",
                          MoveItCode.INVALID_LINK_NAME)
        target = poses[0] if poses else ik.pose_stamped
        link = links[0] if links else ik.ik_link_name
        pose = pose_from_message(target.pose)

        def solve(planner: Planner) -> tuple[tuple[str, ...], Any]:
            seed = state_positions(ik.robot_state, planner.joint_names, self._current, "ik_request.robot_state")
            return planner.joint_names, planner.ik(pose, seed, frame=target.header.frame_id, group=ik.group_name,
                                                   link=link, timeout_s=timeout_of(ik.timeout),
                                                   avoid_collisions=ik.avoid_collisions)

        names, solution = self.service.call(solve)
        return {"solution": state_message(self.library, names, solution), "error_code": error_code(self.library)}

    def _fk(self, request: Any) -> dict[str, Any]:
        links = list(request.fk_link_names)
        if not links:
            raise PlanningError("no links to give poses of", what="fk_link_names: links of the URDF",
                                why="fk_link_names is empty", how="name the links whose poses you want",
                                code=MoveItCode.INVALID_LINK_NAME)
        frame = request.header.frame_id

        def compute(planner: Planner) -> tuple[dict[str, Any], list[str], str]:
            positions = state_positions(request.robot_state, planner.joint_names, self._current, "robot_state")
            frame_placement(planner, positions, frame)  # an unknown frame is FRAME_TRANSFORM_FAILURE
            known, unknown = [], []
            for link in links:
                try:
                    planner.link_name(link)
                    known.append(link)
                except PlanningError:
                    unknown.append(link)
            return planner.fk(positions, known, frame), unknown, frame or self._frame(planner)

        poses, unknown, frame_id = self.service.call(compute)
        new = self.library.new
        header = new("std_msgs/msg/Header", stamp=self.library.stamp(), frame_id=frame_id)
        code = error_code(self.library)
        if unknown:
            code = error_code(self.library, PlanningError(
                "unknown links in fk_link_names", what="links of the URDF", why=f"unknown: {', '.join(unknown)}",
                how="name links of the robot's URDF (the poses of the others are given)",
                code=MoveItCode.INVALID_LINK_NAME))
            _log.warning("compute_fk: %s", code.message)
        return {"pose_stamped": [new("geometry_msgs/msg/PoseStamped", header=header,
                                     pose=pose_message(self.library, pose)) for pose in poses.values()],
                "fk_link_names": list(poses), "error_code": code}

    # -- planning ---------------------------------------------------------------------------------------
    def _plan(self, request: Any) -> dict[str, Any]:
        motion = request.motion_plan_request
        if is_pilz(motion):
            return {"motion_plan_response": self._pilz(motion)}
        check_motion_request(motion)
        goals = goals_from_constraints(list(motion.goal_constraints))
        options, warnings = plan_options(motion, motion.allowed_planning_time)
        for warning in warnings:
            _log.warning("plan_kinematic_path: %s", warning)
        attempts = max(1, motion.num_planning_attempts)

        def plan(planner: Planner) -> Any:
            start = state_positions(motion.start_state, planner.joint_names, self._current, "start_state")
            best = fastest_plan(planner, start, goals, options, attempts)
            return self.library.new(
                "moveit_msgs/msg/MotionPlanResponse",
                trajectory_start=state_message(self.library, planner.joint_names, start),
                group_name=planner.group(options.group).name,
                trajectory=trajectory_message(self.library, best.trajectory, self._frame(planner)),
                planning_time=best.planning_time_s, error_code=error_code(self.library))

        return {"motion_plan_response": self.service.call(plan)}

    def _pilz(self, motion: Any) -> Any:
        """A MotionPlanRequest for Pilz's PTP, LIN or CIRC, planned as a sequence of one item."""
        options, warnings = plan_options(motion, motion.allowed_planning_time)
        for warning in warnings:
            _log.warning("plan_kinematic_path: %s", warning)

        def plan(planner: Planner) -> Any:
            start = state_positions(motion.start_state, planner.joint_names, self._current, "start_state")
            item, link = pilz_item(planner, start, motion, 0.0, "motion_plan_request")
            found = planner.sequence(start, [item], link=link, options=options)
            return self.library.new(
                "moveit_msgs/msg/MotionPlanResponse",
                trajectory_start=state_message(self.library, planner.joint_names, start),
                group_name=planner.group(options.group).name,
                trajectory=trajectory_message(self.library, found.trajectory, self._frame(planner)),
                planning_time=found.planning_time_s, error_code=error_code(self.library))

        return self.service.call(plan)

    def _sequence(self, request: Any) -> dict[str, Any]:
        """pilz_industrial_motion_planner's plan_sequence_path: the items planned as one blended sequence."""
        items = list(request.request.items)
        if not items:
            raise PlanningError("the sequence is empty", what="request.items with at least one item",
                                why="request.items is empty", how="give the motions to plan, one item each",
                                code=MoveItCode.INVALID_GOAL_CONSTRAINTS)
        first = items[0].req
        for index, item in enumerate(items[1:], 1):
            if item.req.start_state.joint_state.name:
                raise refused(f"request.items[{index}].req.start_state", "each motion starts where the one before "
                              "ends; only the first item may give a start state", "leave it empty",
                              MoveItCode.INVALID_ROBOT_STATE)
        options, warnings = plan_options(first, first.allowed_planning_time)
        for warning in warnings:
            _log.warning("plan_sequence_path: %s", warning)

        def plan(planner: Planner) -> Any:
            start = state_positions(first.start_state, planner.joint_names, self._current,
                                    "request.items[0].req.start_state")
            converted = [pilz_item(planner, start, item.req, float(item.blend_radius), f"request.items[{index}].req")
                         for index, item in enumerate(items)]
            links = sorted({link for _, link in converted if link})
            if len(links) > 1:
                raise refused(f"goals on links {', '.join(links)}", "a sequence moves one link",
                              "constrain the same link in every item", MoveItCode.INVALID_LINK_NAME)
            found = planner.sequence(start, [item for item, _ in converted], link=links[0] if links else "",
                                     options=options)
            return self.library.new(
                "moveit_msgs/msg/MotionSequenceResponse", error_code=error_code(self.library),
                sequence_start=state_message(self.library, planner.joint_names, start),
                planned_trajectories=[trajectory_message(self.library, found.trajectory, self._frame(planner))],
                planning_time=found.planning_time_s)

        return {"response": self.service.call(plan)}

    def _cartesian(self, request: Any) -> dict[str, Any]:
        check_cartesian_request(request)
        waypoints = [pose_from_message(pose) for pose in request.waypoints]
        options, warnings = plan_options(request, 0.0, request.avoid_collisions)
        for warning in warnings:
            _log.warning("compute_cartesian_path: %s", warning)

        def follow(planner: Planner) -> tuple[Any, Plan, str]:
            start = state_positions(request.start_state, planner.joint_names, self._current, "start_state")
            plan = planner.cartesian(start, waypoints, frame=request.header.frame_id, link=request.link_name,
                                     max_step=request.max_step, jump_threshold=request.jump_threshold,
                                     options=options)
            return state_message(self.library, planner.joint_names, start), plan, self._frame(planner)

        start_state, plan, frame = self.service.call(follow)
        return {"start_state": start_state, "solution": trajectory_message(self.library, plan.trajectory, frame),
                "fraction": plan.fraction, "error_code": error_code(self.library)}

    # -- the planning scene -----------------------------------------------------------------------------
    def _apply_scene(self, request: Any) -> dict[str, Any]:
        message = request.scene
        check_scene_message(message)
        self.service.call(lambda planner: apply_scene(planner, self._current(), message))
        extras = self.extras if message.is_diff else _SceneExtras()
        extras.name = message.name or extras.name
        extras.colors.update({color.id: color.color for color in message.object_colors})
        extras.types.update({change.id: change.type for change in message.world.collision_objects
                             if change.type.key or change.type.db})
        self.extras = extras
        return {"success": True}

    def _get_scene(self, request: Any) -> dict[str, Any]:
        components = int(request.components.components)
        extras, library = self.extras, self.library

        def read(planner: Planner) -> dict[str, Any]:
            objects = planner.scene.objects()
            fields: dict[str, Any] = {"is_diff": False}
            if components & SCENE_SETTINGS:
                fields.update(name=extras.name, robot_model_name=self.robot_model)
            if components & (ROBOT_STATE | ATTACHED_OBJECTS):
                attached = [library.new(
                    "moveit_msgs/msg/AttachedCollisionObject", link_name=obj.attached_to,
                    touch_links=list(obj.touch_links), object=collision_object_message(
                        library, obj, self._frame(planner, obj.attached_to), object_type=extras.types.get(obj.name)))
                    for obj in objects if obj.attached_to is not None and components & ATTACHED_OBJECTS]
                fields["robot_state"] = state_message(library, planner.joint_names, self._current(), attached)
            if components & (OBJECT_NAMES | OBJECT_GEOMETRY):
                world = [collision_object_message(
                    library, obj, self._frame(planner, "" if obj.frame == WORLD else obj.frame),
                    geometry=bool(components & OBJECT_GEOMETRY), object_type=extras.types.get(obj.name))
                    for obj in objects if obj.attached_to is None]
                fields["world"] = library.new("moveit_msgs/msg/PlanningSceneWorld", collision_objects=world)
            if components & OBJECT_COLORS:
                fields["object_colors"] = [library.new("moveit_msgs/msg/ObjectColor", id=obj.name,
                                                       color=extras.colors[obj.name])
                                           for obj in objects if obj.name in extras.colors]
            return fields

        return {"scene": library.new("moveit_msgs/msg/PlanningScene", **self.service.call(read))}

    # -- execution --------------------------------------------------------------------------------------
    def _start_execution(self, goal: Any) -> Execution:
        """Run an ExecuteTrajectory goal through the robot client, or end it at once with why it cannot run."""
        try:
            unknown = [name for name in goal.controller_names if name != self.trajectory_controller]
            if unknown:
                raise refused(f"controllers {', '.join(unknown)}", f"plem runs trajectories through "
                              f"{self.trajectory_controller} alone", "leave controller_names empty",
                              MoveItCode.CONTROL_FAILED)
            if goal.trajectory.multi_dof_joint_trajectory.points:
                raise refused("multi_dof_joint_trajectory", "the arm has no multi-DOF joints",
                              "leave trajectory.multi_dof_joint_trajectory empty", MoveItCode.CONTROL_FAILED)
            client = self.client
            trajectory = trajectory_from_message(goal.trajectory.joint_trajectory)
            return _Execution(TrajectoryGoal(client, client.execute_trajectory(trajectory), self.library),
                              self.library)
        except PlemError as error:
            return _Execution(rejected_trajectory(error), self.library)


def fastest_plan(planner: Planner, start: Sequence[float], goals: Sequence[Goal], options: PlanOptions,
                 attempts: int) -> Plan:
    """The fastest of up to `attempts` plans to each of `goals` within the options' planning time; a goal that
    fails is not tried again. Raises the first failure when no plan is found."""
    began = time.perf_counter()
    best: Plan | None = None
    failed: dict[int, PlanningError] = {}
    for _ in range(attempts):
        for index, goal in enumerate(goals):
            remaining = options.timeout_s - (time.perf_counter() - began)
            if index in failed or remaining <= 0.0:
                continue
            try:
                plan = planner.plan(start, goal, dataclasses.replace(options, timeout_s=remaining))
            except PlanningError as error:
                failed[index] = error
                continue
            if best is None or plan.duration_s < best.duration_s:
                best = plan
    if best is None:
        raise next(iter(failed.values()), None) or PlanningError(
            "no time was left to plan", what=f"a plan within {options.timeout_s:g} s", why="the time ran out",
            how="allow more planning time (allowed_planning_time)", code=MoveItCode.TIMED_OUT)
    return dataclasses.replace(best, planning_time_s=time.perf_counter() - began)
