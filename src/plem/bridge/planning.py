"""A client's link to its robot's planner process: plans, IK, FK and the planning scene.

Requests and answers travel as JSON frames on `/dev/shm/{robot_id}_planner`, one request at a time per
client. Errors come back as PlanningError with MoveIt's error code; a planner working on another client's
request answers at once that it is busy. A request whose answer does not come in time is given up: the
connection closes, which cancels it in the planner. Plans are executed by the client itself through the
robot's command path, never by the planner.
"""

from __future__ import annotations

import json
import socket
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

from plem.control.trajectory import TrajectoryTolerances
from plem.errors import MoveItCode, PlanningError
from plem.ipc import command_socket
from plem.ipc.command_socket import CommandSocketError, FrameReader, frame
from plem.ipc.requests import new_request_id
from plem.planning.goals import Goal, Plan, PlanOptions, goal_of
from plem.planning.poses import Pose
from plem.planning.protocol import goal_json, options_json, plan_from_json
from plem.planning.scene import PlanningScene, SceneObject
from plem.planning.sequence import Circular, Item, Linear, ToolLimits, item_json

if TYPE_CHECKING:
    from plem.planning.service import PlannerService

#: Largest answer accepted from the planner (a long plan's points).
MAX_ANSWER_BYTES = 64 << 20
#: Time an answer may take beyond the planning time asked for.
ANSWER_MARGIN_S = 30.0


class PlannerLink:
    """A blocking connection to a robot's planner; thread-safe (requests are serialised)."""

    def __init__(self, robot_id: str) -> None:
        self.robot_id = robot_id
        self._socket: socket.socket | None = None
        self._reader = FrameReader(MAX_ANSWER_BYTES)
        self._lock = threading.Lock()

    def request(self, op: str, wait_s: float = ANSWER_MARGIN_S, **args: Any) -> Any:
        """Send one request and wait for its answer's result; its error is raised as PlanningError."""
        request_id = new_request_id()
        with self._lock:
            try:
                connection = self._connection()
            except CommandSocketError as error:
                raise PlanningError(f"robot '{self.robot_id}' has no planner running", what=error.what,
                                    why=error.why, how=error.how, code=MoveItCode.FAILURE) from None
            try:
                connection.sendall(frame(json.dumps({"id": request_id, "op": op, **args}).encode()))
                answer = _read_answer(connection, self._reader, request_id, wait_s)
            except (OSError, CommandSocketError) as error:
                self._close()  # a request still running in the planner is cancelled by this
                raise _no_answer(wait_s, error) from None
        if answer.get("error") is not None:
            raise _error(answer["error"])
        return answer.get("result")

    def cancel(self) -> str | None:
        """Cancel the request the planner is working on (this client's or another's), on a connection of its own;
        what it was, or None when it was idle."""
        try:
            connection = command_socket.connect(self.robot_id, service="planner")
        except CommandSocketError as error:
            raise PlanningError(f"robot '{self.robot_id}' has no planner running", what=error.what,
                                why=error.why, how=error.how, code=MoveItCode.FAILURE) from None
        with connection:
            request_id = new_request_id()
            try:
                connection.sendall(frame(json.dumps({"id": request_id, "op": "cancel"}).encode()))
                answer = _read_answer(connection, FrameReader(MAX_ANSWER_BYTES), request_id, ANSWER_MARGIN_S)
            except (OSError, CommandSocketError) as error:
                raise _no_answer(ANSWER_MARGIN_S, error) from None
        cancelled: str | None = (answer.get("result") or {}).get("cancelled")
        return cancelled

    def close(self) -> None:
        """Drop the connection (the planner runs on)."""
        with self._lock:
            self._close()

    def _connection(self) -> socket.socket:
        if self._socket is None:
            self._socket = command_socket.connect(self.robot_id, service="planner")
            self._socket.setblocking(True)
            self._reader = FrameReader(MAX_ANSWER_BYTES)
        return self._socket

    def _close(self) -> None:
        if self._socket is not None:
            self._socket.close()
            self._socket = None


def _read_answer(connection: socket.socket, reader: FrameReader, request_id: str, timeout_s: float) -> dict[str, Any]:
    """The answer to request `request_id` on `connection`, within `timeout_s`."""
    deadline = time.monotonic() + timeout_s
    while True:
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            raise TimeoutError(f"no answer within {timeout_s:.0f} s")
        connection.settimeout(remaining)
        data = connection.recv(1 << 20)
        if not data:
            raise ConnectionResetError("the planner closed the connection")
        for payload in reader.feed(data):
            answer: dict[str, Any] = json.loads(payload)
            if answer.get("id") == request_id:
                return answer


def _no_answer(wait_s: float, error: Exception) -> PlanningError:
    return PlanningError("the planner did not answer", what=f"an answer within {wait_s:.0f} s",
                         why=f"{type(error).__name__}: {error}"[:300],
                         how="check the launch's output for the planner's state; plem launch restarts nothing by "
                             "itself: relaunch the robot if the planner stopped", code=MoveItCode.FAILURE)


