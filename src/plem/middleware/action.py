"""ROS 2 actions over DDS: a server that runs goals through callbacks, and a client to send them.

An action is three services (send_goal, cancel_goal, get_result) and two topics (feedback, status)
under `<action>/_action/`, with the QoS rcl_action gives them. The server keeps every goal's status,
answers result requests once the goal ends (or at once when it already has), and publishes the status
array whenever a status changes, as rcl_action does.
"""

from __future__ import annotations

import logging
import time
import uuid
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

from plem.middleware.names import ActionNames
from plem.middleware.node import Entities, Node
from plem.middleware.qos import DEFAULT, LATCHED

_log = logging.getLogger("plem.bridge")
# action_msgs/msg/GoalStatus values.
UNKNOWN, ACCEPTED, EXECUTING, CANCELING, SUCCEEDED, CANCELED, ABORTED = range(7)
TERMINAL = frozenset({SUCCEEDED, CANCELED, ABORTED})
# action_msgs/srv/CancelGoal return codes.
CANCEL_NONE, CANCEL_REJECTED, CANCEL_UNKNOWN_GOAL, CANCEL_TERMINATED = range(4)
#: Ended goals whose results stay available to late get_result requests.
KEPT_RESULTS = 100
STATUS_TYPE = "action_msgs/msg/GoalStatusArray"


class Execution(Protocol):
    """A running goal as the server sees it; the server polls it and publishes what it reports."""

    def poll(self) -> tuple[Any | None, tuple[int, Any] | None]:
        """(feedback fields or None, (terminal status, result fields) once the goal ended, else None)."""

    def cancel(self) -> bool:
        """Ask the goal to stop; False when it cannot be canceled."""


def goal_uuid(node: Node, goal_id: bytes) -> Any:
    """unique_identifier_msgs/UUID of a goal id."""
    return node.library.new("unique_identifier_msgs/msg/UUID", uuid=list(goal_id))


@dataclass
class _Goal:
    goal_id: bytes
    stamp: Any
    execution: Execution
    status: int = EXECUTING
    result: Any = None
    waiting: list[Any] = field(default_factory=list)


class _Failed:
    """A goal whose start raised (a bug, logged): it ends ABORTED with an empty result."""

    def poll(self) -> tuple[None, tuple[int, dict[str, Any]]]:
        return None, (ABORTED, {})

    def cancel(self) -> bool:
        return False


