"""rosbags' rosbag2 writer taking a whole batch of messages of several topics in one call.

rosbags writes an MCAP message record, and later its index entry, with several Python calls per message.
`BulkWriter.write_groups` takes groups of messages (one topic, equal-size payloads each), places every
message record of the batch in stamp order with numpy, and keeps the chunk's message index as arrays, so a
batch costs a few numpy calls whatever its length. The file is the one rosbags writes (same records, chunks,
indexes and summary; messages in stamp order, as rosbags' reader needs for a file without its summary);
sqlite3 bags insert a batch with one `executemany`.
"""

from __future__ import annotations

import struct
from collections import defaultdict
from collections.abc import Sequence
from io import BytesIO
from typing import Any, cast

import numpy as np
from rosbags.interfaces import Connection
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.storage_mcap import McapWriter, PendingChunk, write_record, write_string
from rosbags.rosbag2.storage_sqlite3 import Sqlite3Writer

from plem.recording.mcap_records import CHUNK, MESSAGE, MESSAGE_FIELDS, MESSAGE_INDEX

#: rosbags closes a chunk once it holds this many bytes (a segment flushes much sooner).
MAX_CHUNK_BYTES = 2**20
_INDEX_ENTRY = np.dtype([("time", "<u8"), ("offset", "<u8")])
#: Messages of one connection: stamps (ns, ascending) and payloads (messages × bytes).
Group = tuple[Connection, np.ndarray, np.ndarray]


def message_records(channel: int, stamps: np.ndarray, payloads: np.ndarray) -> np.ndarray:
    """MCAP message records (opcode, length, channel, sequence 0, log and publish time, payload) of equal-size
    payloads (messages × bytes), as one row of bytes each."""
    count, size = payloads.shape
    records = np.zeros(count, np.dtype([("opcode", "u1"), ("length", "<u8"), ("channel", "<u2"),
                                        ("sequence", "<u4"), ("log_time", "<u8"), ("publish_time", "<u8"),
                                        ("data", "u1", (size,))]))
    records["opcode"] = MESSAGE
    records["length"] = MESSAGE_FIELDS + size
    records["channel"] = channel
    records["log_time"] = records["publish_time"] = stamps
    records["data"] = payloads
    return records.view(np.uint8).reshape(count, records.dtype.itemsize)


class BulkMcapWriter(McapWriter):
    """rosbags' MCAP storage whose pending chunk takes whole batches; single messages take the same path."""

    def __init__(self, *arguments: Any) -> None:
        super().__init__(*arguments)
        self._index: defaultdict[int, list[np.ndarray]] = defaultdict(list)

    def write(self, connection: Connection, timestamp: int, data: bytes | memoryview) -> None:
        """One message (rosbags' own entry point)."""
        self.write_groups([(connection, np.array([timestamp], np.int64), np.frombuffer(data, np.uint8)[None, :])])

    def write_groups(self, groups: Sequence[Group]) -> None:
        """Every message of `groups` into the pending chunk, in stamp order."""
        records = [message_records(connection.id, stamps, payloads) for connection, stamps, payloads in groups]
        sizes = np.concatenate([np.full(len(rows), rows.shape[1]) for rows in records])
        by_stamp = np.argsort(np.concatenate([group[1] for group in groups]), kind="stable")
        starts = np.empty_like(sizes)                                  # each message's place in the batch
        starts[by_stamp] = np.cumsum(sizes[by_stamp]) - sizes[by_stamp]
        batch = np.empty(int(sizes.sum()), np.uint8)
        chunk = self.chunk
        base, first = chunk.bio.tell(), 0
        for (connection, stamps, _), rows in zip(groups, records, strict=True):
            places = starts[first:first + len(rows)]
            first += len(rows)
            batch[places[:, None] + np.arange(rows.shape[1])] = rows
            entries = np.empty(len(rows), _INDEX_ENTRY)
            entries["time"], entries["offset"] = stamps, base + places
            self._index[connection.id].append(entries)
            self.channel_stats[connection.id] += len(rows)
            if len(rows):
                low, high = int(stamps.min()), int(stamps.max())
                chunk.message_start_time = min(low, chunk.message_start_time)
                chunk.message_end_time = max(high, chunk.message_end_time)
                self.message_start_time = min(low, self.message_start_time)
                self.message_end_time = max(high, self.message_end_time)
        chunk.bio.write(batch.data)
        if chunk.bio.tell() > MAX_CHUNK_BYTES:
            self.close_chunk()

    def close_chunk(self) -> None:
        """Write the pending chunk, its message indexes and keep its chunk index for the summary (as rosbags)."""
        chunk = self.chunk
        body = chunk.bio.getvalue()
        record = BytesIO()
        record.write(struct.pack("<QQQI", chunk.message_start_time, chunk.message_end_time, len(body), 0))
        compressed = self.compressor(body)
        write_string(record, self.compression)
        record.write(struct.pack("<Q", len(compressed)))
        record.write(compressed)
        chunk_start = self.bio.tell()
        write_record(self.bio, CHUNK, record)
        chunk_end = self.bio.tell()
        offsets = BytesIO()
        for channel, parts in self._index.items():
            entries = np.concatenate(parts)
            entries = entries[np.argsort(entries["time"], kind="stable")]
            offsets.write(struct.pack("<HQ", channel, self.bio.tell()))
            record = BytesIO()
            record.write(struct.pack("<HI", channel, entries.nbytes))
            record.write(entries.data)
            write_record(self.bio, MESSAGE_INDEX, record)
        index = BytesIO()
        index.write(struct.pack("<QQQQI", chunk.message_start_time, chunk.message_end_time, chunk_start,
                                chunk_end - chunk_start, len(offsets.getbuffer())))
        index.write(offsets.getbuffer())
        index.write(struct.pack("<Q", self.bio.tell() - chunk_end))
        write_string(index, self.compression)
        index.write(struct.pack("<QQ", len(compressed), len(body)))
        self.chunks.append(index)
        self.chunk = PendingChunk(2**63 - 1, 0, BytesIO(), defaultdict(list))
        self._index = defaultdict(list)


class BulkWriter(Writer):
    """rosbags' rosbag2 writer with `write_groups`; its MCAP storage is `BulkMcapWriter`."""

    STORAGE_PLUGINS = {**Writer.STORAGE_PLUGINS, StoragePlugin.MCAP: BulkMcapWriter}

    def write_groups(self, groups: Sequence[Group]) -> None:
        """Messages of several connections (each group: stamps ascending, equal-size payloads), in stamp order."""
        groups = [group for group in groups if len(group[1])]
        if not groups:
            return
        storage = self.storage
        if isinstance(storage, BulkMcapWriter):
            storage.write_groups(groups)
        else:
            rows: list[tuple[int, int, bytes]] = [
                (connection.id, stamp, payload.tobytes()) for connection, stamps, payloads in groups
                for stamp, payload in zip(stamps.tolist(), payloads, strict=True)]
            rows.sort(key=lambda row: row[1])
            cast(Sqlite3Writer, storage).cursor.executemany(
                "INSERT INTO messages (topic_id, timestamp, data) VALUES(?, ?, ?)", rows)
        for connection, stamps, _ in groups:
            self.counts[connection.id] += len(stamps)
            self.min_timestamp = min(int(stamps.min()), self.min_timestamp)
            self.max_timestamp = max(int(stamps.max()), self.max_timestamp)
