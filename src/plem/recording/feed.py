"""The recorder's reading of one robot's rings: everything new in one batch per pump, serialised in bulk.

A `MonitorFeed` hands messages over one by one, which costs the recorder tens of microseconds of Python per
1 kHz cycle. A `RecordingFeed` reads every new rt_raw record in one copy, encodes the RtRaw and
JointState payloads of the whole batch with numpy, and gives the recorder the batch with the few other
messages (events, statistics); the recorder writes them in stamp order. Events and statistics are read
before rt_raw, so a record the driver wrote before them is in this batch rather than the next one.
"""

from __future__ import annotations

import json
from typing import Any, Protocol

import numpy as np

from plem.bridge.client import RobotClient
from plem.control.events import Event
from plem.middleware.monitor_feed import MonitorFeed, QueueCount
from plem.middleware.types import InterfaceLibrary
from plem.recording.bulk_cdr import JointStateEncoder, raw_payloads
from plem.recording.recorder import Messages


class BatchSink(Protocol):
    """Where a `RecordingFeed`'s batches go (the `Recorder`)."""

    def record(self, batch: list[Messages]) -> None:
        """Messages of several topics, each topic's in stamp order."""
        ...

    def queues(self) -> list[QueueCount]:
        """The sink's own queues, reported in rt_monitor_stats."""
        ...


class _Singles:
    """A MonitorSink that keeps what `MonitorFeed` hands it as serialised messages (events and statistics)."""

    def __init__(self, sink: BatchSink) -> None:
        self.sink = sink
        self.messages: list[Messages] = []

    def rt_raw(self, cdr: bytes, wall_ns: int) -> None:
        self.messages.append(Messages.one("rt_raw", wall_ns, cdr))

    def joint_state(self, message: Any, wall_ns: int) -> None:
        self.messages.append(Messages.one("joint_states", wall_ns, message.serialize()))

    def rt_event(self, message: Any, event: Event, wall_ns: int) -> None:
        self.messages.append(Messages.one("rt_events", wall_ns, message.serialize(), event))

    def rt_monitor_stats(self, message: Any, wall_ns: int) -> None:
        self.messages.append(Messages.one("rt_monitor_stats", wall_ns, message.serialize()))

    def queues(self) -> list[QueueCount]:
        return self.sink.queues()


class RecordingFeed(MonitorFeed):
    """A `MonitorFeed` from the oldest records the rings hold, pumped into a `BatchSink` one batch at a time."""

    def __init__(self, client: RobotClient, library: InterfaceLibrary, joint_state_rate: float) -> None:
        super().__init__(client, library, joint_state_rate, history=True)
        self._joint_states = JointStateEncoder(client.joint_names)

    def pump_batch(self, sink: BatchSink) -> int:
        """Hand everything new to `sink` as one batch; the number of rt_raw samples in it."""
        singles = _Singles(sink)
        for event_record in self.readers["events"].read_all():
            self._event(singles, event_record)
        for stats_record in self.readers["stats"].read_all():
            self._stats(singles, json.loads(stats_record))
        records = self.readers["rt_raw"].read_values_many()
        wall_ns = records[:, 1].astype(np.int64) + self.wall_offset
        picks = self._joint_state_picks(records[:, 1].astype(np.int64))
        joint_states = self._joint_states.payloads(records[picks], wall_ns[picks])
        sink.record([Messages("rt_raw", wall_ns, raw_payloads(records, wall_ns, self.client.dof)),
                     Messages("joint_states", wall_ns[picks], joint_states), *singles.messages])
        return len(records)

    def _joint_state_picks(self, monotonic_ns: np.ndarray) -> list[int]:
        """The records that are joint_states: each the first to reach the next joint_states period, as
        `MonitorFeed` picks them one by one (after a gap the periods restart, never a burst)."""
        picks: list[int] = []
        index = 0
        while True:
            index += int(np.searchsorted(monotonic_ns[index:], self._next_joint_state))
            if index >= len(monotonic_ns):
                return picks
            stamp = int(monotonic_ns[index])
            picks.append(index)
            self._next_joint_state += self._joint_period_ns
            if self._next_joint_state <= stamp:
                self._next_joint_state = stamp + self._joint_period_ns
            index += 1
