"""The few MCAP records plem reads itself: a killed segment has no summary for an MCAP library to start from,
and `plem bag` reads payloads straight from the chunks. Layouts follow the MCAP specification.
"""

from __future__ import annotations

import struct
from collections.abc import Iterator
from mmap import mmap

from plem.errors import PlemError

MAGIC = b"\x89MCAP0\r\n"
SCHEMA, CHANNEL, MESSAGE, CHUNK, MESSAGE_INDEX = 0x03, 0x04, 0x05, 0x06, 0x07
#: Bytes of a record before its content (opcode, length), and of a message record before its payload
#: (channel, sequence, log time, publish time).
RECORD_HEADER, MESSAGE_FIELDS = 1 + 8, 2 + 4 + 8 + 8


class McapError(PlemError):
    """An MCAP file plem cannot read."""


def records(data: bytes | mmap, start: int = 0) -> Iterator[tuple[int, memoryview]]:
    """(opcode, content) of every complete record from `start`; stops at the first truncated one."""
    view, position = memoryview(data), start
    while position + 9 <= len(data):
        opcode, length = struct.unpack_from("<BQ", data, position)
        end = position + 9 + length
        if end > len(data):
            return
        yield opcode, view[position + 9:end]
        position = end


def string(content: memoryview, offset: int) -> tuple[str, int]:
    """A length-prefixed string at `offset`, and the offset after it."""
    (length,) = struct.unpack_from("<I", content, offset)
    return bytes(content[offset + 4:offset + 4 + length]).decode(), offset + 4 + length


def define(opcode: int, content: memoryview, schemas: dict[int, str], channels: dict[int, tuple[str, str]]) -> None:
    """Note what a SCHEMA (id → type) or CHANNEL (id → topic, type) record defines; other records are ignored."""
    if opcode == SCHEMA:
        (schema_id,) = struct.unpack_from("<H", content, 0)
        schemas[schema_id], _ = string(content, 2)          # the type; its embedded definition is not needed
    elif opcode == CHANNEL:
        channel_id, schema_id = struct.unpack_from("<HH", content, 0)
        topic, _ = string(content, 4)
        channels[channel_id] = (topic, schemas.get(schema_id, ""))


def chunk_records(content: memoryview) -> bytes:
    """The records inside a chunk (plem writes them uncompressed)."""
    offset = 8 + 8 + 8 + 4                               # start time, end time, uncompressed size, crc
    compression, offset = string(content, offset)
    if compression:
        raise McapError("a chunk is compressed", what="uncompressed chunks, as plem's recorder writes them",
                        why=f"compression {compression!r}", how="decompress it with an MCAP tool first")
    (size,) = struct.unpack_from("<Q", content, offset)
    return bytes(content[offset + 8:offset + 8 + size])
