"""One robot on ROS 2: its shared memory published as topics, ROS commands passed to its RT driver.

Under `/{robot_id}/` it publishes joint_states, robot_description and robot_description_semantic (latched; the
latter when the package has an SRDF), rt_raw (every cycle),
rt_events and rt_monitor_stats (10 Hz), and serves joint_trajectory_controller's topic and action and
the wim_rt_driver/set_mode action. A read-only bridge (`commands=False`) creates none of these command
endpoints, so nothing on the network can command the arm through it. It only reads shared memory and
sends commands to the robot's command service through `RobotClient`, so nothing it does (or a slow
subscriber does to it) can delay the loop; what it could not keep up with is counted in rt_monitor_stats.
"""

from __future__ import annotations

import logging
import threading
from typing import Any

from cyclonedds.util import duration

from plem.bridge.client import RobotClient
from plem.control.events import Event
from plem.errors import PlemError
from plem.middleware.action import ActionServer
from plem.middleware.goals import FJT, start_mode_change, start_trajectory, trajectory_from_message
from plem.middleware.monitor_feed import MONITOR_TOPICS, MonitorFeed, QueueCount
from plem.middleware.node import Node, Subscription
from plem.middleware.qos import DEFAULT, EVENTS, LATCHED, RT_RAW
from plem.recording.status import read_status

_log = logging.getLogger("plem.bridge")


class RobotBridge:
    """Publishes one robot's shared memory on ROS 2 and, unless read-only, serves its ROS 2 commands."""

    trajectories: Subscription[Any]
    follow: ActionServer
    set_mode: ActionServer

    def __init__(self, client: RobotClient, node: Node, description: str, joint_state_rate: float,
                 commands: bool = True, semantic: str | None = None) -> None:
        self.client = client
        self.node = node
        self.library = node.library
        self.namespace = f"/{client.robot_id}"
        self.commands = commands
        ns = self.namespace
        profiles = {"rt_raw": RT_RAW, "rt_events": EVENTS, "rt_monitor_stats": DEFAULT, "joint_states": DEFAULT}
        self.publishers = {name: node.publisher(f"{ns}/{name}", ros_type, profiles[name])
                           for name, ros_type in MONITOR_TOPICS.items()}
        self.description = node.publisher(f"{ns}/robot_description", "std_msgs/msg/String", LATCHED)
        if commands:
            self._command_endpoints()
        self.description.publish(self.description.message(data=description))
        if semantic is not None:
            self.semantic = node.publisher(f"{ns}/robot_description_semantic", "std_msgs/msg/String", LATCHED)
            self.semantic.publish(self.semantic.message(data=semantic))
        self.feed = MonitorFeed(client, self.library, joint_state_rate)
        self._profiles = profiles

    def _command_endpoints(self) -> None:
        """joint_trajectory_controller's topic and action and the set_mode action, as ROS 2 names them."""
        client, node, ns = self.client, self.node, self.namespace
        self.trajectories = node.subscription(f"{ns}/joint_trajectory_controller/joint_trajectory",
                                              "trajectory_msgs/msg/JointTrajectory", DEFAULT)
        self.follow = ActionServer(node, f"{ns}/joint_trajectory_controller/follow_joint_trajectory", FJT,
                                   lambda goal: start_trajectory(client, self.library, goal))
        self.set_mode = ActionServer(node, f"{ns}/wim_rt_driver/set_mode", "plem_msgs/action/SetMode",
                                     lambda goal: start_mode_change(client, goal))

    # -- shared memory → topics -----------------------------------------------------------------------
    def pump(self) -> int:
        """Publish everything new in shared memory; the number of rt_raw samples published."""
        return self.feed.pump(self)

    def rt_raw(self, cdr: bytes, wall_ns: int) -> None:
        """Publish one rt_raw sample as it is, in CDR."""
        self.publishers["rt_raw"].publish_cdr(cdr)

    def joint_state(self, message: Any, wall_ns: int) -> None:
        """Publish on joint_states."""
        self.publishers["joint_states"].publish(message)

    def rt_event(self, message: Any, event: Event, wall_ns: int) -> None:
        """Publish on rt_events."""
        self.publishers["rt_events"].publish(message)

    def rt_monitor_stats(self, message: Any, wall_ns: int) -> None:
        """Publish on rt_monitor_stats."""
        self.publishers["rt_monitor_stats"].publish(message)

    def queues(self) -> list[QueueCount]:
        """The DDS publishers that could refuse a write (fill is not exposed by Cyclone DDS), then the recorder's."""
        publishers = [QueueCount(f"dds:{name}", self._profiles[name].depth, 0, self.publishers[name].published,
                                 self.publishers[name].dropped) for name in ("rt_raw", "joint_states", "rt_events")]
        return [*publishers, *read_status(self.client.robot_id)]

    # -- ROS commands → command service ---------------------------------------------------------------
    def serve_commands(self, stop: threading.Event, period: float = 0.01) -> None:
        """Take trajectories and action requests until `stop`; runs in its own thread (not when read-only)."""
        waitset = self.node.waitset([self.trajectories, *self.follow.services, *self.set_mode.services])
        timeout = duration(seconds=period)
        while not stop.is_set():
            waitset.wait(timeout)
            try:
                for message in self.trajectories.take():
                    self._on_trajectory(message)
                self.follow.spin_once()
                self.set_mode.spin_once()
            except Exception:  # noqa: BLE001 - one bad request must not end command service for everyone
                _log.exception("a ROS command could not be handled; serving goes on")

    def _on_trajectory(self, message: Any) -> None:
        """joint_trajectory_controller's topic: a trajectory replaces the running one; an empty one stops."""
        try:
            if not message.points:
                self.client.stop()
                return
            self.client.execute_trajectory(trajectory_from_message(message))
        except PlemError as error:
            _log.warning("joint_trajectory refused:\n%s", error.render())
