"""A line of emulated EtherCAT slaves answering frames the way the real ring does, with fault injection.

Every datagram of a frame passes every slave in network order. Auto-increment addressing (APxx, ARMW)
acts at the slave where ADP is 0 and each slave increments ADP; configured addressing (FPxx, FRMW) acts
at the slave whose station address is ADP; broadcasts act everywhere (reads OR their data in) and count
ADP up; logical datagrams go through each slave's FMMUs. Working counters: +1 per read, +1 per write,
read-write +1 for the read and +2 for the write; ARMW/FRMW +1 where the slave read or wrote. The answer
leaves with the locally administered bit set in its source MAC, as a real ESC marks it. A frame that
carried process data to a slave is followed by one `application.step(operational)`.

Faults, seeded and deterministic: `drop_rate` (frames lost), `delay_s` (answered late, by the wire),
`disappear`/`reappear` (a slave bridged out of the line: it neither answers nor counts, and its
watchdog runs out like a real drive's). Watchdogs are checked on each frame and on `poll`, so they expire
when no frames come at all.
"""

from __future__ import annotations

import random
import time
from collections.abc import Sequence

import numpy as np

from plem.errors import PlemError
from plem.fieldbus.ethercat.virtual import frames
from plem.fieldbus.ethercat.virtual.application import DriveApplication
from plem.fieldbus.ethercat.virtual.esc import Esc
from plem.fieldbus.ethercat.virtual.frames import Command
from plem.fieldbus.ethercat.virtual.sii import SlaveIdentity
from plem.fieldbus.ethercat.virtual.stack import OP, DriveStack

#: Time a frame takes from one slave's port 0 to the next one's, for the receive times DC latches.
HOP_NS = 300

_POSITION = (Command.APRD, Command.APWR, Command.APRW, Command.ARMW)
_BROADCAST = (Command.BRD, Command.BWR, Command.BRW)
_READS = (Command.APRD, Command.FPRD, Command.BRD)
_WRITES = (Command.APWR, Command.FPWR, Command.BWR)
_READ_WRITES = (Command.APRW, Command.FPRW, Command.BRW)


class Segment:
    """The emulated slaves of one virtual network, in network order, in front of the drives' application."""

    def __init__(self, identities: Sequence[SlaveIdentity], application: DriveApplication, *, seed: int = 0,
                 missing_objects: frozenset[int] = frozenset()) -> None:
        if len(identities) != application.count:
            raise PlemError(f"{len(identities)} slave identities for {application.count} drives",
                            what=f"the segment got {len(identities)} identities, the application has "
                                 f"{application.count} drives",
                            why="each slave of the segment is one drive of the application, in network order",
                            how="give one identity per drive")
        self.application = application
        self.drop_rate = 0.0
        self.delay_s = 0.0
        self._random = random.Random(seed)
        self.stacks = tuple(DriveStack(identity, application, drive, clock_offset_ns=self._random.randrange(10 ** 12),
                                       missing_objects=missing_objects)
                            for drive, identity in enumerate(identities))
        self._present = [True] * len(self.stacks)
        self._line: tuple[Esc, ...] = ()
        self._operational = np.zeros(len(self.stacks), dtype=bool)
        self._cycle_due = False
        self._relink()

    def disappear(self, slave: int) -> None:
        """Take slave `slave` (0-based, network order) out of the line: frames pass by it."""
        self._present[slave] = False
        self._relink()

    def reappear(self, slave: int) -> None:
        """Put slave `slave` back into the line, in whatever state its firmware is in by now."""
        self._present[slave] = True
        self._relink()

    def poll(self, now: float) -> None:
        """Let the slaves notice what time alone changes (watchdogs); `now` is time.monotonic()."""
        now_ns = round(now * 1e9)
        for stack in self.stacks:
            stack.poll(now_ns)

    def process(self, frame: bytes) -> bytes | None:
        """The frame as it comes back from the line, or None when it is lost (dropped, malformed, no slaves)."""
        if self.drop_rate and self._random.random() < self.drop_rate:
            return None
        line = self._line
        if not line:
            return None
        try:
            decoded = frames.decode(frame)
        except frames.FrameError:
            return None
        now_ns = time.monotonic_ns()
        for stack in self.stacks:
            stack.poll(now_ns)
        for esc in line:
            esc.frame_ns = now_ns
        process_data = False
        for datagram in decoded.datagrams:
            command = datagram.command
            if Command.LRD <= command <= Command.LRW:
                address, data, wkc = datagram.logical, datagram.data, 0
                for esc in line:
                    wkc += esc.logical(command, address, data)
                datagram.wkc += wkc
                process_data = process_data or wkc > 0
            elif command != Command.NOP:
                self._registers(datagram, line)
        self._cycle_due = self._cycle_due or process_data
        decoded.mark_passed()
        return decoded.encode()

    def finish_cycle(self) -> None:
        """After a process-data frame's answer left: outputs in, one application step, inputs out for the next.

        Real slaves answer at wire speed and run their application on their own time; stepping the drives
        only once the answer is on its way keeps their computation out of the master's round trip.
        """
        if self._cycle_due:
            self._cycle_due = False
            self._cycle()

    def _registers(self, datagram: frames.Datagram, line: tuple[Esc, ...]) -> None:
        """A physically addressed datagram (auto-increment, configured, broadcast) on its way along the line."""
        command, address, data = datagram.command, datagram.ado, datagram.data
        position, broadcast = command in _POSITION, command in _BROADCAST
        multiple = command in (Command.ARMW, Command.FRMW)
        for esc in line:
            if position or broadcast:
                here = broadcast or datagram.adp == 0
                datagram.adp = (datagram.adp + 1) & 0xFFFF
            else:
                here = esc.station == datagram.adp
            if multiple:
                read, write = here, not here
            elif here:
                read = command in _READS or command in _READ_WRITES
                write = command in _WRITES or command in _READ_WRITES
            else:
                continue
            incoming = bytes(data) if write else b""
            if read:
                value = esc.read(address, len(data))
                if value is not None:
                    if broadcast:
                        value = (int.from_bytes(data, "little") | int.from_bytes(value, "little")).to_bytes(
                            len(data), "little")
                    data[:] = value
                    datagram.wkc += 1
            if write and esc.write(address, incoming):
                datagram.wkc += 2 if command in _READ_WRITES else 1

    def _cycle(self) -> None:
        stacks, mask = self.stacks, self._operational
        for drive, stack in enumerate(stacks):
            stack.take_outputs()
            mask[drive] = stack.state == OP
        self.application.step(mask)
        for stack in stacks:
            stack.give_inputs()

    def _relink(self) -> None:
        self._line = tuple(stack.esc for stack, present in zip(self.stacks, self._present, strict=True) if present)
        last = len(self._line) - 1
        for position, esc in enumerate(self._line):
            esc.set_links(downstream=position < last)
            esc.forward_ns = position * HOP_NS
            esc.return_ns = (2 * last - position) * HOP_NS if position < last else None
