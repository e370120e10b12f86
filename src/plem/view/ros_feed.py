"""A robot on another host, read over DDS from the topics its bridge publishes under `/{robot_id}/`: the URDF
(robot_description), the measured positions (joint_states), the commanded ones and the mode (rt_raw), the loop
statistics (rt_monitor_stats) and the faults (rt_events).

Every read takes what has arrived and never waits; the streams are read best effort with a history of one, so a
slow page drops old samples instead of working through them."""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from plem.control.events import EventKind
from plem.control.modes import Mode
from plem.middleware.monitor_feed import DESCRIPTION_TOPIC, DESCRIPTION_TYPE, MONITOR_TOPICS
from plem.middleware.node import Node, Subscription
from plem.middleware.qos import EVENTS, LATCHED, QosProfile
from plem.view.feed import Snapshot, drives_text, fault_text, latency_text, mode_text, recorder_text
from plem.view.server import ViewError

#: Only the newest sample of a stream matters to the view.
NEWEST = QosProfile(reliable=False, depth=1)
#: How often the constructor looks for the description and the first joint_states.
POLL_S = 0.05
#: What a readout shows before its topic has said anything.
NOT_REPORTED = "not reported"


class RosFeed:
    """Snapshots of a robot seen over DDS (`plem view --ros ROBOT_ID`)."""

    def __init__(self, robot_id: str, timeout_s: float = 10.0) -> None:
        """Join the domain and wait up to `timeout_s` for robot_description and the first joint_states."""
        self.robot_id = robot_id
        self.packages: dict[str, str] = {}  # package:// URIs resolve on this host's PLEM_PACKAGE_PATH
        self.node = Node()
        topics = {**MONITOR_TOPICS, DESCRIPTION_TOPIC: DESCRIPTION_TYPE}
        profiles = {DESCRIPTION_TOPIC: LATCHED, "rt_events": EVENTS}
        self._topics: dict[str, Subscription[Any]] = {
            name: self.node.subscription(f"/{robot_id}/{name}", ros_type, profiles.get(name, NEWEST))
            for name, ros_type in topics.items()}
        self._newest: dict[str, Any] = {}
        self._fault: Any = None
        self._readouts: dict[str, str] = {}
        try:
            self._wait_for_start(timeout_s)
        except BaseException:
            self.close()
            raise
        self.urdf: str = self._newest[DESCRIPTION_TOPIC].data
        self.joint_names: tuple[str, ...] = tuple(self._newest["joint_states"].name)

    def _wait_for_start(self, timeout_s: float) -> None:
        """Poll until robot_description and joint_states have arrived, for up to `timeout_s`; else ViewError."""
        deadline = time.monotonic() + timeout_s
        while self._take(DESCRIPTION_TOPIC) is None or self._take("joint_states") is None:
            if time.monotonic() >= deadline:
                raise self._not_seen(timeout_s)
            time.sleep(POLL_S)

    def _not_seen(self, timeout_s: float) -> ViewError:
        """What was and was not seen of the robot on the domain."""
        found = []
        for name in (DESCRIPTION_TOPIC, "joint_states"):
            topic = f"/{self.robot_id}/{name}"
            found.append(f"{topic} received" if name in self._newest else
                         f"{topic} has a publisher but sent nothing" if self._topics[name].publishers else
                         f"no publisher of {topic}")
        return ViewError(f"robot '{self.robot_id}' not seen over DDS",
                         what=f"robot_description and joint_states under /{self.robot_id}/, as `plem launch` "
                              "publishes them with bridge:=true",
                         why=f"{'; '.join(found)} within {timeout_s:g} s ({self.node.settings.describe()})",
                         how=f"check that robot {self.robot_id} runs with bridge:=true on the same ROS_DOMAIN_ID "
                             "(and a discovery range that reaches its host), and that `plem topic list` lists "
                             f"/{self.robot_id}/joint_states")

    def _take(self, name: str) -> Any:
        """Take what arrived on topic `name` and keep the newest."""
        messages = self._topics[name].take()
        if messages:
            self._newest[name] = messages[-1]
        return self._newest.get(name)

    def snapshot(self, readouts: bool) -> Snapshot | None:
        """The newest joint_states positions and rt_raw command; the readouts refreshed when asked."""
        joint_state, raw = self._take("joint_states"), self._take("rt_raw")
        if readouts:
            self._readouts = self._read_readouts(raw)
        command = None if raw is None else np.array(raw.command_position, dtype=float)
        return Snapshot(np.array(joint_state.position, dtype=float), command, self._readouts)

    def _read_readouts(self, raw: Any) -> dict[str, str]:
        """The readouts from the newest rt_raw, rt_monitor_stats and fault on rt_events."""
        stats = self._take("rt_monitor_stats")
        self._fault = next((event for event in reversed(self._topics["rt_events"].take())
                            if event.kind == EventKind.FAULT), self._fault)
        queues = {} if stats is None else {queue.name: queue for queue in stats.queues}
        recorder = recorder_text(queues.get("recorder:bag"), NOT_REPORTED)
        latency = (latency_text(None, None) if stats is None else
                   latency_text(stats.latency_interval.p99_us, stats.overruns))
        if raw is None:
            return {"mode": NOT_REPORTED, "drives": NOT_REPORTED, "fault": NOT_REPORTED, "latency": latency,
                    "recorder": recorder}
        return {"mode": mode_text(Mode(raw.mode), raw.faulted),
                "drives": drives_text(raw.drives_enabled, [], self.joint_names),
                "fault": fault_text(raw.faulted, "" if stats is None else stats.fault_reason, self._last_fault()),
                "latency": latency, "recorder": recorder}

    def _last_fault(self) -> tuple[str, float] | None:
        """The reason and wall time (s) of the newest fault seen on rt_events."""
        fault = self._fault
        return None if fault is None else (fault.reason, fault.header.stamp.sec + fault.header.stamp.nanosec * 1e-9)

    def close(self) -> None:
        """Leave the domain: the subscriptions, then the participant."""
        self._topics.clear()
        self.node.close()
