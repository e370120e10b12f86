"""One robot on ROS 2: its shared memory published as topics, ROS commands passed to its RT driver.

Under `/{robot_id}/` it publishes joint_states, robot_description (latched), rt_raw (every cycle),
rt_events and rt_monitor_stats (10 Hz), and serves joint_trajectory_controller's topic and action and
the wim_rt_driver/set_mode action. It only reads shared memory and writes the command ring through
`RobotClient`, so nothing it does (or a slow subscriber does to it) can delay the loop; what it could
not keep up with is counted in rt_monitor_stats.
"""

from __future__ import annotations

import json
import logging
import threading
import time
from typing import Any

import numpy as np
from cyclonedds.util import duration

from plem.bridge.client import RobotClient
from plem.errors import PlemError
from plem.ipc.records import RAW_SCALARS, event_from_record
from plem.ipc.ring import RingReader
from plem.middleware.action import ActionServer
from plem.middleware.goals import FJT, start_mode_change, start_trajectory, trajectory_from_message
from plem.middleware.node import Node
from plem.middleware.qos import DEFAULT, EVENTS, LATCHED, RT_RAW
from plem.middleware.raw_cdr import RawEncoder

_log = logging.getLogger("plem.bridge")
STATS_PERIOD_NS = 100_000_000
#: joint_states follows controllers.yaml's update rate, at most this often (Hz).
MAX_JOINT_STATE_RATE = 100.0
_TIMING_FIELDS = ("samples", "min_us", "mean_us", "p50_us", "p99_us", "p999_us", "max_us")


