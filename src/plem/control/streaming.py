"""Streaming targets to the core: the stream block a client writes samples into and the core reads every cycle.

A sample is a joint position target (`servo_joints`) or a joint velocity (`speed_joints`, `jog`), stamped with the
writer's monotonic clock. The core follows the newest one with its jerk-limited follower (`plem_follow`), so a
late, missing or jumping sample is smoothed within every limit; a stream without samples for its timeout brings
the arm to rest and ends. The block is written under a seqlock with a checksum, so the core never takes a torn
sample or a mix of two writers'; it writes back which sample it used, when, and the speed override in force.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from plem.control.compiled import CONSTANTS as C
from plem.control.compiled import STREAM_BLOCK, new
from plem.ipc import request_bounds as bounds
from plem.ipc.segment import SharedSegment

#: Samples the core takes: joint positions (rad) or joint velocities (rad/s).
KINDS = {"position": C["PLEM_STREAM_POSITION"], "velocity": C["PLEM_STREAM_VELOCITY"]}
#: How long a stream may go without a sample before the arm is brought to rest and the stream ends (moveit_servo's
#: incoming_command_timeout is 0.1 s too).
DEFAULT_TIMEOUT_S = 0.1
#: The longest timeout a stream may ask for: a stream that stopped arriving must not keep the arm moving long.
MAX_TIMEOUT_S = 5.0
_STATES = {C["PLEM_STREAM_NONE"]: "none", C["PLEM_STREAM_FOLLOWING"]: "following",
           C["PLEM_STREAM_TIMED_OUT"]: "timed out"}
_MASK = (1 << 64) - 1


def stream_timeout(value: object) -> float:
    """A stream's timeout (s), checked: above 0 and at most MAX_TIMEOUT_S."""
    return bounds.number(value, "the stream timeout", 0.0, MAX_TIMEOUT_S, low_open=True)


def override_factor(value: object) -> float:
    """A speed override, checked: from 0 (stopped on the path) to 1 (as planned)."""
    return bounds.number(value, "the speed override", 0.0, 1.0)


def stream_block_name(robot_id: str) -> str:
    """The shared-memory name of a robot's stream block (owner-only, as its motion slab)."""
    return f"/{robot_id}_stream"


def checksum(session: int, count: int, kind: int, stamp_ns: int, targets: np.ndarray) -> int:
    """FNV-1a over a sample's words, as the core computes it (a torn or mixed sample fails it)."""
    words = [session, count, kind & _MASK, stamp_ns & _MASK, *np.ascontiguousarray(targets, np.float64).view(np.uint64)]
    total = 0xcbf29ce484222325
    for word in words:
        total = ((total ^ int(word)) * 0x100000001b3) & _MASK
    return total


@dataclass(frozen=True)
class StreamStatus:
    """What the core reports about streaming and the speed override, as of its last cycle."""

    session: int            # the stream the core follows; 0 for none
    state: str              # "none", "following", or "timed out" (coming to rest)
    used_count: int         # the last sample a cycle used
    used_cycle: int         # that cycle
    latency_ns: int         # that sample's stamp to the cycle that first used it
    speed_override: float   # the factor in force
    override_target: float  # the factor asked for
    external_torque: np.ndarray  # estimated external torque per joint (N·m), 0 while not estimated
    wrench: np.ndarray           # the same as a wrench at the flange: force (N) then torque (N·m), base frame


class StreamBlock:
    """One robot's stream block: in the RT driver's shared memory, or private to an in-process robot."""

    def __init__(self, buffer: memoryview | np.ndarray, dof: int, segment: SharedSegment | None = None) -> None:
        #: The block as the compiled core takes it.
        self.buffer = buffer
        self._segment = segment
        self.dof = dof
        self._view = np.ndarray((1,), STREAM_BLOCK, buffer)[0]
        self._lock = threading.Lock()
        self._count = 0

    @classmethod
    def private(cls, dof: int) -> StreamBlock:
        """A block in this process's own memory."""
        return cls(new(STREAM_BLOCK), dof)

    @classmethod
    def create(cls, name: str, dof: int) -> StreamBlock:
        """The RT driver's block in shared memory, readable and writable by its own user only."""
        segment = SharedSegment.create(name, STREAM_BLOCK.itemsize, mode=0o600)
        return cls(segment.buffer, dof, segment)

    @classmethod
    def attach(cls, name: str, dof: int) -> StreamBlock:
        """A client's view of a driver's block, to write samples into."""
        segment = SharedSegment.open(name, writable=True)
        return cls(segment.buffer, dof, segment)

    def close(self) -> None:
        """Unmap a shared block (the name stays for others)."""
        if self._segment is not None:
            self._segment.close()

    def remove(self) -> None:
        """The driver's clean exit: unmap and unlink a shared block."""
        if self._segment is not None:
            self._segment.close()
            SharedSegment.unlink(self._segment.name)

    def write(self, session: int, kind: str, targets: Sequence[float] | np.ndarray, stamp_ns: int | None = None) -> int:
        """Write one sample of stream `session`, stamped now or at `stamp_ns` (CLOCK_MONOTONIC: the time the
        targets are for, later than the last sample's); returns its number. Targets are checked by the caller."""
        values = np.zeros(len(self._view["target"]), np.float64)
        values[:self.dof] = targets
        code = KINDS[kind]
        view = self._view
        with self._lock:
            self._count += 1
            stamp = time.monotonic_ns() if stamp_ns is None else stamp_ns
            total = checksum(session, self._count, code, stamp, values[:self.dof])
            sequence = int(view["sequence"])
            view["sequence"] = sequence + 1 if sequence % 2 == 0 else sequence + 2
            view["session"], view["count"], view["kind"], view["stamp_ns"] = session, self._count, code, stamp
            view["target"] = values
            view["checksum"] = total
            view["sequence"] = int(view["sequence"]) + 1
            return self._count

    def status(self) -> StreamStatus:
        """The core's side of the block, as of its last cycle."""
        view = self._view
        return StreamStatus(int(view["used_session"]), _STATES.get(int(view["state"]), "none"),
                            int(view["used_count"]), int(view["used_cycle"]), int(view["latency_ns"]),
                            float(view["speed_override"]), float(view["override_target"]),
                            view["external"][:self.dof].copy(), view["wrench"].copy())
