"""All shared memory of one robot: the state segment and its rings, created by the RT driver, attached by clients.

Every name starts with the robot_id, so robots on one host never share anything. The state segment
guards the set: creating it refuses a live driver and replaces a stale one, after which leftover rings
of the same robot are stale too and are replaced.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

from plem.control.limits import ArmLimits
from plem.ipc.records import raw_record_length
from plem.ipc.ring import SlotRing
from plem.ipc.segment import SharedSegment, segment_path
from plem.ipc.state_segment import StateSegment, state_segment_name

_log = logging.getLogger("plem.ipc")


@dataclass(frozen=True)
class RingShape:
    slot_bytes: int
    slots: int
    bounded: bool = False


#: The rings of a robot. rt_raw holds about four seconds at 1 kHz; commands are bounded (never dropped:
#: a full ring refuses the request); the rest drop their oldest records when a reader falls behind.
RINGS: dict[str, RingShape | None] = {
    "rt_raw": None,                                # one float64 record per cycle; sized by the DOF
    "events": RingShape(2048, 1024),
    "stats": RingShape(8192, 64),
    "commands": RingShape(1 << 20, 16, bounded=True),
    "replies": RingShape(4096, 1024),
}
RAW_SLOTS = 4096


def channel_names(robot_id: str) -> dict[str, str]:
    """The shared-memory names of a robot: its state segment and each ring."""
    return {"state": state_segment_name(robot_id), **{ring: f"/{robot_id}_{ring}" for ring in RINGS}}


def _shape(ring: str, dof: int) -> RingShape:
    return RINGS[ring] or RingShape(raw_record_length(dof) * 8, RAW_SLOTS)


def _attach_for_commands(name: str) -> SlotRing:
    """The command ring writable when permitted; read-only for users who may watch but not command."""
    if os.access(segment_path(name), os.W_OK):
        return SlotRing.attach(name, writable=True)
    return SlotRing.attach(name)


class RobotChannels:
    """The state segment and rings of one robot, as the driver (`create`) or a client (`attach`) maps them."""

    def __init__(self, robot_id: str, state: StateSegment, rings: dict[str, SlotRing]) -> None:
        self.robot_id = robot_id
        self.state = state
        self.rings = rings

    @property
    def names(self) -> dict[str, str]:
        return channel_names(self.robot_id)

    @classmethod
    def create(cls, robot_id: str, limits: ArmLimits, cycle_time_ns: int, *,
               poses: Mapping[str, Sequence[float]] | None = None, mode: int = 0o600, group: int | None = None,
               warn: Callable[[str], None] = _log.warning) -> RobotChannels:
        """The driver's set; refuses a robot_id whose driver is alive, replaces a crashed run's leftovers."""
        state = StateSegment.create(robot_id, limits, cycle_time_ns, poses=poses, mode=mode, group=group, warn=warn)
        rings: dict[str, SlotRing] = {}
        try:
            for ring, name in channel_names(robot_id).items():
                if ring == "state":
                    continue
                SharedSegment.unlink(name)  # the state segment was free or stale, so this is a leftover
                shape = _shape(ring, limits.dof)
                rings[ring] = SlotRing.create(name, shape.slot_bytes, shape.slots, bounded=shape.bounded,
                                              mode=mode, group=group)
        except BaseException:
            for created in rings.values():
                created.remove()
            state.remove()
            raise
        return cls(robot_id, state, rings)

    @classmethod
    def attach(cls, robot_id: str, expected_dof: int | None = None) -> RobotChannels:
        """A client's view: the state segment read-only, the command ring writable, the others readable."""
        state = StateSegment.attach(robot_id, expected_dof)
        rings: dict[str, SlotRing] = {}
        try:
            for ring, name in channel_names(robot_id).items():
                if ring == "commands":
                    rings[ring] = _attach_for_commands(name)
                elif ring != "state":
                    rings[ring] = SlotRing.attach(name)
        except BaseException:
            for attached in rings.values():
                attached.close()
            state.close()
            raise
        return cls(robot_id, state, rings)

    def close(self) -> None:
        for ring in self.rings.values():
            ring.close()
        self.state.close()

    def remove(self) -> None:
        """The driver's clean exit: unmap and unlink everything."""
        for ring in self.rings.values():
            ring.remove()
        self.state.remove()
