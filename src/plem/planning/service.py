"""The planner's socket: plem clients ask it for IK, FK, plans and scene changes; it never commands the arm.

`/dev/shm/{robot_id}_planner` carries the command socket's length-prefixed JSON frames, a thread per
client. Requests that compute (IK, FK, plans, scene changes) run one at a time (the planner is not
thread-safe): one that arrives while another runs is answered at once that the planner is busy, with whose
request and how long it has left. Reading the scene, the newest plan and the planner's description never
wait. Every request's time is capped (see plem.planning.goals), and a running one ends early when its client
closes its connection or any client sends {"op": "cancel"}. Every field is checked here, and a request that
trips over a bug is answered "internal error" while the planner serves on. A request without a start state
is planned from the arm's state in shared memory. Clients execute plans through the robot's command path
themselves, so a planner that dies or hangs can delay a plan, never move or stall the arm.
"""

from __future__ import annotations

import json
import logging
import math
import select
import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol, TypeVar

from plem.control.state import JointState
from plem.errors import MoveItCode, PlanningError, PlemError
from plem.ipc.command_socket import CommandSocketError, FrameReader, frame, peer_credentials, trusted
from plem.planning.goals import MAX_IK_TIMEOUT_S, PLANNING_TIME_S
from plem.planning.planner import Planner
from plem.planning.poses import MAX_COORDINATE_M, Pose
from plem.planning.protocol import flag, goal_from_json, number, options_from_json, plan_json, text
from plem.planning.scene import PlanningScene
from plem.planning.sequence import ToolLimits, items_from_json

#: Largest request frame the planner reads (a scene mesh or a long list of waypoints fits).
MAX_REQUEST_BYTES = 16 << 20
ACCEPT_POLL_S = 0.2
#: How often a running request looks whether its client closed its connection (s).
GONE_POLL_S = 0.05
#: Operations that only read what the planner holds: served at once, even while another request runs.
READING = frozenset({"describe", "view"})
_log = logging.getLogger("plem.planner")
T = TypeVar("T")


