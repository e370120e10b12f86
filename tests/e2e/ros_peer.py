"""A ROS 2 peer of a launched robot: plem's own DDS node in another process than the launch, no shared memory.

Used in the test process by test_ros_bridge and, as a script, in a second network namespace by
test_two_hosts (`python -m tests.e2e.ros_peer ROBOT_ID JSON_PLAN` prints one JSON line of results).
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Sequence
from typing import Any

from plem.middleware.action import TERMINAL, ActionClient
from plem.middleware.discovery import DiscoverySettings
from plem.middleware.node import Node, Subscription
from plem.middleware.qos import DEFAULT, EVENTS, LATCHED, RT_RAW
from tests.e2e.launched import wait_for

FJT = "control_msgs/action/FollowJointTrajectory"
SET_MODE = "plem_msgs/action/SetMode"
JOINT_NAMES = tuple(f"joint{index}" for index in range(6))  # the default Indy7's
#: The built-in arms' trajectory controller, as their controllers.yaml (the configuration reference's) names it.
TRAJECTORY = "joint_trajectory_controller"


class RosPeer:
    """Topics and actions of one robot (`/{robot_id}/...`) as any ROS 2 node on the domain sees them."""

    def __init__(self, robot_id: str, settings: DiscoverySettings | None = None, node: Node | None = None) -> None:
        self.robot_id = robot_id
        self._owns_node = node is None
        self.node = node or Node(settings)
        self.library = self.node.library
        ns = f"/{robot_id}"
        self.joint_states = self.node.subscription(f"{ns}/joint_states", "sensor_msgs/msg/JointState", DEFAULT)
        self.set_mode = ActionClient(self.node, f"{ns}/wim_rt_driver/set_mode", SET_MODE)
        self.follow = ActionClient(self.node, f"{ns}/{TRAJECTORY}/follow_joint_trajectory", FJT)
        self.trajectories = self.node.publisher(f"{ns}/{TRAJECTORY}/joint_trajectory",
                                                "trajectory_msgs/msg/JointTrajectory", DEFAULT)
        self._latest_joint_state: Any = None
        self._goal_status: dict[bytes, int] = {}

    # -- topics --------------------------------------------------------------------------------------
    def subscribe(self, topic: str, ros_type: str, profile: Any = DEFAULT) -> Subscription[Any]:
        """A new subscription on `/{robot_id}/{topic}`."""
        return self.node.subscription(f"/{self.robot_id}/{topic}", ros_type, profile)

    def rt_raw(self) -> Subscription[Any]:
        return self.subscribe("rt_raw", "plem_msgs/msg/RtRaw", RT_RAW)

    def rt_events(self) -> Subscription[Any]:
        return self.subscribe("rt_events", "plem_msgs/msg/RtEvent", EVENTS)

    def robot_description(self, topic: str = "robot_description") -> Subscription[Any]:
        return self.subscribe(topic, "std_msgs/msg/String", LATCHED)

    def rt_monitor_stats(self) -> Subscription[Any]:
        return self.subscribe("rt_monitor_stats", "plem_msgs/msg/RtMonitorStats", DEFAULT)

    def joint_state(self, timeout: float = 2.0, fresh: bool = True) -> Any:
        """The newest JointState; with `fresh`, one published after this call (older ones are dropped)."""
        messages = self.joint_states.take(10_000)
        if messages:
            self._latest_joint_state = messages[-1]
        if not fresh and self._latest_joint_state is not None:
            return self._latest_joint_state
        message = wait_for(lambda: last(self.joint_states.take(10_000)), timeout)
        if message is None:
            raise AssertionError(f"no joint_states within {timeout} s")
        self._latest_joint_state = message
        return message

    def position(self, timeout: float = 2.0) -> list[float]:
        return list(self.joint_state(timeout).position)

    # -- commands ------------------------------------------------------------------------------------
    def wait_for_servers(self, timeout: float = 10.0) -> bool:
        return (self.set_mode.wait_for_server(timeout) and self.follow.wait_for_server(timeout)
                and wait_for(lambda: self.trajectories.subscribers > 0, timeout))

    def change_mode(self, mode: str, timeout: float = 5.0) -> tuple[int, Any]:
        """Send a SetMode goal and wait for its end: (status, result)."""
        goal_id, accepted = self.set_mode.send_goal(mode=mode)
        assert accepted, f"SetMode {mode!r} was not accepted"
        return self.set_mode.result(goal_id, timeout)

    def duration(self, seconds: float) -> Any:
        whole = int(seconds)
        return self.library.new("builtin_interfaces/msg/Duration", sec=whole, nanosec=round((seconds - whole) * 1e9))

    def trajectory(self, points: Sequence[tuple[Sequence[float], float]],
                   joint_names: Sequence[str] = JOINT_NAMES, at_rest: bool = True) -> Any:
        """A JointTrajectory through (positions, time_from_start) points.

        `at_rest` gives every point zero velocities and accelerations, so each segment is a quintic that starts
        and ends smoothly and runs as sent; without, the points carry positions only, as `ros2 topic pub` users
        send them, and the driver smooths them.
        """
        new = self.library.new
        return new("trajectory_msgs/msg/JointTrajectory", joint_names=list(joint_names), points=[
            new("trajectory_msgs/msg/JointTrajectoryPoint", positions=[float(p) for p in positions],
                velocities=[0.0] * len(positions) if at_rest else [],
                accelerations=[0.0] * len(positions) if at_rest else [], time_from_start=self.duration(at))
            for positions, at in points])

    def send_trajectory(self, trajectory: Any, timeout: float = 5.0) -> bytes:
        """Send a FollowJointTrajectory goal; its id (it must be accepted: plem accepts, then aborts if invalid)."""
        goal_id, accepted = self.follow.send_goal(timeout, trajectory=trajectory)
        assert accepted, "the FollowJointTrajectory goal was not accepted"
        return goal_id

    def goal_status(self, goal_id: bytes) -> int | None:
        """The newest status of a FollowJointTrajectory goal from the action's status topic (None: not listed)."""
        for message in self.follow.status.take():
            self._goal_status.update({bytes(s.goal_info.goal_id.uuid): s.status for s in message.status_list})
        return self._goal_status.get(goal_id)

    def follow_goal(self, goal_id: bytes, timeout: float) -> tuple[int, Any, list[Any]]:
        """Wait for a goal's end, collecting its feedback: (status, result, feedback messages)."""
        feedback: list[Any] = []
        deadline = time.monotonic() + timeout
        while self.goal_status(goal_id) not in TERMINAL and time.monotonic() < deadline:
            feedback += [m for m in self.follow.feedback.take() if bytes(m.goal_id.uuid) == goal_id]
            time.sleep(0.02)
        feedback += [m for m in self.follow.feedback.take() if bytes(m.goal_id.uuid) == goal_id]
        status, result = self.follow.result(goal_id, max(1.0, deadline - time.monotonic()))
        return status, result, feedback

    def close(self) -> None:
        if self._owns_node:
            self.node.close()


