"""EtherCAT frames on Ethernet: decoding, the chained datagrams, and encoding the answer.

A frame is decoded in place. Each `Datagram` holds a view on its data inside the frame's buffer, so the
slaves read and write process data where it lies, and `Frame.encode` only writes back the header fields
a slave changes on the way (ADP, IRQ, working counter).
"""

from __future__ import annotations

import struct
from enum import IntEnum

ETHERTYPE = 0x88A4
#: The EtherCAT header's type of a frame that carries datagrams (the other types are not processed by slaves).
TYPE_DATAGRAMS = 1
ETHERNET_HEADER = 14
DATAGRAM_HEADER = 10
WKC_SIZE = 2
#: The datagram's length word: 11 bits of length, and the flag saying that another datagram follows.
LENGTH_MASK = 0x07FF
MORE = 0x8000

_DATAGRAM_HEADER = struct.Struct("<BBHHHH")   # command, index, ADP, ADO, length and flags, IRQ
_WORD = struct.Struct("<H")
_IRQ_AT = 8                                    # offset of the IRQ word in the datagram header
_ADP_AT = 2


class Command(IntEnum):
    """Datagram commands: auto-increment (AP), configured (FP), broadcast (B) and logical (L) addressing."""

    NOP = 0
    APRD = 1
    APWR = 2
    APRW = 3
    FPRD = 4
    FPWR = 5
    FPRW = 6
    BRD = 7
    BWR = 8
    BRW = 9
    LRD = 10
    LWR = 11
    LRW = 12
    ARMW = 13
    FRMW = 14


class FrameError(ValueError):
    """Bytes that are not a well-formed EtherCAT frame; a slave controller drops such a frame."""


class Datagram:
    """One datagram: command, index, address (ADP/ADO, or a 32-bit logical address), data and working counter."""

    __slots__ = ("command", "index", "adp", "ado", "data", "irq", "wkc", "_at")

    def __init__(self, command: int, index: int, adp: int, ado: int, data: memoryview, irq: int, wkc: int,
                 at: int) -> None:
        self.command = command
        self.index = index
        self.adp = adp
        self.ado = ado
        self.data = data
        self.irq = irq
        self.wkc = wkc
        self._at = at                              # where the datagram starts in its frame's buffer

    @property
    def logical(self) -> int:
        """The 32-bit logical address of an LRD/LWR/LRW datagram (ADP is its low word)."""
        return self.adp | self.ado << 16


class Frame:
    """A decoded frame: its buffer (edited in place by the slaves) and its datagrams in order."""

    __slots__ = ("buffer", "datagrams")

    def __init__(self, buffer: bytearray, datagrams: list[Datagram]) -> None:
        self.buffer = buffer
        self.datagrams = datagrams

    def mark_passed(self) -> None:
        """Set the locally administered bit of the source address, as a slave controller does on the way."""
        self.buffer[6] |= 0x02

    def encode(self) -> bytes:
        """The frame with the ADP, IRQ and working counter of every datagram written back."""
        buffer = self.buffer
        for datagram in self.datagrams:
            at = datagram._at
            _WORD.pack_into(buffer, at + _ADP_AT, datagram.adp & 0xFFFF)
            _WORD.pack_into(buffer, at + _IRQ_AT, datagram.irq & 0xFFFF)
            _WORD.pack_into(buffer, at + DATAGRAM_HEADER + len(datagram.data), datagram.wkc & 0xFFFF)
        return bytes(buffer)


def decode(raw: bytes) -> Frame:
    """Parse an Ethernet frame of EtherCAT datagrams; raise FrameError when it is not one."""
    if len(raw) < ETHERNET_HEADER + 2 or raw[12] != ETHERTYPE >> 8 or raw[13] != ETHERTYPE & 0xFF:
        raise FrameError("not an EtherCAT frame (ethertype 0x88A4)")
    buffer = bytearray(raw)
    (header,) = _WORD.unpack_from(buffer, ETHERNET_HEADER)
    if header >> 12 != TYPE_DATAGRAMS:
        raise FrameError(f"EtherCAT header type {header >> 12} carries no datagrams")
    end = ETHERNET_HEADER + 2 + (header & LENGTH_MASK)
    if end > len(buffer):
        raise FrameError(f"EtherCAT header says {header & LENGTH_MASK} bytes, the frame holds {len(buffer) - 16}")
    view = memoryview(buffer)
    datagrams = []
    at = ETHERNET_HEADER + 2
    more = True
    while more:
        if at + DATAGRAM_HEADER + WKC_SIZE > end:
            raise FrameError("datagram runs past the end of the EtherCAT frame")
        command, index, adp, ado, flags, irq = _DATAGRAM_HEADER.unpack_from(buffer, at)
        length = flags & LENGTH_MASK
        data_at = at + DATAGRAM_HEADER
        if data_at + length + WKC_SIZE > end:
            raise FrameError("datagram runs past the end of the EtherCAT frame")
        datagrams.append(Datagram(command, index, adp, ado, view[data_at:data_at + length], irq,
                                  buffer[data_at + length] | buffer[data_at + length + 1] << 8, at))
        at = data_at + length + WKC_SIZE
        more = bool(flags & MORE)
    return Frame(buffer, datagrams)

