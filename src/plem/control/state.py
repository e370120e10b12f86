"""The joint-state block the loop publishes every cycle, readable without tearing (a seqlock).

The block is one float64 array of joint values plus an int64 header, over any writable buffer: plain
memory for a robot inside a Python process, POSIX shared memory for the RT driver process. The writer, the
compiled core's cycle, makes the sequence odd, copies, makes it even again; a reader retries until it copied
between two equal even sequence values, so it never sees a half-written sample and never blocks the writer.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from plem.control.modes import Mode

#: Rows of the joint-value array, in order.
ROWS = ("position", "velocity", "effort", "command_position", "command_velocity", "command_acceleration")


#: Slots of the int64 header, in order (the core writes them in this order; read indexes them directly).
HEADER = ("sequence", "cycle", "monotonic_ns", "mode", "faulted", "drives_enabled")
HEADER_SLOTS = len(HEADER)


@dataclass(frozen=True)
class JointState:
    """A consistent copy of one cycle's state (SI units)."""

    cycle: int
    monotonic_ns: int
    mode: Mode
    faulted: bool
    drives_enabled: bool
    position: np.ndarray
    velocity: np.ndarray
    effort: np.ndarray
    command_position: np.ndarray
    command_velocity: np.ndarray
    command_acceleration: np.ndarray


class StateBlock:
    """Header and joint values of one arm over `buffer` (allocated here when not given)."""

    def __init__(self, dof: int, buffer: memoryview | bytearray | None = None, offset: int = 0) -> None:
        self.dof = dof
        size = self.nbytes(dof)
        if buffer is None:
            buffer = bytearray(size)
        self.header = np.ndarray((HEADER_SLOTS,), dtype=np.int64, buffer=buffer, offset=offset)
        self.values = np.ndarray((len(ROWS), dof), dtype=np.float64, buffer=buffer, offset=offset + HEADER_SLOTS * 8)

    @staticmethod
    def nbytes(dof: int) -> int:
        """Bytes a block of `dof` joints occupies, for sizing a shared-memory segment."""
        return HEADER_SLOTS * 8 + len(ROWS) * dof * 8

    def publish(self, values: np.ndarray, cycle: int, monotonic_ns: int, mode: int, faulted: bool,
                drives_enabled: bool) -> None:
        """Write one cycle's state as the core does (a stand-in writer: tests and benchmarks of readers)."""
        header = self.header
        header[0] += 1
        np.copyto(self.values, values)
        header[1] = cycle
        header[2] = monotonic_ns
        header[3] = mode
        header[4] = faulted
        header[5] = drives_enabled
        header[0] += 1

    def read(self, retries: int = 10_000) -> JointState | None:
        """A consistent copy, or None if nothing was published yet or the writer kept interfering."""
        header = self.header
        for _ in range(retries):
            before = int(header[0])
            if before == 0:
                return None
            if before & 1:
                continue
            head = header.copy()
            values = self.values.copy()
            if int(header[0]) == before:
                return JointState(int(head[1]), int(head[2]), Mode(int(head[3])), bool(head[4]), bool(head[5]),
                                  *values)
        return None