@dataclass
class Running:
    """The request the planner is working on: whose, since when, the time it asked for, and its cancel flag."""

    op: str
    client: str
    budget_s: float | None
    gone: Callable[[], bool] = lambda: False
    started: float = field(default_factory=time.monotonic)
    cancel: threading.Event = field(default_factory=threading.Event)
    _looked: float = 0.0
    _gone: bool = False

    def cancelled(self) -> bool:
        """Whether the request was cancelled, or its client went away (looked at every GONE_POLL_S)."""
        if self.cancel.is_set():
            return True
        now = time.monotonic()
        if now - self._looked >= GONE_POLL_S:
            self._looked = now
            self._gone = self.gone()
        return self._gone

    def name(self) -> str:
        """'a plan request from plem (pid 42, uid 0)'."""
        return f"a{'n' if self.op[:1] in 'aeiou' else ''} {self.op} request from {self.client}"

    def state(self) -> str:
        """'a plan request from ..., 12 s left of its 60 s'."""
        elapsed = time.monotonic() - self.started
        timing = (f"{max(self.budget_s - elapsed, 0.0):.0f} s left of its {self.budget_s:g} s"
                  if self.budget_s is not None else f"running for {elapsed:.0f} s")
        return f"{self.name()}, {timing}"


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
        self._running: Running | None = None
        #: (op, error type) of internal errors whose traceback was logged: each is logged once.
        self._logged: set[tuple[str, str]] = set()
        self._operations: dict[str, Callable[[dict[str, Any]], Any]] = {
            "describe": self._describe, "fk": self._fk, "ik": self._ik, "plan": self._plan,
            "cartesian": self._cartesian, "sequence": self._sequence, "scene": self._scene, "contacts": self._contacts,
            "view": self._view,
        }

    def call(self, work: Callable[[Planner], T], op: str = "ROS", client: str = "MoveIt's ROS services",
             budget_s: float | None = None, gone: Callable[[], bool] = lambda: False) -> T:
        """Run `work` on the planner, one request at a time (as socket requests run); PlanningError at once when
        another request runs. `gone()` tells whether the client went away (which cancels the work)."""
        running = Running(op, client, budget_s, gone)
        if not self._lock.acquire(blocking=False):
            raise self._busy()
        try:
            self._running = running
            self.planner.cancelled = running.cancelled
            return work(self.planner)
        except PlanningError as error:
            if error.code == MoveItCode.PREEMPTED:
                _log.warning("%s ended early: %s", running.name(),
                             "a client cancelled it" if running.cancel.is_set() else "its client closed its connection")
            raise
        finally:
            self.planner.cancelled = _not_cancelled
            self._running = None
            self._lock.release()

    def cancel(self) -> str | None:
        """Cancel the request running, if any; what it was."""
        running = self._running
        if running is None:
            return None
        running.cancel.set()
        return running.state()

    def handle(self, request: dict[str, Any], client: str = "this process",
               gone: Callable[[], bool] = lambda: False) -> dict[str, Any]:
        """The reply to one request: {'id', 'result'} or {'id', 'error'} (WHAT/WHY/HOW and MoveIt's code).
        `client` names who asks (in a busy answer to others), `gone()` says whether it went away."""
        request_id = request.get("id")
        op = str(request.get("op"))[:40]
        operation = self._operations.get(op)
        try:
            if op == "cancel":
                return {"id": request_id, "result": {"cancelled": self.cancel()}}
            if operation is None:
                raise PlanningError(f"unknown planner request {op!r}",
                                    what=f"one of {', '.join([*self._operations, 'cancel'])}",
                                    why="the op is not one of them",
                                    how="use plem's client (plem.bridge.connect) or the CLI", code=MoveItCode.FAILURE)
            if op in READING or (op == "scene" and request.get("action", "get") == "get"):
                return {"id": request_id, "result": operation(request)}  # reads only: never waits
            result = self.call(lambda _: operation(request), op, client, self._time_asked(op, request), gone)
            return {"id": request_id, "result": result}
        except PlemError as error:
            return {"id": request_id, "error": _error_payload(error)}
        except Exception as error:  # noqa: BLE001 - a request that trips over a bug is answered; the planner serves on
            self._log_internal(op, error)
            return {"id": request_id, "error": _error_payload(internal_error(op, error))}

    def _busy(self) -> PlanningError:
        """The answer while another request runs: whose it is and how long it has left."""
        running = self._running
        doing = running.state() if running is not None else "another request"
        return PlanningError("the planner is busy", what="a planner free to take the request",
                             why=f"it is working on {doing}; it serves one planning request at a time",
                             how="send the request again when that one is done, or cancel it (Ctrl-C in the command "
                                 "that asked, cancel_planning() of plem's Python client)", code=MoveItCode.FAILURE)

    def _time_asked(self, op: str, request: dict[str, Any]) -> float | None:
        """The time a request may take, for the busy answer (None where unknown)."""
        if op == "ik":
            asked = request.get("timeout_s")
            if isinstance(asked, int | float) and not isinstance(asked, bool) and 0 < asked <= MAX_IK_TIMEOUT_S:
                return float(asked)
            return max(group.settings.budget_s for group in self.planner.groups.values())
        if op in ("plan", "cartesian", "sequence"):
            options = request.get("options")
            asked = options.get("timeout_s") if isinstance(options, dict) else None
            if isinstance(asked, int | float) and not isinstance(asked, bool) and math.isfinite(asked):
                return float(asked)
            return PLANNING_TIME_S
        return None

    def _log_internal(self, op: str, error: Exception) -> None:
        """A request's internal error in the log, with its traceback, once per request kind and error type (a client
        repeating a request that trips over a bug never floods the launch's output)."""
        key = (op, type(error).__name__)
        if key in self._logged:
            return
        self._logged.add(key)
        _log.error("planner request %r failed (logged once; the planner serves on)", op, exc_info=error)

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
        if not isinstance(value, list) or not all(isinstance(v, int | float) and not isinstance(v, bool)
                                                  for v in value):
            raise PlanningError("positions must be a list of numbers", what=f"{len(self.planner.joint_names)} "
                                "numbers in rad", why=f"got {str(value)[:200]}", how="send a list of numbers",
                                code=MoveItCode.INVALID_ROBOT_STATE)
        return [float(v) for v in value]

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
        if timeout is not None:  # 0: kinematics.yaml's timeout, as MoveIt takes it
            timeout = number(request, "timeout_s", 0.0, 0.0, MAX_IK_TIMEOUT_S, low_included=True)
        solution = self.planner.ik(
            Pose.from_json(request.get("pose")), self._positions(request.get("seed")), frame=text(request, "frame"),
            group=text(request, "group"), link=text(request, "link"),
            timeout_s=timeout,
            avoid_collisions=flag(request, "avoid_collisions", True),
            position_only=flag(request, "position_only", False))
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
                                      max_step=number(request, "max_step", 0.01, 0.0, MAX_COORDINATE_M),
                                      jump_threshold=number(request, "jump_threshold", 0.0, 0.0, math.inf,
                                                            low_included=True),
                                      options=options_from_json(request.get("options")))
        return plan_json(plan)

    def _sequence(self, request: dict[str, Any]) -> dict[str, Any]:
        plan = self.planner.sequence(self._positions(request.get("start")), items_from_json(request.get("items")),
                                     link=text(request, "link"),
                                     tool_limits=ToolLimits.from_json(request.get("tool_limits")),
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
            if not isinstance(touch, list) or not all(isinstance(link, str) for link in touch):
                raise PlanningError("touch_links must be a list of link names", what="a list of strings",
                                    why=f"got {str(touch)[:200]}", how="name links of the URDF",
                                    code=MoveItCode.INVALID_LINK_NAME)
            self.planner.attach(name, text(request, "link") or self.planner.group().tip_link, touch,
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
        """Answer one client's requests until it closes its connection or `stop`; nothing it sends ends the thread."""
        try:
            self._serve_frames(connection, stop)
        except Exception as error:  # noqa: BLE001 - the last resort: that client is dropped, the planner serves on
            self._log_internal("connection", error)
            connection.close()

    def _serve_frames(self, connection: socket.socket, stop: threading.Event) -> None:
        reader = FrameReader(MAX_REQUEST_BYTES)
        client = describe_peer(connection)
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
                        connection.sendall(frame(self._reply(payload, client, lambda: closed(connection))))
                    except OSError:
                        return
                    connection.settimeout(ACCEPT_POLL_S)

    def _reply(self, payload: bytes, client: str, gone: Callable[[], bool]) -> bytes:
        """The encoded answer to one frame; an answer that cannot be encoded becomes that request's error."""
        answer = self._answer(payload, client, gone)
        try:
            return json.dumps(answer).encode()
        except (TypeError, ValueError) as error:
            _log.exception("the answer to a planner request could not be encoded")
            failure = internal_error("answer", error)
            return json.dumps({"id": answer.get("id"), "error": _error_payload(failure)}).encode()

    def _answer(self, payload: bytes, client: str, gone: Callable[[], bool]) -> dict[str, Any]:
        try:
            request = json.loads(payload)
        except (ValueError, RecursionError) as error:
            return {"id": None, "error": PlanningError("the request is not JSON", what="a JSON object",
                                                       why=str(error)[:200], how="use plem's client",
                                                       code=MoveItCode.FAILURE).to_dict()}
        if not isinstance(request, dict):
            request = {"op": None}
        return self.handle(request, client, gone)


def describe_peer(connection: socket.socket) -> str:
    """The process at the other end of a connection, as a busy answer names it: 'plem (pid 42, uid 0)'."""
    pid, uid, _ = peer_credentials(connection)
    try:
        name = Path(f"/proc/{pid}/comm").read_text().strip() or "a process"
    except OSError:
        name = "a process"
    return f"{name} (pid {pid}, uid {uid})"


def closed(connection: socket.socket) -> bool:
    """Whether the client closed its end (its next bytes are the end of the stream), without reading its data."""
    try:
        readable, _, _ = select.select([connection], [], [], 0.0)
        return bool(readable) and connection.recv(1, socket.MSG_PEEK | socket.MSG_DONTWAIT) == b""
    except BlockingIOError:
        return False
    except (OSError, ValueError):
        return True


def _not_cancelled() -> bool:
    """The planner's cancel check outside requests."""
    return False


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