def last(items: Sequence[Any]) -> Any:
    return items[-1] if items else None


def shifted(position: Sequence[float], joint: int, distance: float) -> list[float]:
    moved = [float(value) for value in position]
    moved[joint] += distance
    return moved


def main(argv: list[str]) -> int:
    """Two-host check: joint_states arrive, then hold and a FollowJointTrajectory goal; one JSON line out."""
    robot_id, plan = argv[0], json.loads(argv[1])
    peer = RosPeer(robot_id)
    report: dict[str, Any] = {"domain": peer.node.settings.describe()}
    started = time.monotonic()
    first = wait_for(lambda: peer.joint_states.take(), plan.get("discovery_timeout", 30))
    report["discovered_after_s"] = round(time.monotonic() - started, 3)
    if not first:
        report["error"] = "no joint_states"
        print(json.dumps(report), flush=True)
        return 1
    received, counting = list(first), time.monotonic()
    while time.monotonic() - counting < 1.0:  # the reader keeps only the last 10 (keep last 10, as ROS's default)
        received += peer.joint_states.take()
        time.sleep(0.02)
    report["joint_states"] = len(received)
    report["joint_state_rate"] = round((len(received) - len(first)) / (time.monotonic() - counting), 1)
    report["names"] = list(received[-1].name)
    report["servers"] = peer.wait_for_servers(plan.get("discovery_timeout", 30))
    status, result = peer.change_mode("hold")
    report["set_mode"] = {"status": status, "success": bool(result.success), "mode": result.mode}
    start = list(received[-1].position)
    target = shifted(start, plan.get("joint", 0), plan.get("distance", 0.2))
    goal_id = peer.send_trajectory(peer.trajectory([(target, plan.get("duration", 2.0))]))
    status, result, feedback = peer.follow_goal(goal_id, plan.get("duration", 2.0) + 10)
    report["follow"] = {"status": status, "error_code": result.error_code, "error_string": result.error_string,
                        "feedback": len(feedback)}
    report["start"], report["target"] = start, target
    report["final"] = peer.position()
    print(json.dumps(report), flush=True)
    peer.close()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
