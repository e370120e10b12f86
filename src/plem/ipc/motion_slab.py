"""The motion slab `/{robot_id}_motions`: planned motions handed from the command service to the loop.

A few fixed slots, each holding one piecewise-polynomial motion (segment count, final state, knots,
coefficients) as float64. The command service writes a motion into a slot the driver has released and
then names the slot in its start record; the driver's core samples it in place (`view` copies nothing), so
handing over a 5000-point trajectory costs the RT process the same few microseconds as a short one. The first
`shared_slots` are the command service's; the rest belong to motions planned in the driver's own process.
"""

from __future__ import annotations

import struct

import numpy as np

from plem.control.polynomial import ORDER, PolynomialMotion
from plem.ipc.request_bounds import MAX_POINTS
from plem.ipc.segment import SegmentError, SharedSegment

MAGIC = b"PLEMMOTN"
LAYOUT_VERSION = 2
HEADER_BYTES = 64
_HEADER = struct.Struct("<8sIIIII")  # magic, layout version, dof, slots, capacity (segments per slot), shared slots
#: Slots of the command service: the running motion, the next one, and one being written.
SLOTS = 3
#: Slots of motions planned in the RT driver's own process (its Robot's methods).
LOCAL_SLOTS = 2
#: Segments per slot: every point of the largest trajectory plus the segment from the start state.
CAPACITY = MAX_POINTS + 1


class MotionSlabError(SegmentError):
    """A slab is not usable, or a motion does not fit or does not match what its start record says."""


def _slot_values(dof: int, capacity: int) -> int:
    """float64 values of one slot: segment count, final state, knots, coefficients."""
    return 1 + 3 * dof + (capacity + 1) + capacity * ORDER * dof


class MotionSlab:
    """The slab mapped by the driver (`create`) or the command service (`attach`)."""

    def __init__(self, segment: SharedSegment | None, dof: int, slots: int, capacity: int, shared_slots: int,
                 memory: np.ndarray | None = None) -> None:
        self.name = segment.name if segment is not None else "(private)"
        self.dof = dof
        self.slots = slots
        self.capacity = capacity
        self.shared_slots = shared_slots
        self._segment = segment
        buffer: memoryview | np.ndarray | None = segment.buffer if segment is not None else memory
        if buffer is None:
            raise ValueError("a motion slab needs a shared segment or memory of its own")
        #: The whole slab, header included, as the compiled core reads it.
        self.buffer = buffer
        self._values = np.ndarray((slots, _slot_values(dof, capacity)), np.float64, self.buffer, HEADER_BYTES)

    @property
    def local_slots(self) -> range:
        """The slots of motions planned in the process that owns the loop."""
        return range(self.shared_slots, self.slots)

    @classmethod
    def private(cls, dof: int, slots: int = SLOTS, capacity: int = CAPACITY) -> MotionSlab:
        """A slab in this process's own memory, every slot local, for a robot whose loop runs here."""
        memory = np.zeros(HEADER_BYTES + slots * _slot_values(dof, capacity) * 8, dtype=np.uint8)
        memory[:_HEADER.size] = np.frombuffer(_HEADER.pack(MAGIC, LAYOUT_VERSION, dof, slots, capacity, 0), np.uint8)
        return cls(None, dof, slots, capacity, 0, memory)

    @classmethod
    def create(cls, name: str, dof: int, slots: int = SLOTS, capacity: int = CAPACITY,
               local_slots: int = LOCAL_SLOTS) -> MotionSlab:
        """A new slab, owner-only: only the driver and its command service ever map it."""
        size = HEADER_BYTES + (slots + local_slots) * _slot_values(dof, capacity) * 8
        segment = SharedSegment.create(name, size, 0o600)
        segment.buffer[:_HEADER.size] = _HEADER.pack(MAGIC, LAYOUT_VERSION, dof, slots + local_slots, capacity, slots)
        return cls(segment, dof, slots + local_slots, capacity, slots)

    @classmethod
    def attach(cls, name: str) -> MotionSlab:
        """Map an existing slab writable (the command service)."""
        segment = SharedSegment.open(name, writable=True)
        magic, version, dof, slots, capacity, shared = _HEADER.unpack_from(segment.buffer)
        if magic != MAGIC or version != LAYOUT_VERSION or not dof or not shared or shared > slots or \
                segment.size < HEADER_BYTES + slots * _slot_values(dof, capacity) * 8:
            segment.close()
            raise MotionSlabError(f"{name} is not a plem motion slab of this version",
                                  what=f"magic {MAGIC!r}, layout version {LAYOUT_VERSION} and a matching size",
                                  why=f"found magic {magic!r}, version {version}, {segment.size} bytes",
                                  how="run the same plem version for the driver and its command service")
        return cls(segment, dof, slots, capacity, shared)

    def _parts(self, slot: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        row, dof, capacity = self._values[slot], self.dof, self.capacity
        final = row[1:1 + 3 * dof].reshape(3, dof)
        knots = row[1 + 3 * dof:2 + 3 * dof + capacity]
        coefficients = row[2 + 3 * dof + capacity:].reshape(capacity, ORDER, dof)
        return row[:1], final, knots, coefficients

    def write(self, slot: int, motion: PolynomialMotion) -> int:
        """Store `motion` in `slot` (which the driver must have released); returns its segment count."""
        segments = motion.segments
        if segments > self.capacity:
            raise MotionSlabError("the motion has too many segments", what=f"at most {self.capacity} segments",
                                  why=f"it has {segments}", how="send fewer trajectory points")
        count, final, knots, coefficients = self._parts(slot)
        final[:] = (motion.final_positions, motion.final_velocities, motion.final_accelerations)
        knots[:segments + 1] = motion.knots[:segments + 1]
        coefficients[:segments] = motion.coefficients
        count[0] = segments
        return segments

    def view(self, slot: int, segments: int) -> PolynomialMotion:
        """The motion in `slot`, sampled in place; MotionSlabError when the slot does not hold `segments`."""
        if not (0 <= slot < self.slots and 0 <= segments <= self.capacity):
            raise MotionSlabError("a start record names no valid slot", what=f"slot < {self.slots}, "
                                  f"segments <= {self.capacity}", why=f"slot {slot}, {segments} segments",
                                  how="restart the robot (its command service is out of step)")
        count, final, knots, coefficients = self._parts(slot)
        if int(count[0]) != segments:
            raise MotionSlabError("the motion slot does not hold the announced motion",
                                  what=f"{segments} segments in slot {slot}", why=f"it holds {int(count[0])}",
                                  how="restart the robot (its command service is out of step)")
        return PolynomialMotion(knots[:segments + 1], coefficients[:segments], final)

    def close(self) -> None:
        """Drop the views, then unmap."""
        del self._values, self.buffer
        if self._segment is not None:
            self._segment.close()

    def remove(self) -> None:
        """Unmap and unlink (the driver's clean exit)."""
        self.close()
        if self._segment is not None:
            SharedSegment.unlink(self.name)
