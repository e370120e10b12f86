"""Rebuild a bag segment whose writer was killed: read what reached the file, write a proper bag.

A killed MCAP segment has its chunks but no summary, footer or metadata.yaml, and readers refuse it.
Every complete chunk is read (schemas and channels travel in the first one); the first incomplete record
ends the scan. A killed sqlite3 segment has its committed transactions and no metadata.yaml. A segment
whose metadata.yaml is there but whose file no longer reads (truncated, damaged) is rebuilt the same way
from what can be read. The rebuilt bag replaces the directory only after it reads back with every
recovered message; the original file is then removed. The rebuilt bag is built in an owner-only
workspace and given the original's access. Every failure is a RepairError (WHAT/WHY/HOW).
"""

from __future__ import annotations

import os
import shutil
import sqlite3
import struct
from dataclasses import dataclass
from pathlib import Path

from rosbags.rosbag2 import Reader, Writer
from rosbags.rosbag2.errors import ReaderError, WriterError

from plem.core.files import read_regular
from plem.errors import PlemError
from plem.middleware.types import library
from plem.recording.access import FileAccess
from plem.recording.mcap_records import CHUNK, MAGIC, MESSAGE, chunk_records, define, records
from plem.recording.segment import BAG_VERSION, STORAGES, bag_file, open_bag_file


class RepairError(PlemError):
    """A segment cannot be rebuilt."""


@dataclass(frozen=True)
class RepairReport:
    """The outcome of `repair`: the segment, the messages it holds, and whether it had to be rebuilt."""

    directory: Path
    messages: int
    repaired: bool


#: The largest storage file read into memory for a rebuild.
MAX_BAG_FILE_BYTES = 8 * 1024**3
#: What reading a damaged bag file may raise, besides a PlemError.
DAMAGED = (OSError, ReaderError, WriterError, sqlite3.Error, struct.error, KeyError, IndexError, TypeError, ValueError)
Channels = dict[int, tuple[str, str]]
Messages = list[tuple[int, int, bytes]]


def recover_sqlite3(db3: Path) -> tuple[Channels, Messages]:
    """Topics (id → topic, type) and committed messages (topic id, time, data) of a killed sqlite3 file."""
    os.close(open_bag_file(db3))                         # a regular file: sqlite3 would block on a FIFO
    connection = sqlite3.connect(f"file:{db3}?mode=rw", uri=True)   # rolls back an interrupted transaction
    try:
        channels = {row[0]: (row[1], row[2]) for row in connection.execute("SELECT id, name, type FROM topics")}
        messages = list(connection.execute("SELECT topic_id, timestamp, data FROM messages ORDER BY id"))
    except sqlite3.DatabaseError as error:
        raise RepairError(f"{db3} cannot be read", what="a rosbag2 sqlite3 database", why=str(error),
                          how="pass the directory of a plem bag segment") from error
    finally:
        connection.close()
    return channels, messages


def recover_mcap(mcap: Path) -> tuple[Channels, Messages]:
    """Channels (id → topic, type) and messages (channel id, time, data) of a killed MCAP file."""
    data = read_regular(mcap, MAX_BAG_FILE_BYTES, "bag file")
    if not data.startswith(MAGIC):
        raise RepairError(f"{mcap} is not an MCAP file", what="a file starting with the MCAP magic",
                          why="its first bytes differ", how="pass the directory of a plem bag segment")
    schemas: dict[int, str] = {}
    channels: Channels = {}
    messages: list[tuple[int, int, bytes]] = []
    for opcode, content in records(data, len(MAGIC)):
        if opcode != CHUNK:
            continue
        for inner, record in records(chunk_records(content)):
            if inner == MESSAGE:
                channel_id, _, log_time = struct.unpack_from("<HIQ", record, 0)
                messages.append((channel_id, log_time, bytes(record[22:])))
            else:
                define(inner, record, schemas, channels)     # types only: the definitions are rebuilt
    return channels, messages


def intact(directory: Path) -> int | None:
    """The message count of a segment that has its metadata.yaml and reads back whole; None otherwise."""
    if not (directory / "metadata.yaml").exists():
        return None
    try:
        with Reader(directory) as reader:
            count = sum(1 for _ in reader.messages())
    except DAMAGED:
        return None
    return count


def repair(directory: Path) -> RepairReport:
    """Make an unfinished or damaged segment readable again; one that reads back whole is left as it is."""
    count = intact(directory)
    if count is not None:
        return RepairReport(directory, count, repaired=False)
    file = bag_file(directory)
    if file is None:
        raise RepairError(f"{directory} is not a killed segment", what="a .mcap or .db3 file and no metadata.yaml",
                          why="it has no bag file", how="pass one segment directory of the bag")
    workspace = directory.with_name(f".{directory.name}.repairing")
    try:
        return _rebuild(directory, file, workspace)
    except DAMAGED as error:
        shutil.rmtree(workspace, ignore_errors=True)
        raise RepairError(f"{directory.name} could not be rebuilt", what="a readable bag rebuilt from the segment",
                          why=f"{type(error).__name__}: {error}", how="check the disk and the segment's files") \
            from None


def _rebuild(directory: Path, file: Path, workspace: Path) -> RepairReport:
    """Write what `file` holds into a new bag, built in `workspace`, that replaces `directory` once it reads back."""
    storage = "mcap" if file.suffix == ".mcap" else "sqlite3"
    channels, messages = (recover_mcap if storage == "mcap" else recover_sqlite3)(file)
    interfaces = library()
    unknown = sorted({msgtype for _, msgtype in channels.values() if not interfaces.known(msgtype)})
    store = interfaces.store
    if unknown:
        raise RepairError(f"{directory} holds types plem does not know", what="plem's recorded types",
                          why=f"unknown: {', '.join(unknown)}", how="repair it with the tool that wrote it")
    shutil.rmtree(workspace, ignore_errors=True)
    workspace.mkdir(mode=0o700)                          # nobody else sees the bag while it is built
    rebuilt = workspace / directory.name                 # same name: the files inside are named after it
    writer = Writer(rebuilt, version=BAG_VERSION, storage_plugin=STORAGES[storage])
    writer.open()
    connections = {channel_id: writer.add_connection(topic, msgtype, typestore=store)
                   for channel_id, (topic, msgtype) in channels.items()}
    for channel_id, timestamp, data in messages:
        writer.write(connections[channel_id], timestamp, data)
    writer.close()
    with Reader(rebuilt) as reader:
        if reader.message_count != len(messages):
            raise RepairError(f"the rebuilt {directory.name} lost messages", what="every recovered message",
                              why=f"{reader.message_count} of {len(messages)} read back", how="keep the original")
    FileAccess.like(directory).apply_tree(rebuilt)
    killed = workspace / f"{directory.name}.killed"
    directory.rename(killed)                             # the original stays whole until the new one is in place
    rebuilt.rename(directory)
    shutil.rmtree(workspace)
    return RepairReport(directory, len(messages), repaired=True)
