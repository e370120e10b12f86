"""What the RT driver's outbound rings carry: one rt_raw sample per cycle, events, loop statistics.

An rt_raw sample is one float64 record: the state block's header scalars (cycle, time, mode, fault,
drives enabled), this cycle's wake-up latency and the previous cycle's compute time, then the state
block's joint rows, then the speed override in force. Events and statistics are rare and travel as JSON.
"""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np

from plem.control.events import Event, EventKind
from plem.control.modes import Mode
from plem.control.state import ROWS, JointState

RAW_SCALARS = ("cycle", "monotonic_ns", "mode", "faulted", "drives_enabled", "latency_ns", "compute_ns")


def raw_record_length(dof: int) -> int:
    """Float64 values in one rt_raw record of an arm with `dof` joints."""
    return raw_override_column(dof) + 1


def raw_override_column(dof: int) -> int:
    """Where an rt_raw record of an arm with `dof` joints holds the speed override: after the joint rows."""
    return len(RAW_SCALARS) + len(ROWS) * dof


def raw_scalars(record: np.ndarray) -> list[int]:
    """The leading scalars of an rt_raw record (RAW_SCALARS, in that order) as integers."""
    return [int(value) for value in record[:len(RAW_SCALARS)]]


@dataclass(frozen=True)
class RawSample(JointState):
    """One cycle as the loop saw it, with its wake-up latency and the previous cycle's compute time (ns)."""

    latency_ns: int
    compute_ns: int
    speed_override: float

    @classmethod
    def from_record(cls, record: np.ndarray, dof: int) -> RawSample:
        """The sample in one rt_raw record of an arm with `dof` joints; the joint rows are views into it."""
        column = raw_override_column(dof)
        position, velocity, effort, command_position, command_velocity, command_acceleration = (
            record[len(RAW_SCALARS):column].reshape(len(ROWS), dof))
        cycle, stamp, mode, faulted, enabled, latency, compute = raw_scalars(record)
        return cls(cycle, stamp, Mode(mode), bool(faulted), bool(enabled), position, velocity, effort,
                   command_position, command_velocity, command_acceleration, latency, compute,
                   float(record[column]))


def event_record(event: Event, max_bytes: int = 1024) -> bytes:
    """An event as one JSON record of at most `max_bytes`; a reason too long for that is cut short, marked '…'."""
    reason = event.reason
    while True:
        record = json.dumps({"kind": event.kind.value, "cause": event.cause[:64], "reason": reason,
                             "mode": event.mode.name, "cycle": event.cycle, "monotonic_ns": event.monotonic_ns,
                             "wall_time": event.wall_time,
                             "previous_mode": None if event.previous_mode is None else event.previous_mode.name
                             }).encode()
        if len(record) <= max_bytes or not reason:
            return record
        keep = max(0, len(reason) * max_bytes // len(record) - 16)
        reason = reason[:keep] + "…" if keep else ""


def event_from_record(record: bytes) -> Event:
    """The event in one JSON record written by `event_record`."""
    data = json.loads(record)
    previous = data["previous_mode"]
    return Event(EventKind(data["kind"]), data["cause"], data["reason"], Mode[data["mode"]], data["cycle"],
                 data["monotonic_ns"], data["wall_time"], None if previous is None else Mode[previous])
