"""One rosbag2 segment being written: a bag directory whose storage file reaches the disk every second.

rosbags' MCAP writer keeps messages in a pending chunk, its sqlite3 writer in one transaction, and both
write the bag's metadata.yaml only when closed. The segment closes the chunk (or commits) and puts it in
the file every `flush_period_s` or every `CHUNK_BYTES`, and once right after the connections are added
(the first chunk then carries every schema and channel), so a killed recorder loses at most the last
period; `repair` rebuilds what a killed segment lacks.

A full disk loses nothing written before it: the MCAP file reaches the disk only in whole chunks (a chunk
the disk refuses is cut off again and kept in memory), and every open segment holds `RESERVE_BYTES` of
disk in a `.reserve` file. When the disk refuses a chunk, `salvage` gives the reserve back and finishes
the segment with every message written to it, summary and metadata.yaml included.

The writer holds an exclusive lock (flock) on the segment directory while it is open, so any process
tells a segment being written (`being_written`) from one left unfinished by a killed recorder. The bag
directory and its files get the recorder's `FileAccess` once created and again once metadata.yaml is
written.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import shutil
import sqlite3
import stat
import time
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any, Final, cast

import numpy as np
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2.storage_mcap import McapWriter
from rosbags.rosbag2.storage_sqlite3 import Sqlite3Writer
from rosbags.typesys.store import Typestore

from plem.core.files import file_kind
from plem.errors import ConfigError
from plem.recording.access import OWNER_ONLY, FileAccess
from plem.recording.bulk_writer import BulkWriter

STORAGES = {"mcap": StoragePlugin.MCAP, "sqlite3": StoragePlugin.SQLITE3}
#: rosbag2 metadata version written (ROS 2 Jazzy writes 9).
BAG_VERSION: Final = 9
#: A flush comes once this many payload bytes are pending, whatever the flush period.
CHUNK_BYTES: Final = 256 * 1024
#: Disk held back by an open segment: room for its last chunk, its summary and its metadata.yaml.
RESERVE_BYTES: Final = 2 * CHUNK_BYTES
RESERVE_NAME: Final = ".reserve"


def bag_file(segment: Path) -> Path | None:
    """The segment's storage file (.mcap or .db3); None when it has none."""
    return next((path for pattern in ("*.mcap", "*.db3") for path in sorted(segment.glob(pattern))), None)


def open_bag_file(path: Path) -> int:
    """A read-only descriptor of a segment's storage file; ConfigError unless it is a regular file.

    Never waits: a FIFO named like a bag file would block a plain open (and sqlite3) forever.
    """
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    except OSError as error:
        raise ConfigError(f"cannot read {path}", what="a readable bag file", why=error.strerror or str(error),
                          how="check the file's permissions") from None
    mode = os.fstat(fd).st_mode
    if not stat.S_ISREG(mode):
        os.close(fd)
        raise ConfigError(f"{path} is not a bag file", what="a regular .mcap or .db3 file",
                          why=f"it is a {file_kind(mode)}", how="remove it, or pass a segment the recorder wrote")
    return fd


