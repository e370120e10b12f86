"""One robot's monitoring streams as ROS 2 messages, read from its shared-memory rings.

The bridge publishes these messages on DDS and the recorder writes them into bags; both take them
from a `MonitorFeed`, so the two see the same messages with the same stamps. rt_raw comes out as CDR
bytes (the fixed-layout encoder), the others as message structs.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from plem.bridge.client import RobotClient
from plem.control.events import Event
from plem.ipc.records import RAW_SCALARS, event_from_record
from plem.ipc.ring import RingReader
from plem.middleware.raw_cdr import RawEncoder
from plem.middleware.types import InterfaceLibrary

#: The monitoring topics under /{robot_id}/ and their types.
MONITOR_TOPICS = {
    "rt_raw": "plem_msgs/msg/RtRaw",
    "rt_events": "plem_msgs/msg/RtEvent",
    "rt_monitor_stats": "plem_msgs/msg/RtMonitorStats",
    "joint_states": "sensor_msgs/msg/JointState",
}
#: The topic (under /{robot_id}/) and type of the robot's URDF text, latched by the bridge and recorded with every
#: bag segment.
DESCRIPTION_TOPIC, DESCRIPTION_TYPE = "robot_description", "std_msgs/msg/String"
_TIMING_FIELDS = ("samples", "min_us", "mean_us", "p50_us", "p99_us", "p999_us", "max_us")


@dataclass(frozen=True)
class QueueCount:
    """Fill and counters of one queue, as rt_monitor_stats reports it."""

    name: str
    capacity: int
    fill: int
    written: int
    dropped: int


class MonitorSink(Protocol):
    """Where a feed's messages go (`wall_ns`: the message's stamp, ns since the epoch)."""

    def rt_raw(self, cdr: bytes, wall_ns: int) -> None:
        """One cycle's plem_msgs/RtRaw, already in CDR."""
        ...

    def joint_state(self, message: Any, wall_ns: int) -> None:
        """A sensor_msgs/JointState at the joint_states rate."""
        ...

    def rt_event(self, message: Any, event: Event, wall_ns: int) -> None:
        """A plem_msgs/RtEvent, with the event it was made from."""
        ...

    def rt_monitor_stats(self, message: Any, wall_ns: int) -> None:
        """A plem_msgs/RtMonitorStats for one record of the driver's statistics."""
        ...

    def queues(self) -> list[QueueCount]:
        """The sink's own queues, reported after the rings in rt_monitor_stats."""
        ...


