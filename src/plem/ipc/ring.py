"""Record rings in POSIX shared memory: fixed-size slots written without blocking, read by other processes.

For record n the writer marks slot n % slots with sequence 2n+1, copies, marks it 2n+2 and then advances
`head` (x86 keeps stores in order, as in the seqlock of `plem.control.state`); a reader keeps a copy only
if the slot read 2n+2 before and after it, so it never sees a torn record and counts those it lost.
Every ring has one writer. A drop-oldest ring overwrites what slow readers missed; a bounded ring refuses
writes until its single consumer frees a slot. Neither takes a lock, so no other process can hold up the
writer or the reader.
"""

from __future__ import annotations

import os
import struct
from typing import Literal, overload

import numpy as np

from plem.ipc.segment import SegmentError, SharedSegment

MAGIC = b"PLEMRING"
LAYOUT_VERSION = 1
HEADER_BYTES = 64
SLOT_HEADER_BYTES = 16                    # seq u64, length u32, pad u32
BOUNDED = 1
_HEADER = struct.Struct("<8sIIII")        # magic, layout version, slot_bytes, slots, flags
_HOT_OFFSET = 32                          # int64 head, consumer, writer_pid
HEAD, CONSUMER, WRITER_PID = range(3)


class RingError(SegmentError):
    """A segment is not a usable ring, or a record does not fit it."""