class RobotBridge:
    """Publishes one robot's shared memory on ROS 2 and serves its ROS 2 commands."""

    def __init__(self, client: RobotClient, node: Node, description: str, joint_state_rate: float) -> None:
        self.client = client
        self.node = node
        self.library = node.library
        self.namespace = f"/{client.robot_id}"
        ns = self.namespace
        self.joint_states = node.publisher(f"{ns}/joint_states", "sensor_msgs/msg/JointState", DEFAULT)
        self.description = node.publisher(f"{ns}/robot_description", "std_msgs/msg/String", LATCHED)
        self.rt_raw = node.publisher(f"{ns}/rt_raw", "plem_msgs/msg/RtRaw", RT_RAW)
        self.rt_events = node.publisher(f"{ns}/rt_events", "plem_msgs/msg/RtEvent", EVENTS)
        self.rt_stats = node.publisher(f"{ns}/rt_monitor_stats", "plem_msgs/msg/RtMonitorStats", DEFAULT)
        self.trajectories = node.subscription(f"{ns}/joint_trajectory_controller/joint_trajectory",
                                              "trajectory_msgs/msg/JointTrajectory", DEFAULT)
        self.follow = ActionServer(node, f"{ns}/joint_trajectory_controller/follow_joint_trajectory", FJT,
                                   lambda goal: start_trajectory(client, self.library, goal))
        self.set_mode = ActionServer(node, f"{ns}/wim_rt_driver/set_mode", "plem_msgs/action/SetMode",
                                     lambda goal: start_mode_change(client, goal))
        self.description.publish(self.description.message(data=description))
        rings = client.channels.rings
        self._raw = rings["rt_raw"].reader()
        self._events = rings["events"].reader(from_oldest=True)
        self._stats = rings["stats"].reader()
        self._joint_period_ns = round(1e9 / joint_state_rate)
        self._next_joint_state = 0
        self._next_stats = 0
        # Cycles carry CLOCK_MONOTONIC times; messages carry wall-clock stamps.
        self._wall_offset = time.time_ns() - time.monotonic_ns()
        self._newest: np.ndarray | None = None
        self._raw_encoder = RawEncoder(client.dof)

    # -- shared memory → topics -----------------------------------------------------------------------
    def pump(self) -> int:
        """Publish everything new in shared memory; the number of rt_raw samples published."""
        published = 0
        while (record := self._raw.read_values()) is not None:
            self._publish_raw(record)
            self._newest = record
            published += 1
        now = time.monotonic_ns()
        if self._newest is not None and now >= self._next_joint_state:
            self._publish_joint_state(self._newest)
            self._next_joint_state = max(self._next_joint_state + self._joint_period_ns, now)
        for record in self._events.read_all():
            self._publish_event(record)
        if now >= self._next_stats:
            self._publish_stats()
            self._next_stats = now + STATS_PERIOD_NS
        return published

    def _stamp(self, monotonic_ns: int) -> Any:
        return self.library.stamp(monotonic_ns + self._wall_offset)

    def _publish_raw(self, record: np.ndarray) -> None:
        self.rt_raw.publish_cdr(self._raw_encoder.encode(record, int(record[1]) + self._wall_offset))

    def _publish_joint_state(self, record: np.ndarray) -> None:
        scalars, dof = len(RAW_SCALARS), self.client.dof
        rows = record[scalars:scalars + 3 * dof].reshape(3, dof).tolist()
        header = self.library.new("std_msgs/msg/Header", stamp=self._stamp(int(record[1])))
        self.joint_states.publish(self.joint_states.message(header=header, name=list(self.client.joint_names),
                                                            position=rows[0], velocity=rows[1], effort=rows[2]))

    def _publish_event(self, record: bytes) -> None:
        event = event_from_record(record)
        header = self.library.new("std_msgs/msg/Header", stamp=self._stamp(event.monotonic_ns))
        self.rt_events.publish(self.rt_events.message(
            header=header, cycle=event.cycle, monotonic_ns=event.monotonic_ns, kind=event.kind.value,
            cause=event.cause, reason=event.reason, mode=event.mode.name.lower(),
            previous_mode="" if event.previous_mode is None else event.previous_mode.name.lower()))

    def _publish_stats(self) -> None:
        """The driver's newest loop statistics plus the fill and drop counters of every queue."""
        driver: dict[str, Any] = {}
        for record in self._stats.read_all():
            driver = json.loads(record)
        if not driver:
            return
        new = self.library.new
        timing = {key: new("plem_msgs/msg/TimingStats", **{f: driver[key][f] for f in _TIMING_FIELDS})
                  for key in ("latency", "compute", "latency_interval", "compute_interval")}
        commands = driver["commands"]
        self.rt_stats.publish(self.rt_stats.message(
            header=new("std_msgs/msg/Header", stamp=self._stamp(driver["monotonic_ns"])),
            cycles=driver["cycles"], overruns=driver["overruns"], missed_periods=driver["missed_periods"],
            period_ns=round(self.client.cycle_time_s * 1e9), mode=driver["mode"],
            fault_reason=driver["fault_reason"] or "", **timing, commands_received=commands["received"],
            commands_accepted=commands["accepted"], commands_rejected=commands["rejected"],
            queues=self._queues(driver)))

    def _queues(self, driver: dict[str, Any]) -> list[Any]:
        """Rings as this bridge reads them, the command ring as the driver takes it, the DDS publishers."""
        new, rings = self.library.new, self.client.channels.rings
        readers: dict[str, RingReader] = {"rt_raw": self._raw, "events": self._events, "stats": self._stats}
        queues = []
        for name, ring in rings.items():
            reader = readers.get(name)
            if reader is not None:
                fill, dropped = reader.pending, reader.dropped
            elif name == "commands":
                fill, dropped = max(0, ring.head - driver["commands"]["received"]), 0
            else:
                continue
            queues.append(new("plem_msgs/msg/QueueStats", name=name, capacity=ring.slots, fill=fill,
                              written=ring.head, dropped=dropped))
        for publisher, name, profile in ((self.rt_raw, "rt_raw", RT_RAW), (self.joint_states, "joint_states", DEFAULT),
                                         (self.rt_events, "rt_events", EVENTS)):
            queues.append(new("plem_msgs/msg/QueueStats", name=f"dds:{name}", capacity=profile.depth, fill=0,
                              written=publisher.published, dropped=publisher.dropped))
        return queues

    # -- ROS commands → command ring ------------------------------------------------------------------
    def serve_commands(self, stop: threading.Event, period: float = 0.01) -> None:
        """Take trajectories and action requests until `stop`; runs in its own thread."""
        waitset = self.node.waitset([self.trajectories, *self.follow.services, *self.set_mode.services])
        timeout = duration(seconds=period)
        while not stop.is_set():
            waitset.wait(timeout)
            try:
                for message in self.trajectories.take():
                    self._on_trajectory(message)
                self.follow.spin_once()
                self.set_mode.spin_once()
            except Exception:  # one bad request must not end command service for everyone
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
