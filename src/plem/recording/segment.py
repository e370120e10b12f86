"""One rosbag2 segment being written: a bag directory whose storage file reaches the disk every second.

rosbags' MCAP writer keeps messages in a pending chunk of up to 1 MiB (about 2.5 s of rt_raw), its
sqlite3 writer in one transaction, and both write the bag's metadata.yaml only when closed. The segment
closes the chunk (or commits) and flushes the file every `flush_period_s`, and once right after the
connections are added (the first chunk then carries every schema and channel), so a killed recorder
loses at most the last period; `repair` rebuilds what a killed segment lacks. The bag directory and its
files get the recorder's `FileAccess` once created and again once metadata.yaml is written.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Final

from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.storage_mcap import McapWriter
from rosbags.rosbag2.storage_sqlite3 import Sqlite3Writer
from rosbags.typesys.store import Typestore

from plem.recording.access import OWNER_ONLY, FileAccess

STORAGES = {"mcap": StoragePlugin.MCAP, "sqlite3": StoragePlugin.SQLITE3}
#: rosbag2 metadata version written (ROS 2 Jazzy writes 9).
BAG_VERSION: Final = 9


def bag_file(segment: Path) -> Path | None:
    """The segment's storage file (.mcap or .db3); None when it has none."""
    return next((path for pattern in ("*.mcap", "*.db3") for path in sorted(segment.glob(pattern))), None)


class SegmentWriter:
    """Writes serialized messages of fixed topics into one bag directory."""

    def __init__(self, directory: Path, topics: Sequence[tuple[str, str]], store: Typestore,
                 storage: str = "mcap", flush_period_s: float = 1.0, access: FileAccess = OWNER_ONLY) -> None:
        self.directory = directory
        self.access = access
        self.messages = 0
        self.start_ns: int | None = None                     # the earliest stamp written: a reader's start time
        self._writer = Writer(directory, version=BAG_VERSION, storage_plugin=STORAGES[storage])
        self._flush_period_ns = round(flush_period_s * 1e9)
        self._next_flush = 0
        self._writer.open()
        try:
            access.apply_tree(directory)
            self._connections = {topic: self._writer.add_connection(topic, msgtype, typestore=store)
                                 for topic, msgtype in topics}
            self.flush()
        except BaseException:
            self.abandon()                                   # a full disk: no file left open behind the caller
            raise

    @property
    def name(self) -> str:
        """The segment's directory name, which names it in the event log."""
        return self.directory.name

    def write(self, topic: str, timestamp_ns: int, data: bytes) -> None:
        """Append one message; flushes when the flush period has passed."""
        self._writer.write(self._connections[topic], timestamp_ns, data)
        self.messages += 1
        if self.start_ns is None or timestamp_ns < self.start_ns:
            self.start_ns = timestamp_ns
        if time.monotonic_ns() >= self._next_flush:
            self.flush()

    def flush(self) -> None:
        """Put everything written so far into the file (the page cache survives the process)."""
        storage = self._writer.storage
        if isinstance(storage, McapWriter):                  # MCAP: a pending chunk, then the file buffer
            if storage.chunk.bio.tell():
                storage.close_chunk()
            storage.bio.flush()
        elif isinstance(storage, Sqlite3Writer):             # sqlite3: one transaction per flush period
            storage.conn.commit()
        self._next_flush = time.monotonic_ns() + self._flush_period_ns

    def abandon(self) -> None:
        """Close the file unfinished after a failed write or close; it stays a killed segment for `repair`."""
        with contextlib.suppress(OSError):                   # the descriptor is closed even when the flush fails
            self._writer.abort()

    def close(self) -> None:
        """Finish the file (summary, footer) and write metadata.yaml."""
        self._writer.close()
        self.access.apply_tree(self.directory)