class LocalPlannerLink:
    """The planner in this process, for the in-process `Robot`: the same requests as `PlannerLink`, answered by
    a `PlannerService` built on first use (loading pinocchio, coal and OMPL only when planning is asked for)."""

    def __init__(self, build: Callable[[], PlannerService]) -> None:
        self._build = build
        self._service: PlannerService | None = None

    def request(self, op: str, wait_s: float = ANSWER_MARGIN_S, **args: Any) -> Any:
        """Answer one request here; its error is raised as PlanningError."""
        if self._service is None:
            self._service = self._build()
        answer = self._service.handle({"op": op, **args})
        if answer.get("error") is not None:
            raise _error(answer["error"])
        return answer.get("result")

    def cancel(self) -> str | None:
        """Cancel the request the planner is working on (from another thread); what it was, or None."""
        return None if self._service is None else self._service.cancel()

    def close(self) -> None:
        """Nothing to close: the planner lives as long as its robot."""


def _error(value: Mapping[str, Any]) -> PlanningError:
    try:
        code = MoveItCode(int(value.get("code", MoveItCode.FAILURE)))
    except ValueError:
        code = MoveItCode.FAILURE
    return PlanningError(str(value.get("summary", "planning failed")), what=str(value.get("what", "")),
                         why=str(value.get("why", "")), how=str(value.get("how", "")), code=code)