class MonitorFeed:
    """Reads one robot's rt_raw, event and statistics rings and hands what is new to a sink as messages."""

    def __init__(self, client: RobotClient, library: InterfaceLibrary, joint_state_rate: float,
                 history: bool = False) -> None:
        """`history`: start with the cycles still in the ring (a recorder), not with the next one (a publisher)."""
        self.client = client
        self.library = library
        rings = client.channels.rings
        self.readers: dict[str, RingReader] = {"rt_raw": rings["rt_raw"].reader(from_oldest=history),
                                                "events": rings["events"].reader(from_oldest=True),
                                                "stats": rings["stats"].reader(from_oldest=history)}
        self._joint_period_ns = round(1e9 / joint_state_rate)
        self._next_joint_state = 0
        # Cycles carry CLOCK_MONOTONIC times; messages carry wall-clock stamps.
        self.wall_offset = time.time_ns() - time.monotonic_ns()
        self._encoder = RawEncoder(client.dof)

    def pump(self, sink: MonitorSink) -> int:
        """Hand everything new to `sink`; the number of rt_raw samples handed over.

        joint_states are the cycles whose time reaches the next joint_states period, so their rate is
        exact whatever the pump's own period.
        """
        count = 0
        raw = self.readers["rt_raw"]
        while (record := raw.read_values()) is not None:
            monotonic_ns = int(record[1])
            wall_ns = monotonic_ns + self.wall_offset
            sink.rt_raw(self._encoder.encode(record, wall_ns), wall_ns)
            if monotonic_ns >= self._next_joint_state:
                self._joint_state(sink, record)
                self._next_joint_state += self._joint_period_ns
                if self._next_joint_state <= monotonic_ns:        # the first one, or after a gap: no burst
                    self._next_joint_state = monotonic_ns + self._joint_period_ns
            count += 1
        for event_record in self.readers["events"].read_all():
            self._event(sink, event_record)
        for stats_record in self.readers["stats"].read_all():       # the driver writes them at 10 Hz
            self._stats(sink, json.loads(stats_record))
        return count

    def _header(self, monotonic_ns: int) -> tuple[Any, int]:
        wall_ns = monotonic_ns + self.wall_offset
        return self.library.new("std_msgs/msg/Header", stamp=self.library.stamp(wall_ns)), wall_ns

    def _joint_state(self, sink: MonitorSink, record: np.ndarray) -> None:
        scalars, dof = len(RAW_SCALARS), self.client.dof
        rows = record[scalars:scalars + 3 * dof].reshape(3, dof).tolist()
        header, wall_ns = self._header(int(record[1]))
        sink.joint_state(self.library.new(MONITOR_TOPICS["joint_states"], header=header,
                                          name=list(self.client.joint_names), position=rows[0],
                                          velocity=rows[1], effort=rows[2]), wall_ns)

    def _event(self, sink: MonitorSink, record: bytes) -> None:
        event = event_from_record(record)
        header, wall_ns = self._header(event.monotonic_ns)
        sink.rt_event(self.library.new(
            MONITOR_TOPICS["rt_events"], header=header, cycle=event.cycle, monotonic_ns=event.monotonic_ns,
            kind=event.kind.value, cause=event.cause, reason=event.reason, mode=event.mode.name.lower(),
            previous_mode="" if event.previous_mode is None else event.previous_mode.name.lower()), event, wall_ns)

    def _stats(self, sink: MonitorSink, driver: dict[str, Any]) -> None:
        """One record of the driver's loop statistics plus the fill and drop counters of every queue."""
        new = self.library.new
        timing = {key: new("plem_msgs/msg/TimingStats", **{f: driver[key][f] for f in _TIMING_FIELDS})
                  for key in ("latency", "compute", "latency_interval", "compute_interval")}
        commands = driver["commands"]
        queues = [new("plem_msgs/msg/QueueStats", name=q.name, capacity=q.capacity, fill=q.fill, written=q.written,
                      dropped=q.dropped) for q in [*self._ring_queues(driver), *sink.queues()]]
        header, wall_ns = self._header(driver["monotonic_ns"])
        sink.rt_monitor_stats(new(
            MONITOR_TOPICS["rt_monitor_stats"], header=header, cycles=driver["cycles"], overruns=driver["overruns"],
            missed_periods=driver["missed_periods"], period_ns=round(self.client.cycle_time_s * 1e9),
            mode=driver["mode"], fault_reason=driver["fault_reason"] or "", **timing,
            commands_received=commands["received"], commands_accepted=commands["accepted"],
            commands_rejected=commands["rejected"], bus_lost_frames=driver["bus"]["lost_frames"],
            bus_working_counter_errors=driver["bus"]["working_counter_errors"], queues=queues), wall_ns)

    def reader_queues(self) -> list[QueueCount]:
        """The rings this feed reads, as it reads them: fill and records lost to the writer."""
        rings = self.client.channels.rings
        return [QueueCount(name, rings[name].slots, reader.pending, rings[name].head, reader.dropped)
                for name, reader in self.readers.items()]

    def _ring_queues(self, driver: dict[str, Any]) -> list[QueueCount]:
        """The rings as this feed reads them, and the driver's command intake as the driver takes it."""
        intake = driver["command_queue"]
        return [*self.reader_queues(), QueueCount("commands", intake["capacity"], intake["fill"], intake["written"], 0)]
