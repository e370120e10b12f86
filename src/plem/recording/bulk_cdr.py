"""The recorder's 1 kHz messages in CDR, many at once: RtRaw and JointState have a fixed layout per robot.

One numpy pass over a batch of rt_raw ring records gives every RtRaw payload (the layout `raw_dtype` reads
back) and every JointState payload (names fixed at start-up), so the recorder spends no Python call per
message on serialisation. Tests check the bytes against rosbags' serialiser.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence

import numpy as np

from plem.control.state import ROWS
from plem.ipc.records import RAW_SCALARS, raw_override_column
from plem.middleware.raw_cdr import ENCAPSULATION, raw_dtype

_UINT32_MAX = 0xFFFFFFFF
_NS = 1_000_000_000


def _stamps(payloads: np.ndarray, wall_ns: np.ndarray, sec: str, nanosec: str) -> None:
    payloads[sec] = wall_ns // _NS
    payloads[nanosec] = wall_ns % _NS


def raw_payloads(records: np.ndarray, wall_ns: np.ndarray, dof: int) -> np.ndarray:
    """RtRaw CDR of rt_raw ring records (records × values), stamped `wall_ns`: one row of bytes per message."""
    out = np.zeros(len(records), raw_dtype(dof))
    _stamps(out, wall_ns, "sec", "nanosec")
    out["frame_id_length"] = 1
    scalars = records[:, :len(RAW_SCALARS)].astype(np.int64)
    for column, name in enumerate(RAW_SCALARS):
        values = scalars[:, column]
        out[name] = np.minimum(values, _UINT32_MAX) if name in ("latency_ns", "compute_ns") else values
    for index, row in enumerate(ROWS):
        start = len(RAW_SCALARS) + index * dof
        out[f"{row}_length"] = dof
        out[row] = records[:, start:start + dof]
    out["speed_override"] = records[:, raw_override_column(dof)]
    data = out.view(np.uint8).reshape(len(records), out.dtype.itemsize)
    data[:, :len(ENCAPSULATION)] = np.frombuffer(ENCAPSULATION, np.uint8)
    return data


class JointStateEncoder:
    """sensor_msgs/JointState CDR of one robot's joints (names fixed), position, velocity and effort from rt_raw."""

    def __init__(self, names: Sequence[str]) -> None:
        self.dof = len(names)
        body = bytearray(struct.pack("<iII", 0, 0, 1) + b"\0")       # stamp, frame_id ""

        def align(size: int) -> None:
            body.extend(bytes(-len(body) % size))

        align(4)
        body += struct.pack("<I", len(names))
        for name in names:
            align(4)
            text = name.encode() + b"\0"
            body += struct.pack("<I", len(text)) + text
        self._rows: list[int] = []
        for _ in range(3):                                            # position, velocity, effort
            align(4)
            body += struct.pack("<I", self.dof)
            align(8)
            self._rows.append(len(ENCAPSULATION) + len(body))
            body += bytes(8 * self.dof)
        self.template = np.frombuffer(ENCAPSULATION + bytes(body), np.uint8)
        fields = {"sec": ("<i4", 4), "nanosec": ("<u4", 8),
                  **{f"row{i}": ((np.float64, (self.dof,)), at) for i, at in enumerate(self._rows)}}
        self.dtype = np.dtype({"names": list(fields), "formats": [f for f, _ in fields.values()],
                               "offsets": [at for _, at in fields.values()], "itemsize": self.template.size})

    def payloads(self, records: np.ndarray, wall_ns: np.ndarray) -> np.ndarray:
        """JointState CDR of rt_raw ring records (records × values), stamped `wall_ns`: one row of bytes each."""
        data = np.tile(self.template, (len(records), 1))
        out = data.view(self.dtype).reshape(len(records))
        _stamps(out, wall_ns, "sec", "nanosec")
        start = len(RAW_SCALARS)
        for index in range(3):
            out[f"row{index}"] = records[:, start + index * self.dof:start + (index + 1) * self.dof]
        return data
