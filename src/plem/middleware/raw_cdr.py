"""plem_msgs/RtRaw in CDR by its fixed layout: encoded straight from an rt_raw ring record for the 1 kHz
publisher and recorder, and read back field by field from many recorded payloads at once for `plem bag`.

The generic struct serializer walks the message field by field in Python (~28 µs); RtRaw's layout is
fixed once the DOF is known, so one `struct.pack` over the record does the same (~2 µs). Tests check
that both give identical bytes.
"""

from __future__ import annotations

import re
import struct
from collections.abc import Mapping
from functools import cache
from types import MappingProxyType

import numpy as np

from plem.control.state import ROWS
from plem.ipc.records import RAW_SCALARS, raw_override_column, raw_scalars

#: CDR little-endian encapsulation (XCDR1), the 4 bytes in front of every ROS 2 payload.
ENCAPSULATION = b"\x00\x01\x00\x00"
_UINT32_MAX = 0xFFFFFFFF


def _layout(dof: int, override: bool = True) -> str:
    """struct format of RtRaw's body, alignment counted from after the encapsulation as CDR does (without the
    trailing speed_override for RtRaw as plem recorded it before it had one)."""
    # header.stamp (int32 sec, uint32 nanosec), header.frame_id "" (length 1, NUL, 3 padding bytes),
    # cycle, monotonic_ns, mode, faulted, drives_enabled, 1 padding byte, latency_ns, compute_ns.
    layout = "<iII1s3xQqBBBxII"
    offset = struct.calcsize(layout)
    for _ in ROWS:                                   # each float64[]: uint32 length, padding to 8, values
        padding = (8 - (offset + 4) % 8) % 8
        layout += f"I{padding}x{dof}d"
        offset += 4 + padding + 8 * dof
    if override:
        layout += f"{(8 - offset % 8) % 8}xd"
    return layout


def raw_sizes(dof: int) -> tuple[int, int]:
    """The payload size of an RtRaw of `dof` joints (encapsulation included), and its size in bags recorded before
    RtRaw had a speed_override; readers take both."""
    return (len(ENCAPSULATION) + struct.calcsize(_layout(dof)),
            len(ENCAPSULATION) + struct.calcsize(_layout(dof, override=False)))


class RawEncoder:
    """Encodes rt_raw records of one robot (its DOF) as RtRaw CDR payloads."""

    def __init__(self, dof: int) -> None:
        self.dof = dof
        self._struct = struct.Struct(_layout(dof))

    def encode(self, record: np.ndarray, wall_ns: int) -> bytes:
        """RtRaw of one ring record, stamped `wall_ns` (ns since the epoch)."""
        cycle, monotonic_ns, mode, faulted, enabled, latency, compute = raw_scalars(record)
        rows = record[len(RAW_SCALARS):len(RAW_SCALARS) + len(ROWS) * self.dof].tolist()
        values: list[float | int] = []
        for index in range(len(ROWS)):
            values.append(self.dof)
            values.extend(rows[index * self.dof:(index + 1) * self.dof])
        return ENCAPSULATION + self._struct.pack(
            wall_ns // 1_000_000_000, wall_ns % 1_000_000_000, 1, b"\0", cycle, monotonic_ns, mode, bool(faulted),
            bool(enabled), min(latency, _UINT32_MAX), min(compute, _UINT32_MAX), *values,
            float(record[raw_override_column(self.dof)]))


_NUMPY_CODES = {"i": "<i4", "I": "<u4", "Q": "<u8", "q": "<i8", "B": "u1", "d": "<f8"}
_RAW_FIELDS = ("sec", "nanosec", "frame_id_length", "frame_id", "cycle", "monotonic_ns", "mode", "faulted",
               "drives_enabled", "latency_ns", "compute_ns", *(name for row in ROWS for name in (f"{row}_length", row)),
               "speed_override")


@cache
def _raw_layout(dof: int) -> tuple[Mapping[str, tuple[np.dtype, int]], int]:
    """Numpy type and byte offset of each RtRaw field, and the payload's size, read off `_layout` so both agree."""
    names = iter(_RAW_FIELDS)
    fields: dict[str, tuple[np.dtype, int]] = {}
    offset = len(ENCAPSULATION)
    for count_text, code in re.findall(r"(\d*)([a-zA-Z])", _layout(dof)):
        count = int(count_text or 1)
        if code == "x":
            offset += count
            continue
        if code == "s":
            field = np.dtype(f"S{count}")
        else:
            field = np.dtype((_NUMPY_CODES[code], (count,))) if count_text else np.dtype(_NUMPY_CODES[code])
        fields[next(names)] = (field, offset)
        offset += field.itemsize
    return MappingProxyType(fields), offset


def raw_fields(dof: int) -> Mapping[str, tuple[np.dtype, int]]:
    """Numpy type and byte offset of each field of a whole RtRaw CDR payload (encapsulation included)."""
    return _raw_layout(dof)[0]


@cache
def raw_dtype(dof: int) -> np.dtype:
    """A whole RtRaw CDR payload (encapsulation included) as a numpy record, read off `_layout` so both agree."""
    fields, itemsize = _raw_layout(dof)
    return np.dtype({"names": list(fields), "formats": [field for field, _ in fields.values()],
                     "offsets": [at for _, at in fields.values()], "itemsize": itemsize})


def raw_dof(payload: bytes) -> int:
    """The DOF of one RtRaw CDR payload: the length of its position sequence."""
    _, offset = raw_fields(0)["position_length"]
    (dof,) = struct.unpack_from("<I", payload, offset)
    return int(dof)


def raw_field(buffer: np.ndarray, starts: np.ndarray, name: str, dof: int = 0) -> np.ndarray:
    """One field of many RtRaw payloads at once: `buffer` (uint8) holds a payload at each of `starts`.

    Only the field's bytes are gathered, so the cycles of a million messages take milliseconds. `dof`
    matters for the joint rows only: the fields before them sit at the same offsets whatever the DOF.
    """
    field, offset = raw_fields(dof)[name]
    index = np.asarray(starts, dtype=np.int64)[:, None] + (offset + np.arange(field.itemsize))
    gathered: np.ndarray = buffer[index]
    return gathered.view(field.base).reshape(len(index), *field.shape)
