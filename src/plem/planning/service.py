"""The planner's socket: plem clients ask it for IK, FK, plans and scene changes; it never commands the arm.

`/dev/shm/{robot_id}_planner` carries the command socket's length-prefixed JSON frames, a thread per
client. Requests run one at a time (the planner is not thread-safe). A request without a start state is
planned from the arm's state in shared memory. Clients execute plans through the robot's command path
themselves, so a planner that dies or hangs can delay a plan, never move or stall the arm.
"""

from __future__ import annotations

import json
import logging
import socket
import threading
from collections.abc import Callable
from typing import Any, Protocol, TypeVar

from plem.control.state import JointState
from plem.errors import MoveItCode, PlanningError, PlemError
from plem.ipc.command_socket import CommandSocketError, FrameReader, frame, peer_credentials, trusted
from plem.planning.planner import Planner
from plem.planning.poses import Pose
from plem.planning.protocol import MAX_PLANNING_TIME_S, goal_from_json, number, options_from_json, plan_json, text
from plem.planning.scene import PlanningScene

#: Largest request frame the planner reads (a scene mesh or a long list of waypoints fits).
MAX_REQUEST_BYTES = 16 << 20
ACCEPT_POLL_S = 0.2
_log = logging.getLogger("plem.planner")
T = TypeVar("T")


class ArmState(Protocol):
    """Where the planner reads the arm's state: a robot client, or the in-process robot."""

    def live_state(self) -> JointState:
        """The latest cycle's state."""
        ...


