"""Plain values for any ROS type, turned into plem's DDS structs and into rosbags' reference messages and bytes.

Wire tests fill a type with deterministic values, serialise them both ways and compare the CDR bytes.
"""

from __future__ import annotations

import math
import random
from typing import Any

import numpy as np
from rosbags.interfaces import Nodetype

from plem.middleware.types import library

LIB = library()
STORE = LIB.store
#: The parts of every action type: its goal, result and feedback, and the messages rosidl wraps them in.
ACTION_PARTS = ("Goal", "Result", "Feedback", "SendGoal_Request", "SendGoal_Response", "GetResult_Request",
                "GetResult_Response", "FeedbackMessage")

_INTS = {"int8": 8, "int16": 16, "int32": 32, "int64": 64}
_UINTS = {"uint8": 8, "byte": 8, "char": 8, "uint16": 16, "uint32": 32, "uint64": 64}
_DTYPES = {"bool": np.bool_, "byte": np.uint8, "char": np.uint8, "int8": np.int8, "uint8": np.uint8,
           "int16": np.int16, "uint16": np.uint16, "int32": np.int32, "uint32": np.uint32, "int64": np.int64,
           "uint64": np.uint64, "float32": np.float32, "float64": np.float64}
_STRINGS = ("", "joint_1", "ünïcødé ☃ 日本語 😀", "tab\tand\nnewline", "x" * 37)
_ALPHABET = "abcXYZ019_/ -äöüßéçñ€☃日本語中文Ωπ😀🤖"


def fields(ros_type: str) -> list[tuple[str, tuple[Any, Any]]]:
    """A type's (name, spec) fields; asking the library first parses a package it loads on demand."""
    assert LIB.known(ros_type), f"{ros_type} is not in plem's interface library"
    return list(STORE.fielddefs[ros_type][1])


# -- a deterministic filler: ROS type -> nested plain values (dicts, lists, Python scalars) ----------------
class Filler:
    """Pseudo-random field values by ROS base type, with extremes, negatives and non-ASCII strings."""

    def __init__(self, seed: int, zero: bool = False) -> None:
        self.rng = random.Random(seed)
        self.empty = zero or seed % 3 == 0
        self.zero = zero

    def message(self, ros_type: str, depth: int = 0) -> dict[str, Any]:
        return {name: self.value(spec, depth) for name, spec in fields(ros_type)}

    def value(self, spec: tuple[Any, Any], depth: int) -> Any:
        node, detail = spec
        if node == Nodetype.BASE:
            return self.base(*detail)
        if node == Nodetype.NAME:
            return self.message(detail, depth + 1)
        element, size = detail
        if node == Nodetype.ARRAY:
            count = size
        else:
            count = 0 if self.empty else self.rng.randint(0, 3 if depth < 4 else 1)
            count = min(count, size) if size else count
        return [self.value(element, depth + 1) for _ in range(count)]

    def base(self, base: str, bound: int) -> Any:
        rng = self.rng
        if self.zero:
            return {"bool": False, "string": "", "float32": 0.0, "float64": 0.0}.get(base, 0)
        if base == "bool":
            return rng.random() < 0.5
        if base in _INTS or base in _UINTS:
            low, high = (-(1 << (_INTS[base] - 1)), (1 << (_INTS[base] - 1)) - 1) if base in _INTS \
                else (0, (1 << _UINTS[base]) - 1)
            return rng.choice((low, high, 0, max(low, -1), 1, rng.randint(low, high), rng.randint(low, high)))
        if base == "float32":   # values float32 holds exactly
            return rng.choice((0.0, -0.0, math.inf, -math.inf, 3.4028234663852886e38, -1.5,
                               rng.randint(-(1 << 20), 1 << 20) / 64))
        if base == "float64":
            return rng.choice((0.0, -0.0, math.inf, -math.inf, 5e-324, -1.7976931348623157e308,
                               rng.uniform(-1e6, 1e6), rng.uniform(-1e-6, 1e-6)))
        if base == "string":
            text = rng.choice(_STRINGS) if rng.random() < 0.5 else \
                "".join(rng.choice(_ALPHABET) for _ in range(rng.randint(1, 12)))
            return text[:bound] if bound else text
        raise AssertionError(f"no values for base type {base}")


# -- plain values -> plem struct / rosbags message, and back ----------------------------------------------
def to_plem(ros_type: str, plain: dict[str, Any], with_header: bool = False, **header: int) -> Any:
    """plem's struct of `plain`: a message, or with rmw's request header in front when `with_header`."""
    struct_ = LIB.service_part(ros_type) if with_header else LIB.message(ros_type)
    values = {name: _plem_value(spec, plain[name]) for name, spec in fields(ros_type)}
    return struct_(**header, **values)


def _plem_value(spec: tuple[Any, Any], value: Any) -> Any:
    node, detail = spec
    if node == Nodetype.BASE:
        return value
    if node == Nodetype.NAME:
        return to_plem(detail, value)
    return [_plem_value(detail[0], item) for item in value]


def to_rosbags(ros_type: str, plain: dict[str, Any]) -> Any:
    """rosbags' message of `plain`, numeric arrays as numpy arrays."""
    values = {name: _rosbags_value(spec, plain[name]) for name, spec in fields(ros_type)}
    return STORE.types[ros_type](**values)


def _rosbags_value(spec: tuple[Any, Any], value: Any) -> Any:
    node, detail = spec
    if node == Nodetype.BASE:   # rosbags packs a byte as int8: the same octet on the wire, read as signed
        return value - 256 if detail[0] == "byte" and value > 127 else value
    if node == Nodetype.NAME:
        return to_rosbags(detail, value)
    (element_node, element), _ = detail
    if element_node == Nodetype.BASE and element[0] != "string":   # rosbags wants numpy arrays of numbers
        return np.array(value, dtype=_DTYPES[element[0]])
    return [_rosbags_value(detail[0], item) for item in value]


def plain_of(ros_type: str, message: Any) -> dict[str, Any]:
    """A plem struct's content as plain values (bytes of uint8 arrays as lists of ints)."""
    return {name: _plain(spec, getattr(message, name)) for name, spec in fields(ros_type)}


def _plain(spec: tuple[Any, Any], value: Any) -> Any:
    node, detail = spec
    if node == Nodetype.BASE:
        return value
    if node == Nodetype.NAME:
        return plain_of(detail, value)
    if isinstance(value, (bytes, bytearray)):
        return list(value)
    return [_plain(detail[0], item) for item in value]


def reference_bytes(ros_type: str, plain: dict[str, Any]) -> bytes:
    """rosbags' CDR serialisation of `plain`: what a ROS 2 node puts on the wire."""
    return bytes(STORE.serialize_cdr(to_rosbags(ros_type, plain), ros_type))


# -- definitions as text, to compare with upstream's ---------------------------------------------------------
def _type_text(spec: tuple[Any, Any]) -> str:
    node, detail = spec
    if node == Nodetype.BASE:
        return detail[0] + (f"<={detail[1]}" if detail[1] else "")
    if node == Nodetype.NAME:
        return detail
    element, size = detail
    return f"{_type_text(element)}[{size if node == Nodetype.ARRAY else ''}]"


def fields_of(ros_type: str) -> list[tuple[str, str]]:
    """A type's fields as (name, type as written in a .msg with full names)."""
    return [(name, _type_text(spec)) for name, spec in fields(ros_type)]


def constants_of(ros_type: str) -> list[tuple[str, str, Any]]:
    """A type's constants as (name, type, value)."""
    fields(ros_type)
    return list(STORE.fielddefs[ros_type][0])