class SlotRing:
    """A ring mapped by its creator (`create`) or by another process (`attach`)."""

    def __init__(self, segment: SharedSegment, slot_bytes: int, slots: int, bounded: bool) -> None:
        self.name = segment.name
        self.slot_bytes = slot_bytes
        self.slots = slots
        self.bounded = bounded
        self._segment = segment
        buffer, stride = segment.buffer, SLOT_HEADER_BYTES + slot_bytes
        self._hot = np.ndarray((3,), np.int64, buffer, _HOT_OFFSET)
        self._seq = np.ndarray((slots,), np.uint64, buffer, HEADER_BYTES, (stride,))
        self._len = np.ndarray((slots,), np.uint32, buffer, HEADER_BYTES + 8, (stride,))
        payload = HEADER_BYTES + SLOT_HEADER_BYTES
        self._data = np.ndarray((slots, slot_bytes), np.uint8, buffer, payload, (stride, 1))
        self._f64 = np.ndarray((slots, slot_bytes // 8), np.float64, buffer, payload, (stride, 8))
        self._rows = list(self._f64)

    @staticmethod
    def size(slot_bytes: int, slots: int) -> int:
        """Bytes of a ring segment: the header, then per slot its sequence, length and payload."""
        return HEADER_BYTES + slots * (SLOT_HEADER_BYTES + slot_bytes)

    @classmethod
    def create(cls, name: str, slot_bytes: int, slots: int, *, bounded: bool = False, mode: int = 0o600,
               group: int | None = None) -> SlotRing:
        """Create an empty ring of `slots` records of up to `slot_bytes` bytes (rounded up to 8)."""
        if slot_bytes < 1 or slots < 1:
            raise RingError(f"invalid ring {name}", what="at least one slot of at least one byte",
                            why=f"slot_bytes={slot_bytes}, slots={slots}", how="pass positive sizes")
        slot_bytes = -(-slot_bytes // 8) * 8
        segment = SharedSegment.create(name, cls.size(slot_bytes, slots), mode, group)
        segment.buffer[:_HEADER.size] = _HEADER.pack(MAGIC, LAYOUT_VERSION, slot_bytes, slots, BOUNDED * bounded)
        ring = cls(segment, slot_bytes, slots, bounded)
        ring._hot[WRITER_PID] = os.getpid()
        return ring

    @classmethod
    def attach(cls, name: str, *, writable: bool = False) -> SlotRing:
        """Map an existing ring; RingError unless its magic, layout version and size match."""
        segment = SharedSegment.open(name, writable)
        try:
            magic, version, slot_bytes, slots, flags = _HEADER.unpack_from(segment.buffer)
        except struct.error:
            magic = version = slot_bytes = slots = flags = 0
        if magic != MAGIC or version != LAYOUT_VERSION:
            segment.close()
            raise RingError(f"{name} is not a plem ring of this version",
                            what=f"magic {MAGIC!r} with layout version {LAYOUT_VERSION}",
                            why=f"found magic {magic!r}, version {version}",
                            how="run the same plem version for the driver and the client, "
                                "or check the segment name")
        if slot_bytes % 8 or not slots or segment.size < cls.size(slot_bytes, slots):
            segment.close()
            raise RingError(f"{name} is inconsistent", what="slot size, slot count and segment size that agree",
                            why=f"{slots} slots of {slot_bytes} bytes in {segment.size} bytes",
                            how="restart the process that creates it (the ring will be recreated)")
        return cls(segment, slot_bytes, slots, bool(flags & BOUNDED))

    @property
    def buffer(self) -> memoryview:
        """The whole ring, header included, as the compiled core writes rt_raw records into it."""
        return self._segment.buffer

    @property
    def writable(self) -> bool:
        """True when this process mapped the ring for writing."""
        return self._segment.writable

    @property
    def head(self) -> int:
        """Number of records ever written."""
        return int(self._hot[HEAD])

    @property
    def writer_pid(self) -> int:
        """The process that created the ring."""
        return int(self._hot[WRITER_PID])

    def write(self, payload: bytes | bytearray | memoryview) -> bool:
        """Append one record; a bounded ring returns False (writing nothing) while it is full."""
        data = np.frombuffer(payload, np.uint8)
        if data.size > self.slot_bytes:
            raise RingError(f"record too large for ring {self.name}", what=f"at most {self.slot_bytes} bytes",
                            why=f"got {data.size} bytes", how="send smaller records or create a ring "
                                                              "with larger slots")
        if self.bounded and self.head - int(self._hot[CONSUMER]) >= self.slots:
            return False
        self._put(data)
        return True

    def write_values(self, values: np.ndarray) -> None:
        """Append one record of slot_bytes/8 float64 values without allocating (the RT loop's write)."""
        if self.bounded or values.shape != (self.slot_bytes // 8,):
            raise RingError(f"cannot write values to ring {self.name}",
                            what=f"a drop-oldest ring and {self.slot_bytes // 8} float64 values",
                            why=f"{'bounded' if self.bounded else 'drop-oldest'} ring, values of shape "
                                f"{values.shape}", how="use write() on bounded rings; match the slot size")
        n, i = self._begin()
        np.copyto(self._rows[i], values)
        self._end(n, i, self.slot_bytes)

    def _put(self, data: np.ndarray) -> None:
        n, i = self._begin()
        self._data[i, :data.size] = data
        self._end(n, i, data.size)

    def _begin(self) -> tuple[int, int]:
        n = int(self._hot[HEAD])
        i = n % self.slots
        self._seq[i] = 2 * n + 1
        return n, i

    def _end(self, n: int, i: int, length: int) -> None:
        self._len[i] = length
        self._seq[i] = 2 * n + 2
        self._hot[HEAD] = n + 1

    @overload
    def _take(self, n: int, values: Literal[False]) -> bytes | None: ...
    @overload
    def _take(self, n: int, values: Literal[True]) -> np.ndarray | None: ...
    @overload
    def _take(self, n: int, values: bool) -> bytes | np.ndarray | None: ...
    def _take(self, n: int, values: bool) -> bytes | np.ndarray | None:
        """A copy of record n, or None when it was overwritten before or during the copy."""
        i = n % self.slots
        before = int(self._seq[i])
        if before != 2 * n + 2:
            return None
        record = self._f64[i].copy() if values else self._data[i, :self._len[i]].tobytes()
        return record if int(self._seq[i]) == before else None

    def newest(self) -> bytes | None:
        """A copy of the latest record, or None when there is none (or it was overwritten during the copy)."""
        head = self.head
        return self._take(head - 1, values=False) if head else None

    def reader(self, *, from_oldest: bool = False) -> RingReader:
        """A reader starting at the next record, or at the oldest record the ring still holds."""
        head = self.head
        return RingReader(self, max(head - self.slots, 0) if from_oldest else head)

    def consumer(self) -> RingConsumer:
        """The single consumer of a bounded ring; its cursor in the header frees slots for producers."""
        if not (self.bounded and self._segment.writable):
            raise RingError(f"ring {self.name} has no consumer here", what="a bounded ring attached writable",
                            why=f"bounded={self.bounded}, writable={self._segment.writable}",
                            how="use reader() on drop-oldest rings; attach with writable=True to consume")
        return RingConsumer(self)

    def close(self) -> None:
        """Drop the views, then unmap."""
        del self._hot, self._seq, self._len, self._data, self._f64, self._rows
        self._segment.close()

    def remove(self) -> None:
        """Unmap and unlink (the creator's clean exit)."""
        self.close()
        SharedSegment.unlink(self.name)


class RingReader:
    """One reader's cursor over a ring; `dropped` counts records it lost to the writer."""

    def __init__(self, ring: SlotRing, cursor: int) -> None:
        self._ring = ring
        self._cursor = cursor
        self.dropped = 0

    @property
    def pending(self) -> int:
        """Records written but not yet read (at most one ring): the fill level this reader sees."""
        return min(self._ring.head - self._cursor, self._ring.slots)

    @overload
    def _next(self, values: Literal[False]) -> bytes | None: ...
    @overload
    def _next(self, values: Literal[True]) -> np.ndarray | None: ...
    def _next(self, values: bool) -> bytes | np.ndarray | None:
        ring = self._ring
        while (head := ring.head) > self._cursor:
            if head - self._cursor > ring.slots:
                self.dropped += head - ring.slots - self._cursor
                self._cursor = head - ring.slots
            record = ring._take(self._cursor, values)
            self._cursor += 1
            if record is not None:
                return record
            self.dropped += 1
        return None

    def read(self) -> bytes | None:
        """The next record, or None when there is nothing new."""
        return self._next(values=False)

    def read_all(self, limit: int | None = None) -> list[bytes]:
        """Every new record (at most `limit`), oldest first."""
        records: list[bytes] = []
        while (limit is None or len(records) < limit) and (record := self.read()) is not None:
            records.append(record)
        return records

    def read_values(self) -> np.ndarray | None:
        """A float64 copy of the next record of a `write_values` ring, or None when there is nothing new."""
        return self._next(values=True)

    def read_values_many(self) -> np.ndarray:
        """A float64 copy of every new record of a `write_values` ring at once, oldest first (shape: records ×
        values); records overwritten before or during the copy are left out and counted in `dropped`."""
        ring = self._ring
        head = ring.head
        if head - self._cursor > ring.slots:
            self.dropped += head - ring.slots - self._cursor
            self._cursor = head - ring.slots
        numbers = np.arange(self._cursor, head, dtype=np.int64)
        slots = numbers % ring.slots
        expected = (2 * numbers + 2).astype(np.uint64)
        before = ring._seq[slots]
        records = ring._f64[slots]                           # a copy (fancy indexing), then the seqlock check
        whole = (before == expected) & (ring._seq[slots] == before)
        self.dropped += int(numbers.size - np.count_nonzero(whole))
        self._cursor = head
        return records if whole.all() else records[whole]


class RingConsumer:
    """The single consumer of a bounded ring, whose cursor lives in the shared header."""

    def __init__(self, ring: SlotRing) -> None:
        self._ring = ring

    @property
    def pending(self) -> int:
        """Records written and not yet taken."""
        return self._ring.head - int(self._ring._hot[CONSUMER])

    def read(self) -> bytes | None:
        """The next record, freeing its slot for the producer after the copy; None when the ring is empty."""
        ring = self._ring
        n = int(ring._hot[CONSUMER])
        if n >= ring.head:
            return None
        record = ring._take(n, values=False)
        ring._hot[CONSUMER] = n + 1
        return record