def being_written(segment: Path) -> bool:
    """Whether a live process holds the segment open for writing (its writer's lock)."""
    try:
        fd = os.open(segment, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    finally:
        os.close(fd)                                         # also drops the shared lock just taken
    return False


@contextlib.contextmanager
def _storage_errors() -> Iterator[None]:
    """sqlite3's errors as the OSError they stand for (a full disk is SQLITE_FULL), as the MCAP writer raises them."""
    try:
        yield
    except sqlite3.Error as error:
        full = getattr(error, "sqlite_errorcode", None) == sqlite3.SQLITE_FULL
        raise OSError(errno.ENOSPC if full else errno.EIO, str(error)) from error


class StagedFile:
    """The MCAP file as rosbags writes it, put on disk only by `flush`: the file always ends after a whole record.

    A flush the disk refuses cuts the file back to its previous end and keeps the bytes, so a later flush
    writes them again and the writer's own bookkeeping (chunk index, counts) stays true.
    """

    def __init__(self, path: Path) -> None:
        self._fd = os.open(path, os.O_WRONLY | os.O_CLOEXEC)
        self.committed = os.fstat(self._fd).st_size
        self._pending = bytearray()

    def write(self, data: bytes | bytearray | memoryview) -> int:
        """Append to what the next flush writes."""
        self._pending += data
        return len(data)

    def tell(self) -> int:
        """The file's size once flushed, where rosbags places its next record."""
        return self.committed + len(self._pending)

    def flush(self) -> None:
        """Write what is pending; on failure the file is cut back to its last whole record and the bytes kept."""
        done = 0
        with memoryview(self._pending) as view:
            try:
                while done < len(view):
                    done += os.pwrite(self._fd, view[done:], self.committed + done)
            except OSError:
                with contextlib.suppress(OSError):
                    os.ftruncate(self._fd, self.committed)
                raise
        self.committed += done
        self._pending.clear()

    def discard(self) -> None:
        """Forget what is pending (the segment is given up)."""
        self._pending.clear()

    def close(self) -> None:
        """Flush and close the file; the descriptor is closed even when the flush fails."""
        if self._fd < 0:
            return
        try:
            self.flush()
        finally:
            os.close(self._fd)
            self._fd = -1


class SegmentWriter:
    """Writes serialized messages of fixed topics into one bag directory; `custom_data` goes into its metadata.yaml."""

    def __init__(self, directory: Path, topics: Sequence[tuple[str, str]], store: Typestore,
                 storage: str = "mcap", flush_period_s: float = 1.0, access: FileAccess = OWNER_ONLY,
                 custom_data: Mapping[str, str] | None = None) -> None:
        self.directory = directory
        self.access = access
        self.messages = 0
        self.start_ns: int | None = None                     # the earliest stamp written: a reader's start time
        self._writer = BulkWriter(directory, version=BAG_VERSION, storage_plugin=STORAGES[storage])
        for key, value in (custom_data or {}).items():
            self._writer.set_custom_data(key, value)
        self._flush_period_ns = round(flush_period_s * 1e9)
        self._next_flush = 0
        self._file: StagedFile | None = None
        self._lock = -1
        self._done = False                                   # closed or abandoned
        self._uncommitted = 0                                # messages appended since the last flush
        self._uncommitted_bytes = 0
        self.lost = 0                                        # messages appended that a failed write took along
        self._reserve = directory / RESERVE_NAME
        self._writer.open()
        try:
            self._lock = os.open(directory, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
            fcntl.flock(self._lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
            mcap = self._writer.storage
            if isinstance(mcap, McapWriter):
                mcap.bio.close()                             # its magic and header reach the file
                self._file = StagedFile(mcap.path)
                mcap.bio = cast(Any, self._file)             # rosbags only calls write, tell and close
            self._hold_reserve()
            access.apply_tree(directory)
            with _storage_errors():
                self._connections = {topic: self._writer.add_connection(topic, msgtype, typestore=store)
                                     for topic, msgtype in topics}
            self.flush()
        except BaseException:
            self.abandon()                                   # a full disk: no file left open behind the caller,
            shutil.rmtree(directory, ignore_errors=True)     # nor a segment that never held a message
            raise

    @property
    def name(self) -> str:
        """The segment's directory name, which names it in the event log."""
        return self.directory.name

    def _hold_reserve(self) -> None:
        fd = os.open(self._reserve, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o600)
        try:
            os.posix_fallocate(fd, 0, RESERVE_BYTES)
        finally:
            os.close(fd)

    def _release_reserve(self) -> None:
        with contextlib.suppress(OSError):                   # gone already, or the directory is no longer ours
            self._reserve.unlink()

    def append(self, topic: str, timestamp_ns: int, data: bytes) -> None:
        """Add one message to the segment, as `append_groups` adds many."""
        self.append_groups([(topic, np.array([timestamp_ns], np.int64), np.frombuffer(data, np.uint8)[None, :])])

    def append_groups(self, groups: Sequence[tuple[str, np.ndarray, np.ndarray]]) -> None:
        """Add messages to the segment (MCAP: to its pending chunk, in memory) in stamp order; `flush_due` puts them
        on disk. Each group: a topic, stamps (ns, ascending) and equal-size payloads (messages × bytes)."""
        with _storage_errors():
            self._writer.write_groups([(self._connections[topic], stamps, payloads)
                                       for topic, stamps, payloads in groups])
        for _, stamps, payloads in groups:
            self.messages += len(stamps)
            self._uncommitted += len(stamps)
            self._uncommitted_bytes += payloads.size
            if len(stamps) and (self.start_ns is None or int(stamps.min()) < self.start_ns):
                self.start_ns = int(stamps.min())

    def flush_due(self) -> None:
        """Flush when the flush period has passed or `CHUNK_BYTES` are pending."""
        if time.monotonic_ns() >= self._next_flush or self._uncommitted_bytes >= CHUNK_BYTES:
            self.flush()

    def flush(self) -> None:
        """Put everything written so far into the file (the page cache survives the process)."""
        storage = self._writer.storage
        if isinstance(storage, McapWriter) and self._file is not None:   # MCAP: the pending chunk, then the file
            if storage.chunk.bio.tell():
                storage.close_chunk()
            self._file.flush()
        elif isinstance(storage, Sqlite3Writer):             # sqlite3: one transaction per flush period
            with _storage_errors():
                storage.conn.commit()
        self._uncommitted = self._uncommitted_bytes = 0
        self._next_flush = time.monotonic_ns() + self._flush_period_ns

    def close(self) -> None:
        """Finish the file (summary, footer) and write metadata.yaml; a failure leaves it for `repair`."""
        self._release_reserve()
        try:
            with _storage_errors():
                self._writer.close()
        except BaseException:
            self.abandon()
            raise
        self._done = True
        self._unlock()
        self.access.apply_tree(self.directory)

    def salvage(self) -> bool:
        """After the disk refused a write: finish the segment with everything written to it, in the reserve's room.

        MCAP keeps every message (the refused chunk is written again); sqlite3 keeps them when the failed
        write left its transaction open, else the segment is left for `repair`, which keeps its committed
        transactions. False when the segment is left unfinished.
        """
        if self._done:
            return False                                     # a close that failed gave it up already
        storage = self._writer.storage
        if isinstance(storage, Sqlite3Writer) and self._uncommitted and not storage.conn.in_transaction:
            self.lost, self.messages = self._uncommitted, self.messages - self._uncommitted
            self.abandon()                                   # sqlite3 rolled the transaction back
            return False
        try:
            self.close()
        except OSError:
            return False
        return True

    def abandon(self) -> None:
        """Close the file unfinished after a failed write or close; it stays a killed segment for `repair`."""
        if self._file is not None:
            self._file.discard()                             # a torn chunk never reaches the file
        with contextlib.suppress(OSError, sqlite3.Error):    # the descriptor is closed even when the flush fails
            self._writer.abort()
        self._release_reserve()
        self._done = True
        self._unlock()

    def _unlock(self) -> None:
        if self._lock >= 0:
            os.close(self._lock)
            self._lock = -1
