"""All shared memory of one robot: the state segment, its rings, the motion slab and the stream block, created by
the RT driver.

Every name starts with the robot_id, so robots on one host never share anything. The state segment
guards the set: creating it refuses a live driver and replaces a stale one, after which leftover rings
of the same robot are stale too and are replaced.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

from plem.control.events import FAULT_HISTORY, FAULT_KINDS, Event, EventLog
from plem.control.limits import ArmLimits
from plem.control.streaming import StreamBlock, stream_block_name
from plem.ipc.motion_slab import MotionSlab
from plem.ipc.records import event_record, raw_record_length
from plem.ipc.ring import SlotRing
from plem.ipc.segment import SharedSegment
from plem.ipc.state_segment import StateSegment, state_segment_name

_log = logging.getLogger("plem.ipc")


@dataclass(frozen=True)
class RingShape:
    """The size of one ring: its slots and their bytes, and whether writers wait for the consumer."""

    slot_bytes: int
    slots: int
    bounded: bool = False


#: The rings of a robot. rt_raw holds about four seconds at 1 kHz; events and stats drop their oldest records
#: when a reader falls behind. faults holds the faults and their clearing from the events, which other
#: events never push out. intake (command service → driver) is bounded, so nothing is dropped;
#: outcomes (driver → command service) holds far more answers than can be pending.
RINGS: dict[str, RingShape | None] = {
    "rt_raw": None,                                # one float64 record per cycle; sized by the DOF
    "events": RingShape(2048, 1024),
    "faults": RingShape(2048, FAULT_HISTORY),
    "stats": RingShape(8192, 64),
    "intake": RingShape(4096, 64, bounded=True),
    "outcomes": RingShape(4096, 1024),
}
#: Rings only the driver and its command service map: owner-only even when shm_group opens the others.
PRIVATE_RINGS = ("intake", "outcomes")
RAW_SLOTS = 4096


def channel_names(robot_id: str) -> dict[str, str]:
    """The shared-memory names of a robot: its state segment, each ring, the motion slab and the stream block."""
    return {"state": state_segment_name(robot_id), **{ring: f"/{robot_id}_{ring}" for ring in RINGS},
            "motions": f"/{robot_id}_motions", "stream": stream_block_name(robot_id)}


def _shape(ring: str, dof: int) -> RingShape:
    return RINGS[ring] or RingShape(raw_record_length(dof) * 8, RAW_SLOTS)


class RobotChannels:
    """The state segment and rings of one robot, as the driver (`create`) or a client (`attach`) maps them."""

    def __init__(self, robot_id: str, state: StateSegment, rings: dict[str, SlotRing],
                 motions: MotionSlab | None = None, stream: StreamBlock | None = None) -> None:
        self.robot_id = robot_id
        self.state = state
        self.rings = rings
        self.motions = motions
        self.stream = stream

    @property
    def names(self) -> dict[str, str]:
        """The shared-memory names of this robot's channels."""
        return channel_names(self.robot_id)

    @classmethod
    def create(cls, robot_id: str, limits: ArmLimits, cycle_time_ns: int, *,
               poses: Mapping[str, Sequence[float]] | None = None, mode: int = 0o600, group: int | None = None,
               warn: Callable[[str], None] = _log.warning) -> RobotChannels:
        """The driver's set; refuses a robot_id whose driver is alive, replaces a crashed run's leftovers."""
        state = StateSegment.create(robot_id, limits, cycle_time_ns, poses=poses, mode=mode, group=group, warn=warn)
        rings: dict[str, SlotRing] = {}
        names = channel_names(robot_id)
        try:
            for ring in RINGS:
                SharedSegment.unlink(names[ring])  # the state segment was free or stale, so this is a leftover
                shape = _shape(ring, limits.dof)
                private = ring in PRIVATE_RINGS
                rings[ring] = SlotRing.create(names[ring], shape.slot_bytes, shape.slots, bounded=shape.bounded,
                                              mode=0o600 if private else mode, group=None if private else group)
            SharedSegment.unlink(names["motions"])
            motions = MotionSlab.create(names["motions"], limits.dof)
            SharedSegment.unlink(names["stream"])
            stream = StreamBlock.create(names["stream"], limits.dof)
        except BaseException:
            for created in rings.values():
                created.remove()
            for name in ("motions", "stream"):
                SharedSegment.unlink(names[name])
            state.remove()
            raise
        return cls(robot_id, state, rings, motions, stream)

    def publish_events(self, log: EventLog) -> None:
        """The driver's side: write every later event of `log` into the events ring, faults also into faults."""
        events, faults = self.rings["events"], self.rings["faults"]

        def publish(event: Event) -> None:
            record = event_record(event, events.slot_bytes)
            events.write(record)
            if event.kind in FAULT_KINDS:
                faults.write(record)

        log.subscribe(publish)

    @classmethod
    def attach(cls, robot_id: str, expected_dof: int | None = None) -> RobotChannels:
        """A client's view: the state segment and the public rings, read-only."""
        state = StateSegment.attach(robot_id, expected_dof)
        return cls._with_rings(robot_id, state, [ring for ring in RINGS if ring not in PRIVATE_RINGS], service=False)

    @classmethod
    def attach_service(cls, robot_id: str) -> RobotChannels:
        """The command service's view: the state segment, intake writable, outcomes readable, the motion slab."""
        return cls._with_rings(robot_id, StateSegment.attach(robot_id), list(PRIVATE_RINGS), service=True)

    @classmethod
    def _with_rings(cls, robot_id: str, state: StateSegment, rings: list[str], service: bool) -> RobotChannels:
        names = channel_names(robot_id)
        attached: dict[str, SlotRing] = {}
        try:
            for ring in rings:
                attached[ring] = SlotRing.attach(names[ring], writable=service and ring == "intake")
            motions = MotionSlab.attach(names["motions"]) if service else None
        except BaseException:
            for ring_ in attached.values():
                ring_.close()
            state.close()
            raise
        return cls(robot_id, state, attached, motions)

    def close(self) -> None:
        """Unmap every ring, the motion slab and the state segment; the names stay for others."""
        for ring in self.rings.values():
            ring.close()
        if self.motions is not None:
            self.motions.close()
        if self.stream is not None:
            self.stream.close()
        self.state.close()

    def remove(self) -> None:
        """The driver's clean exit: unmap and unlink everything."""
        for ring in self.rings.values():
            ring.remove()
        if self.motions is not None:
            self.motions.remove()
        if self.stream is not None:
            self.stream.remove()
        self.state.remove()
