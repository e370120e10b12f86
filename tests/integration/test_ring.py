"""Record rings in real POSIX shared memory, written and read by real processes."""

from __future__ import annotations

import stat
import struct
import subprocess
import sys
import textwrap
import time
import uuid

import numpy as np
import pytest

from plem.ipc.ring import RingError, SlotRing
from plem.ipc.segment import SharedSegment, segment_path


@pytest.fixture
def name():
    ring_name = f"/test_ring_{uuid.uuid4().hex[:8]}"
    yield ring_name
    SharedSegment.unlink(ring_name)


def start(code: str) -> subprocess.Popen:
    """A Python process running `code`."""
    return subprocess.Popen([sys.executable, "-c", textwrap.dedent(code)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def test_bytes_and_values_round_trip_with_owner_only_permissions(name):
    ring = SlotRing.create(name, 20, 4)
    assert ring.slot_bytes == 24 and not ring.bounded
    assert stat.S_IMODE(segment_path(name).stat().st_mode) == 0o600
    reader = SlotRing.attach(name)
    assert (reader.slot_bytes, reader.slots, reader.bounded) == (24, 4, False)
    cursor = reader.reader()
    assert cursor.read() is None
    assert ring.write(b"") and ring.write(bytearray(b"abc")) and ring.write(memoryview(b"x" * 24))
    assert cursor.pending == 3
    assert cursor.read_all() == [b"", b"abc", b"x" * 24] and cursor.pending == 0
    ring.write_values(np.array([1.5, -2.0, 3.25]))
    values = cursor.read_values()
    assert np.array_equal(values, [1.5, -2.0, 3.25]) and values.dtype == np.float64
    assert reader.head == 4 and cursor.dropped == 0
    reader.close()
    ring.remove()
    assert not SharedSegment.exists(name)


def test_reader_from_head_sees_only_new_records_from_oldest_sees_what_is_held(name):
    ring = SlotRing.create(name, 8, 4)
    assert ring.newest() is None
    for k in range(6):
        ring.write(bytes([k]))
    assert ring.newest() == bytes([5])
    assert ring.reader().read() is None
    oldest = ring.reader(from_oldest=True)
    assert oldest.read_all(limit=3) == [bytes([2]), bytes([3]), bytes([4])]
    ring.write(b"\x06")
    assert oldest.read_all() == [b"\x05", b"\x06"] and oldest.dropped == 0
    ring.remove()


def test_slow_reader_counts_exactly_the_lost_records_then_reads_the_newest_in_order(name):
    ring = SlotRing.create(name, 8, 4)
    reader = ring.reader()
    for k in range(11):
        ring.write(struct.pack("<q", k))
    assert reader.pending == 4
    assert [struct.unpack("<q", r)[0] for r in reader.read_all()] == [7, 8, 9, 10]
    assert reader.dropped == 7
    ring.remove()


def test_bounded_ring_refuses_when_full_and_accepts_after_the_consumer_read(name):
    ring = SlotRing.create(name, 8, 2, bounded=True)
    client = SlotRing.attach(name, writable=True)
    consumer = ring.consumer()
    assert client.bounded and client.write(b"a") and client.write(b"b")
    assert not client.write(b"c") and ring.head == 2
    assert consumer.read() == b"a"
    assert client.write(b"c")
    assert [consumer.read(), consumer.read(), consumer.read()] == [b"b", b"c", None]
    client.close()
    ring.remove()


def test_a_producer_process_delivers_every_record_exactly_once_untorn(name):
    ring = SlotRing.create(name, 64, 8, bounded=True)
    consumer = ring.consumer()
    producer = start(f"""
        import struct
        from plem.ipc.ring import SlotRing
        ring = SlotRing.attach({name!r}, writable=True)
        for k in range(1000):
            while not ring.write(struct.pack("<I", k) * 16):
                pass
    """)
    received: list[int] = []
    deadline = time.monotonic() + 20
    while len(received) < 1000 and time.monotonic() < deadline:
        record = consumer.read()
        if record is not None:
            assert record == record[:4] * 16, "torn record"
            received.append(struct.unpack("<I", record[:4])[0])
    assert producer.wait(timeout=10) == 0, producer.stderr.read()
    assert consumer.read() is None
    assert received == list(range(1000))
    ring.remove()


def test_reader_never_sees_a_torn_record_from_a_writer_at_full_speed(name):
    writer = start(f"""
        import numpy as np
        from plem.ipc.ring import SlotRing
        ring = SlotRing.create({name!r}, 8 * 1024, 8)
        values = np.zeros(1024)
        print("ready", flush=True)
        n = 0
        while True:
            values[:] = n
            ring.write_values(values)
            n += 1
    """)
    try:
        assert writer.stdout.readline().strip() == "ready", writer.stderr.read()
        ring = SlotRing.attach(name)
        assert ring.writer_pid == writer.pid
        reader = ring.reader()
        seen: list[int] = []
        dropped_before_first = 0
        deadline = time.monotonic() + 0.8
        while time.monotonic() < deadline:
            values = reader.read_values()
            if values is None:
                continue
            assert np.all(values == values[0]), f"torn record: {np.unique(values)}"
            if not seen:
                dropped_before_first = reader.dropped
            seen.append(int(values[0]))
            if len(seen) % 64 == 0:
                time.sleep(0.0005)  # fall a ring behind now and then
    finally:
        writer.kill()
        writer.wait()
    assert len(seen) > 100 and reader.dropped > dropped_before_first
    assert all(a < b for a, b in zip(seen, seen[1:], strict=False))
    assert len(seen) - 1 + reader.dropped - dropped_before_first == seen[-1] - seen[0]
    ring.close()


def test_foreign_segments_wrong_versions_and_misuse_are_ring_errors(name):
    foreign = SharedSegment.create(name, 4096)
    foreign.buffer[:8] = b"not ring"
    with pytest.raises(RingError, match="not a plem ring") as caught:
        SlotRing.attach(name)
    assert "b'not ring'" in caught.value.why
    foreign.close()
    SharedSegment.unlink(name)

    ring = SlotRing.create(name, 16, 4)
    patch = SharedSegment.open(name, writable=True)
    struct.pack_into("<I", patch.buffer, 8, 99)
    patch.close()
    with pytest.raises(RingError, match="not a plem ring") as caught:
        SlotRing.attach(name)
    assert "version 99" in caught.value.why

    with pytest.raises(RingError, match="record too large") as caught:
        ring.write(b"x" * 17)
    assert "16 bytes" in caught.value.what and "17 bytes" in caught.value.why
    with pytest.raises(RingError, match="cannot write values"):
        ring.write_values(np.zeros(3))
    with pytest.raises(RingError, match="no consumer"):
        ring.consumer()
    assert ring.head == 0
    ring.remove()