class PlannerService:
    """Answers planning requests (JSON objects with an 'op') for one robot."""

    def __init__(self, planner: Planner, robot: ArmState) -> None:
        self.planner = planner
        self.robot = robot
        self._lock = threading.Lock()
        self._operations: dict[str, Callable[[dict[str, Any]], Any]] = {
            "describe": self._describe, "fk": self._fk, "ik": self._ik, "plan": self._plan,
            "cartesian": self._cartesian, "scene": self._scene, "contacts": self._contacts,
            "view": self._view,
        }

    def call(self, work: Callable[[Planner], T]) -> T:
        """Run `work` on the planner, one request at a time (as socket requests run)."""
        with self._lock:
            return work(self.planner)

    def handle(self, request: dict[str, Any]) -> dict[str, Any]:
        """The reply to one request: {'id', 'result'} or {'id', 'error'} (WHAT/WHY/HOW and MoveIt's code)."""
        request_id = request.get("id")
        operation = self._operations.get(str(request.get("op")))
        try:
            if operation is None:
                raise PlanningError(f"unknown planner request {request.get('op')!r}",
                                    what=f"one of {', '.join(self._operations)}", why="the op is not one of them",
                                    how="use plem's client (plem.bridge.connect) or the CLI",
                                    code=MoveItCode.FAILURE)
            with self._lock:
                return {"id": request_id, "result": operation(request)}
        except PlemError as error:
            return {"id": request_id, "error": _error_payload(error)}
        except Exception as error:  # noqa: BLE001 - a request that trips over a bug is answered; the planner serves on
            _log.exception("planner request %r failed", request.get("op"))
            return {"id": request_id, "error": _error_payload(internal_error(request.get("op"), error))}

    # -- operations ---------------------------------------------------------------------------------------
    def _describe(self, request: dict[str, Any]) -> dict[str, Any]:
        planner = self.planner
        return {"joint_names": list(planner.joint_names), "root_link": planner.root_link,
                "groups": {name: {"joints": list(g.joints), "base_link": g.base_link, "tip_link": g.tip_link,
                                  "solver": g.settings.solver, "timeout_s": g.settings.timeout_s}
                           for name, g in planner.groups.items()},
                "named_states": {name: list(map(float, values)) for name, values in planner.named_states.items()},
                "warnings": list(planner.warnings)}

    def _positions(self, value: Any) -> list[float]:
        """Positions given in the request, else the arm's current ones."""
        if value is None:
            return list(map(float, self.robot.live_state().position))
        if not isinstance(value, list):
            raise PlanningError("positions must be a list of numbers", what=f"{len(self.planner.joint_names)} "
                                "numbers in rad", why=f"got {type(value).__name__}", how="send a list",
                                code=MoveItCode.INVALID_ROBOT_STATE)
        return value

    def _fk(self, request: dict[str, Any]) -> dict[str, Any]:
        links = request.get("links") or [self.planner.group().tip_link]
        if not isinstance(links, list) or not all(isinstance(link, str) for link in links):
            raise PlanningError("links must be a list of link names", what="a list of strings",
                                why=f"got {str(links)[:200]}", how="name links of the URDF",
                                code=MoveItCode.INVALID_LINK_NAME)
        poses = self.planner.fk(self._positions(request.get("positions")), links, text(request, "frame"))
        return {link: pose.to_json() for link, pose in poses.items()}

    def _ik(self, request: dict[str, Any]) -> list[float]:
        timeout = request.get("timeout_s")
        if timeout is not None:
            timeout = number(request, "timeout_s", 0.0, 0.0, MAX_PLANNING_TIME_S)
        solution = self.planner.ik(
            Pose.from_json(request.get("pose")), self._positions(request.get("seed")), frame=text(request, "frame"),
            group=text(request, "group"), link=text(request, "link"),
            timeout_s=timeout,
            avoid_collisions=bool(request.get("avoid_collisions", True)),
            position_only=bool(request.get("position_only", False)))
        return list(map(float, solution))

    def _plan(self, request: dict[str, Any]) -> dict[str, Any]:
        plan = self.planner.plan(self._positions(request.get("start")), goal_from_json(request.get("goal")),
                                 options_from_json(request.get("options")))
        return plan_json(plan)

    def _cartesian(self, request: dict[str, Any]) -> dict[str, Any]:
        waypoints = request.get("waypoints")
        if not isinstance(waypoints, list) or not waypoints:
            raise PlanningError("a Cartesian path needs waypoints", what="a list of poses",
                                why=f"got {str(waypoints)[:200]}", how="give at least one pose",
                                code=MoveItCode.INVALID_GOAL_CONSTRAINTS)
        plan = self.planner.cartesian(self._positions(request.get("start")), [Pose.from_json(w) for w in waypoints],
                                      frame=text(request, "frame"), link=text(request, "link"),
                                      max_step=float(request.get("max_step", 0.01)),
                                      jump_threshold=float(request.get("jump_threshold", 0.0)),
                                      options=options_from_json(request.get("options")))
        return plan_json(plan)

    def _contacts(self, request: dict[str, Any]) -> list[list[str]]:
        return [list(pair) for pair in self.planner.contacts(self._positions(request.get("positions")))]

    def _scene(self, request: dict[str, Any]) -> dict[str, Any]:
        scene = self.planner.scene
        action = request.get("action", "get")
        name = text(request, "name")
        if action == "add":
            for item in PlanningScene.from_json({"objects": request.get("objects", [])}).objects():
                scene.add(item)
        elif action == "move":
            scene.move(name, Pose.from_json(request.get("pose")))
        elif action == "remove":
            scene.remove(name)
        elif action == "clear":
            for item in scene.objects():
                scene.remove(item.name)
        elif action == "attach":
            touch = request.get("touch_links", [])
            self.planner.attach(name, text(request, "link") or self.planner.group().tip_link,
                                [str(link) for link in touch] if isinstance(touch, list) else [],
                                self._positions(None))
        elif action == "detach":
            self.planner.detach(name, self._positions(None))
        elif action != "get":
            raise PlanningError(f"unknown scene action {action!r}",
                                what="add, move, remove, clear, attach, detach or get", why=f"got {action!r}",
                                how="use one of those", code=MoveItCode.FAILURE)
        return scene.to_json()

    def _view(self, request: dict[str, Any]) -> dict[str, Any]:
        """What a view draws: the newest plan when newer than `plans_seen`, the scene when newer than `scene_seen`."""
        planner = self.planner
        newer = planner.plans_made > int(number(request, "plans_seen", 0, -1, 2**63))
        plan = planner.latest_plan if newer else None
        scene = planner.scene
        changed = scene.version != int(number(request, "scene_seen", -1, -2, 2**63))
        return {"plans": planner.plans_made, "plan": None if plan is None else plan_json(plan),
                "scene": scene.to_json() if changed else None}

    # -- the socket ---------------------------------------------------------------------------------------
    def serve(self, server: socket.socket, stop: threading.Event) -> None:
        """Accept clients until `stop`; each is served by a thread of its own."""
        server.setblocking(True)
        server.settimeout(ACCEPT_POLL_S)
        while not stop.is_set():
            try:
                connection, _ = server.accept()
            except TimeoutError:
                continue
            _, uid, _ = peer_credentials(connection)
            if not trusted(uid):
                connection.close()
                continue
            threading.Thread(target=self._serve_client, args=(connection, stop), daemon=True,
                             name="plem-planner-client").start()

    def _serve_client(self, connection: socket.socket, stop: threading.Event) -> None:
        reader = FrameReader(MAX_REQUEST_BYTES)
        connection.settimeout(ACCEPT_POLL_S)
        with connection:
            while not stop.is_set():
                try:
                    data = connection.recv(1 << 16)
                except TimeoutError:
                    continue
                except OSError:
                    return
                if not data:
                    return
                try:
                    frames = reader.feed(data)
                except CommandSocketError as error:
                    _log.warning("a client sent an oversized frame: %s", error.summary)
                    return
                for payload in frames:
                    connection.settimeout(None)
                    try:
                        connection.sendall(frame(self._reply(payload)))
                    except OSError:
                        return
                    connection.settimeout(ACCEPT_POLL_S)

    def _reply(self, payload: bytes) -> bytes:
        """The encoded answer to one frame; an answer that cannot be encoded becomes that request's error."""
        answer = self._answer(payload)
        try:
            return json.dumps(answer).encode()
        except (TypeError, ValueError) as error:
            _log.exception("the answer to a planner request could not be encoded")
            failure = internal_error("answer", error)
            return json.dumps({"id": answer.get("id"), "error": _error_payload(failure)}).encode()

    def _answer(self, payload: bytes) -> dict[str, Any]:
        try:
            request = json.loads(payload)
        except (ValueError, UnicodeDecodeError) as error:
            return {"id": None, "error": PlanningError("the request is not JSON", what="a JSON object",
                                                       why=str(error)[:200], how="use plem's client",
                                                       code=MoveItCode.FAILURE).to_dict()}
        if not isinstance(request, dict):
            request = {"op": None}
        return self.handle(request)


def internal_error(operation: object, error: Exception) -> PlanningError:
    """The answer to a request the planner failed on by a fault of its own (a bug): what failed, and that the
    planner goes on serving."""
    return PlanningError(f"the planner failed on this {operation} request",
                         what=f"an answer to the {operation} request",
                         why=f"{type(error).__name__}: {str(error)[:300] or 'no message'} (the planner's log has "
                             "the traceback; it goes on serving other requests)",
                         how="retry with other values, and report this with the planner's log (plem launch prints it)",
                         code=MoveItCode.FAILURE)


def _error_payload(error: PlemError) -> dict[str, Any]:
    """An error as the 'error' of a reply, with MoveIt's code (FAILURE when the error has none)."""
    payload = error.to_dict()
    payload.setdefault("code", int(MoveItCode.FAILURE))
    return payload