class PlanningCalls:
    """The planner's calls on a robot client: plans, moves through the planner, IK, FK and the scene.

    Mixed into `RobotClient` and the in-process `Robot`, which say where their planner is and give
    `execute_trajectory`.
    """

    _planner_link: PlannerLink | LocalPlannerLink | None = None

    def _planner(self) -> PlannerLink | LocalPlannerLink:
        if self._planner_link is None:
            self._planner_link = self._new_planner_link()
        return self._planner_link

    def _new_planner_link(self) -> PlannerLink | LocalPlannerLink:
        """The link to this robot's planner (a process of its own, or in this one)."""
        raise NotImplementedError

    def _planning_joints(self) -> tuple[str, ...]:
        """The arm's joints in order, for positions given as a list."""
        raise NotImplementedError

    def _close_planner(self) -> None:
        if self._planner_link is not None:
            self._planner_link.close()

    def plan(self, target: Goal | Pose | str | Sequence[float] | Mapping[str, float], *,
             start: Sequence[float] | None = None, frame: str = "", options: PlanOptions | None = None) -> Plan:
        """A collision-free, timed and checked plan to `target` (a Pose, a named state such as 'home', positions in
        joint order or by name) from `start` (default: where the arm is); nothing moves."""
        goal = goal_of(target, self._planning_joints(), frame)
        options = options or PlanOptions()
        result = self._planner().request("plan", options.timeout_s + ANSWER_MARGIN_S, goal=goal_json(goal),
                                         options=options_json(options),
                                         start=None if start is None else [float(v) for v in start])
        return plan_from_json(result)

    def move_to(self, target: Goal | Pose | str | Sequence[float] | Mapping[str, float], *, frame: str = "",
                options: PlanOptions | None = None, tolerances: TrajectoryTolerances | None = None) -> Any:
        """Plan to `target` from where the arm is and run the plan through the robot's command path; returns the
        accepted motion's handle (`.wait()` for its result)."""
        plan = self.plan(target, frame=frame, options=options)
        return self.execute_trajectory(plan.trajectory, tolerances)  # type: ignore[attr-defined]

    def cartesian_path(self, waypoints: Sequence[Pose], *, frame: str = "", link: str = "", max_step: float = 0.01,
                       jump_threshold: float = 0.0, start: Sequence[float] | None = None,
                       options: PlanOptions | None = None) -> Plan:
        """A plan moving `link` (the group's tip) along straight lines through `waypoints`; its `fraction` says how
        much of the way it covers (MoveIt's compute_cartesian_path)."""
        options = options or PlanOptions()
        result = self._planner().request(
            "cartesian", options.timeout_s + ANSWER_MARGIN_S, waypoints=[pose.to_json() for pose in waypoints],
            frame=frame, link=link, max_step=max_step, jump_threshold=jump_threshold,
            options=options_json(options), start=None if start is None else [float(v) for v in start])
        return plan_from_json(result)

    def plan_sequence(self, items: Sequence[Item], *, link: str = "", tool_limits: ToolLimits | None = None,
                      start: Sequence[float] | None = None, options: PlanOptions | None = None) -> Plan:
        """A plan through `items` (Joint, Linear, Circular, each with a blend radius) from `start` (default: where the
        arm is), passing corners with a blend radius without stopping, within the joint limits and `tool_limits` (on
        Cartesian moves); refused, naming the item and pose, where the path cannot be followed. Nothing moves."""
        options = options or PlanOptions()
        result = self._planner().request(
            "sequence", options.timeout_s + ANSWER_MARGIN_S, items=[item_json(item) for item in items], link=link,
            tool_limits=(tool_limits or ToolLimits()).to_json(), options=options_json(options),
            start=None if start is None else [float(v) for v in start])
        return plan_from_json(result)

    def move_sequence(self, items: Sequence[Item], *, link: str = "", tool_limits: ToolLimits | None = None,
                      options: PlanOptions | None = None, tolerances: TrajectoryTolerances | None = None) -> Any:
        """Plan `items` from where the arm is (`plan_sequence`) and run the plan through the robot's command path;
        returns the accepted motion's handle (`.wait()` for its result). ur_rtde's moveL/moveJ with a path."""
        plan = self.plan_sequence(items, link=link, tool_limits=tool_limits, options=options)
        return self.execute_trajectory(plan.trajectory, tolerances)  # type: ignore[attr-defined]

    def move_linear(self, pose: Pose, *, frame: str = "", link: str = "", tool_limits: ToolLimits | None = None,
                    options: PlanOptions | None = None, tolerances: TrajectoryTolerances | None = None) -> Any:
        """Move the tool (`link`, the group's tip) in a straight line to `pose` in `frame`, the orientation turning
        by slerp (Pilz's LIN, ur_rtde's moveL); returns the motion's handle."""
        return self.move_sequence([Linear(pose, frame=frame)], link=link, tool_limits=tool_limits, options=options,
                                  tolerances=tolerances)

    def move_circular(self, via: Pose | Sequence[float] | None, pose: Pose, *,
                      center: Pose | Sequence[float] | None = None, frame: str = "", link: str = "",
                      tool_limits: ToolLimits | None = None, options: PlanOptions | None = None,
                      tolerances: TrajectoryTolerances | None = None) -> Any:
        """Move the tool on an arc through `via` (or around `center`, with via None) to `pose` (Pilz's CIRC,
        ur_rtde's moveC); returns the motion's handle."""
        return self.move_sequence([Circular(pose, via=via, center=center, frame=frame)], link=link,
                                  tool_limits=tool_limits, options=options, tolerances=tolerances)

    def compute_ik(self, pose: Pose, *, frame: str = "", seed: Sequence[float] | None = None, group: str = "",
                   link: str = "", timeout: float | None = None, avoid_collisions: bool = True,
                   position_only: bool = False) -> list[float]:
        """Joint positions putting `link` (the group's tip) at `pose`, nearest `seed` (default: where the arm is)."""
        result: list[float] = self._planner().request(
            "ik", (timeout or 0.0) + ANSWER_MARGIN_S, pose=pose.to_json(), frame=frame, group=group, link=link,
            seed=None if seed is None else [float(v) for v in seed], timeout_s=timeout,
            avoid_collisions=avoid_collisions, position_only=position_only)
        return result

    def cancel_planning(self) -> str | None:
        """Cancel the plan, IK or Cartesian path the robot's planner is working on, whichever client asked for it;
        says what was cancelled (None when the planner was idle). The request's client gets PREEMPTED."""
        return self._planner().cancel()

    def compute_fk(self, positions: Sequence[float] | None = None, links: Sequence[str] = ()) -> dict[str, Pose]:
        """The pose of each link (default: the group's tip) in the root frame at `positions` (default: now)."""
        result = self._planner().request("fk", positions=None if positions is None else [float(v) for v in positions],
                                         links=list(links))
        return {link: Pose.from_json(value) for link, value in result.items()}

    def contacts(self, positions: Sequence[float] | None = None) -> list[tuple[str, str]]:
        """Every colliding pair (links and scene objects) at `positions` (default: now)."""
        result = self._planner().request("contacts",
                                         positions=None if positions is None else [float(v) for v in positions])
        return [(a, b) for a, b in result]

    def planning_scene(self) -> PlanningScene:
        """The planner's scene: its world and attached objects."""
        return PlanningScene.from_json(self._planner().request("scene", action="get"))

    def add_objects(self, *objects: SceneObject) -> None:
        """Add objects to the scene (an existing name is replaced)."""
        self._planner().request("scene", action="add", objects=[item.to_json() for item in objects])

    def move_object(self, name: str, pose: Pose) -> None:
        """Move a world object to `pose` (in its frame) or an attached one relative to its link."""
        self._planner().request("scene", action="move", name=name, pose=pose.to_json())

    def remove_object(self, name: str) -> None:
        """Remove an object from the scene."""
        self._planner().request("scene", action="remove", name=name)

    def attach_object(self, name: str, link: str = "", touch_links: Sequence[str] = ()) -> None:
        """Attach a world object to `link` (the group's tip) where it is now; it then moves with the link."""
        self._planner().request("scene", action="attach", name=name, link=link, touch_links=list(touch_links))

    def detach_object(self, name: str) -> None:
        """Leave an attached object in the world where it is now."""
        self._planner().request("scene", action="detach", name=name)

    def clear_scene(self) -> None:
        """Remove every object."""
        self._planner().request("scene", action="clear")