class ActionServer:
    """Serves one action. `start(goal) -> Execution` runs an accepted goal; it may return a finished one."""

    def __init__(self, node: Node, name: str, ros_type: str, start: Callable[[Any], Execution],
                 feedback_period: float = 0.05) -> None:
        self.node = node
        self.ros_type = ros_type
        self._start = start
        self._feedback_period = feedback_period
        self._next_feedback = 0.0
        names = ActionNames(name)
        self.send_goal, self.cancel_goal, self.get_result = (node.service(*part) for part in names.services(ros_type))
        self._feedback = node.publisher(names.feedback, f"{ros_type}_FeedbackMessage", DEFAULT)
        self._status = node.publisher(names.status, STATUS_TYPE, LATCHED)
        self._goals: OrderedDict[bytes, _Goal] = OrderedDict()

    @property
    def services(self) -> tuple[Any, ...]:
        """The service servers, for a wait set."""
        return self.send_goal, self.cancel_goal, self.get_result

    def entities(self) -> Entities:
        """The DDS endpoints behind the action: its three services and two topics."""
        total = self._feedback.entities() + self._status.entities()
        for service in self.services:
            total = total + service.entities()
        return total

    def spin_once(self) -> None:
        """Answer waiting requests, poll running goals, publish feedback and status changes."""
        for service in self.services:
            service.flush()
        changed = False
        for request in self.send_goal.take():
            changed |= self._on_send_goal(request)
        for request in self.cancel_goal.take():
            changed |= self._on_cancel(request)
        for request in self.get_result.take():
            goal = self._goals.get(bytes(request.goal_id.uuid))
            if goal is None:
                self.get_result.reply(request, status=UNKNOWN)
            elif goal.status in TERMINAL:
                self.get_result.reply(request, status=goal.status, result=goal.result)
            else:
                goal.waiting.append(request)
        changed |= self._poll()
        if changed:
            self._publish_status()

    def _on_send_goal(self, request: Any) -> bool:
        goal_id = bytes(request.goal_id.uuid)
        stamp = self.node.library.stamp()
        if goal_id in self._goals:   # a repeated id is refused, as rcl_action does
            self.send_goal.reply(request, accepted=False, stamp=stamp)
            return False
        self.send_goal.reply(request, accepted=True, stamp=stamp)
        execution: Execution
        try:
            execution = self._start(request.goal)
        except Exception:  # noqa: BLE001 - an accepted goal always ends, even when starting it failed unexpectedly
            _log.exception("a %s goal could not be started; it is aborted", self.ros_type)
            execution = _Failed()
        self._goals[goal_id] = _Goal(goal_id, stamp, execution)
        self._trim()
        return True

    def _on_cancel(self, request: Any) -> bool:
        info = request.goal_info
        goal_id, before = bytes(info.goal_id.uuid), info.stamp.sec * 1_000_000_000 + info.stamp.nanosec
        every = not any(goal_id) and before == 0
        chosen = [goal for goal in self._goals.values()
                  if every or goal.goal_id == goal_id
                  or (before and goal.stamp.sec * 1_000_000_000 + goal.stamp.nanosec <= before)]
        canceling = [goal for goal in chosen if goal.status in (ACCEPTED, EXECUTING) and goal.execution.cancel()]
        for goal in canceling:
            goal.status = CANCELING
        if canceling:
            code = CANCEL_NONE
        elif any(goal_id) and goal_id not in self._goals:
            code = CANCEL_UNKNOWN_GOAL
        elif chosen and all(goal.status in TERMINAL for goal in chosen):
            code = CANCEL_TERMINATED
        else:
            code = CANCEL_REJECTED
        infos = [self._info(goal) for goal in canceling]
        self.cancel_goal.reply(request, return_code=code, goals_canceling=infos)
        return bool(canceling)

    def _poll(self) -> bool:
        now = time.monotonic()
        send_feedback = now >= self._next_feedback
        if send_feedback:
            self._next_feedback = now + self._feedback_period
        changed = False
        for goal in self._goals.values():
            if goal.status in TERMINAL:
                continue
            feedback, ended = goal.execution.poll()
            if feedback is not None and send_feedback and ended is None:
                self._feedback.publish(self._feedback.message(goal_id=goal_uuid(self.node, goal.goal_id),
                                                              feedback=self._part("Feedback", feedback)))
            if ended is not None:
                goal.status, goal.result = ended[0], self._part("Result", ended[1])
                for request in goal.waiting:
                    self.get_result.reply(request, status=goal.status, result=goal.result)
                goal.waiting.clear()
                changed = True
        return changed

    def _part(self, part: str, value: Any) -> Any:
        """A Feedback or Result struct from the fields an execution reported (or the struct itself)."""
        return self.node.library.new(f"{self.ros_type}_{part}", **value) if isinstance(value, dict) else value

    def _publish_status(self) -> None:
        status = [self.node.library.new("action_msgs/msg/GoalStatus", goal_info=self._info(goal), status=goal.status)
                  for goal in self._goals.values()]
        self._status.publish(self._status.message(status_list=status))

    def _trim(self) -> None:
        ended = [goal_id for goal_id, goal in self._goals.items() if goal.status in TERMINAL]
        for goal_id in ended[:max(0, len(ended) - KEPT_RESULTS)]:
            del self._goals[goal_id]

    def _info(self, goal: _Goal) -> Any:
        return self.node.library.new("action_msgs/msg/GoalInfo", goal_id=goal_uuid(self.node, goal.goal_id),
                                     stamp=goal.stamp)


class ActionClient:
    """Sends goals to one action and waits for their results, with feedback as it arrives."""

    def __init__(self, node: Node, name: str, ros_type: str) -> None:
        self.node = node
        self.ros_type = ros_type
        names = ActionNames(name)
        self._send_goal, self._cancel, self._get_result = (node.client(*part) for part in names.services(ros_type))
        self.feedback = node.subscription(names.feedback, f"{ros_type}_FeedbackMessage", DEFAULT)
        self.status = node.subscription(names.status, STATUS_TYPE, LATCHED)

    def wait_for_server(self, timeout: float) -> bool:
        """True once every service of the action is matched with a server."""
        deadline = time.monotonic() + timeout
        while not all(client.ready for client in (self._send_goal, self._cancel, self._get_result)):
            if time.monotonic() > deadline:
                return False
            time.sleep(0.02)
        return True

    def send_goal(self, timeout: float = 5.0, /, **goal: Any) -> tuple[bytes, bool]:
        """Send a goal of any fields (`timeout` is positional only, so a goal field may be named so); (goal id,
        accepted)."""
        goal_id = uuid.uuid4().bytes
        message = self.node.library.new(f"{self.ros_type}_Goal", **goal)
        reply = self._send_goal.call(timeout, goal_id=goal_uuid(self.node, goal_id), goal=message)
        return goal_id, reply.accepted

    def result(self, goal_id: bytes, timeout: float) -> tuple[int, Any]:
        """Wait for the goal's end: (status, result)."""
        reply = self._get_result.call(timeout, goal_id=goal_uuid(self.node, goal_id))
        return reply.status, reply.result

    def cancel(self, goal_id: bytes, timeout: float = 5.0) -> int:
        """Ask the server to cancel one goal; the CancelGoal return code."""
        info = self.node.library.new("action_msgs/msg/GoalInfo", goal_id=goal_uuid(self.node, goal_id))
        return int(self._cancel.call(timeout, goal_info=info).return_code)

