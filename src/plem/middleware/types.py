"""ROS 2 interface types as Cyclone DDS structs, built at run time from their .msg/.srv/.action definitions.

Standard definitions come from the `rosbags` type store (ROS 2 Jazzy); the few it lacks and plem's own
`plem_msgs` ship as definition files in `interfaces/`. MoveIt's packages there are parsed only when one of
their types is first asked for, so processes that never serve MoveIt do not pay for them. Each ROS type
becomes a Cyclone DDS struct whose DDS type name follows the ROS 2 rule (`pkg::msg::dds_::Name_`), so its
CDR bytes are the ones a ROS 2 node sends and expects. Service parts carry the request header rmw_cyclonedds
puts in front of their fields (the client writer's 64-bit id and a sequence number).
"""

from __future__ import annotations

import dataclasses
import threading
import time
import types
from collections.abc import Iterable, Iterator
from functools import cache
from pathlib import Path
from typing import Any

import cyclonedds.idl.types as idl
from cyclonedds.idl import IdlStruct
from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from plem.middleware.names import dds_type_name

INTERFACES = Path(__file__).with_name("interfaces")
PLEM_MSGS = INTERFACES / "plem_msgs"
#: Packages in `interfaces/` parsed when one of their types is first asked for, not when the library loads.
ON_DEMAND = frozenset({"moveit_msgs", "octomap_msgs", "object_recognition_msgs"})

#: Fields rmw_cyclonedds writes before a request's or reply's own fields.
REQUEST_HEADER = ("rmw_guid", "rmw_seq")

_BASE = {
    "bool": bool, "byte": idl.uint8, "char": idl.uint8, "int8": idl.int8, "uint8": idl.uint8,
    "int16": idl.int16, "uint16": idl.uint16, "int32": idl.int32, "uint32": idl.uint32,
    "int64": idl.int64, "uint64": idl.uint64, "float32": idl.float32, "float64": idl.float64, "string": str,
}
_ZERO = {"bool": False, "string": "", "float32": 0.0, "float64": 0.0}

# The goal/result/feedback parts every action type has, as rosidl composes them.
_ACTION_PARTS = {
    "SendGoal_Request": "unique_identifier_msgs/UUID goal_id\n{action}_Goal goal",
    "SendGoal_Response": "bool accepted\nbuiltin_interfaces/Time stamp",
    "GetResult_Request": "unique_identifier_msgs/UUID goal_id",
    "GetResult_Response": "int8 status\n{action}_Result result",
    "FeedbackMessage": "unique_identifier_msgs/UUID goal_id\n{action}_Feedback feedback",
}


def _split(text: str) -> list[str]:
    """The parts of a .srv or .action text, separated by '---' lines."""
    parts: list[list[str]] = [[]]
    for line in text.splitlines():
        if line.strip() == "---":
            parts.append([])
        else:
            parts[-1].append(line)
    return ["\n".join(part) for part in parts]


def _definitions(path: Path) -> dict[str, str]:
    """ROS type name → .msg text for one definition file (a .srv or .action yields its parts)."""
    package, kind, name = path.parent.parent.name, path.suffix[1:], path.stem
    text = path.read_text(encoding="utf-8")
    if kind == "msg":
        return {f"{package}/msg/{name}": text}
    base = f"{package}/{kind}/{name}"
    if kind == "srv":
        request, response = _split(text)
        return {f"{base}_Request": request, f"{base}_Response": response}
    goal, result, feedback = _split(text)
    parts = {f"{base}_Goal": goal, f"{base}_Result": result, f"{base}_Feedback": feedback}
    parts.update({f"{base}_{part}": template.format(action=base) for part, template in _ACTION_PARTS.items()})
    return parts


def _parse(ros_type: str, text: str) -> dict[str, Any]:
    """Parse as a message of the type's package, so relative field types resolve to `pkg/msg/...`."""
    package, _, name = ros_type.split("/")
    parsed = get_types_from_msg(text, f"{package}/msg/{name}")
    return {ros_type: parsed[f"{package}/msg/{name}"]}


def _idl_type(constructor: type, *parameters: Any) -> Any:
    """`constructor[parameters]` of cyclonedds's array, sequence or bounded_str: an annotation built at run time."""
    return constructor[parameters]  # type: ignore[index]  # cyclonedds subscripts plain classes (__class_getitem__)


def _register(store: Typestore, paths: Iterable[Path]) -> list[str]:
    """Parse definition files into the store in one registration; the ROS types they define."""
    parsed: dict[str, Any] = {}
    for path in paths:
        for ros_type, text in _definitions(path).items():
            parsed.update(_parse(ros_type, text))
    store.register(parsed)
    return list(parsed)


def _referenced(fields: Iterable[tuple[str, tuple[Any, Any]]]) -> Iterator[str]:
    """The message types a type's fields hold, directly or as array and sequence elements."""
    for _, (node, detail) in fields:
        while node in (Nodetype.ARRAY, Nodetype.SEQUENCE):
            node, detail = detail[0]
        if node == Nodetype.NAME:
            yield detail


class InterfaceLibrary:
    """Every ROS 2 type plem speaks, as rosbags definitions and as Cyclone DDS structs."""

    def __init__(self) -> None:
        self.store = get_typestore(Stores.ROS2_JAZZY)
        paths = sorted(INTERFACES.glob("*/*/*.*"))
        self._pending = {package: [path for path in paths if path.parent.parent.name == package]
                         for package in ON_DEMAND}
        self._loading = threading.RLock()  # guards the on-demand packages and the structs built so far
        self._structs: dict[tuple[str, bool], type[IdlStruct]] = {}
        _register(self.store, [path for path in paths if path.parent.parent.name not in ON_DEMAND])

    def known(self, ros_type: str) -> bool:
        """Whether `ros_type` (e.g. `std_msgs/msg/String`) has a definition here."""
        self._require(ros_type)
        return ros_type in self.store.fielddefs

    def message(self, ros_type: str) -> type[IdlStruct]:
        """The DDS struct of a message type, e.g. `sensor_msgs/msg/JointState`."""
        return self._struct(ros_type, with_header=False)

    def service_part(self, ros_type: str) -> type[IdlStruct]:
        """The DDS struct of a request or reply on the wire: rmw's request header, then the part's fields."""
        return self._struct(ros_type, with_header=True)

    def new(self, ros_type: str, /, **fields: Any) -> Any:
        """A message of `ros_type` with the given fields and every other field zero or empty."""
        return self.message(ros_type)(**fields)

    def stamp(self, ns: int | None = None) -> Any:
        """builtin_interfaces/Time of `ns` nanoseconds since the epoch (default: now)."""
        ns = time.time_ns() if ns is None else ns
        return self.new("builtin_interfaces/msg/Time", sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)

    def type_hash(self, ros_type: str) -> str:
        """The type's RIHS01 hash, as ROS 2 Iron and later announce it."""
        self._require(ros_type)
        return self.store.hash_rihs01(ros_type)

    def _require(self, ros_type: str) -> None:
        """Parse the on-demand package `ros_type` belongs to, and those its types use, if not done yet."""
        with self._loading:
            paths = self._pending.pop(ros_type.split("/", 1)[0], None)
            if paths is None:
                return
            for defined in _register(self.store, paths):
                for used in _referenced(self.store.fielddefs[defined][1]):
                    self._require(used)

    def _struct(self, ros_type: str, with_header: bool) -> type[IdlStruct]:
        """The one struct class of a type (threads asking at once get the same class)."""
        key = (ros_type, with_header)
        found = self._structs.get(key)
        if found is None:
            with self._loading:
                found = self._structs.get(key)
                if found is None:
                    found = self._structs[key] = self._build_struct(ros_type, with_header)
        return found

    def _build_struct(self, ros_type: str, with_header: bool) -> type[IdlStruct]:
        self._require(ros_type)
        constants, fields = self.store.fielddefs[ros_type]
        annotations: dict[str, Any] = {}
        defaults: dict[str, Any] = {}
        if with_header:
            annotations.update({REQUEST_HEADER[0]: idl.uint64, REQUEST_HEADER[1]: idl.int64})
            defaults.update({REQUEST_HEADER[0]: 0, REQUEST_HEADER[1]: 0})
        for name, spec in fields:
            annotations[name], defaults[name] = self._field(spec)

        def body(namespace: dict[str, Any]) -> None:
            namespace["__annotations__"] = annotations
            for name, default in defaults.items():
                namespace[name] = dataclasses.field(default_factory=default) if callable(default) else default
            namespace.update({name: value for name, _, value in constants})

        name = ros_type.rsplit("/", 1)[1]
        struct = types.new_class(name, (IdlStruct,), {"typename": dds_type_name(ros_type)}, body)
        return dataclasses.dataclass(struct)

    def _field(self, spec: tuple[Any, Any]) -> tuple[Any, Any]:
        """A field's DDS annotation and its default (a value, or a factory for mutable ones)."""
        node, detail = spec
        if node == Nodetype.BASE:                             # with a bound for strings
            base, bound = detail
            if base == "wstring":
                raise NotImplementedError("wstring fields are not supported")
            kind = _idl_type(idl.bounded_str, bound) if base == "string" and bound else _BASE[base]
            return kind, _ZERO.get(base, 0)
        if node == Nodetype.NAME:                             # another message
            struct = self.message(detail)
            return struct, struct
        element, size = detail
        kind, default = self._field(element)
        if node == Nodetype.ARRAY:
            return (_idl_type(idl.array, kind, size),
                    lambda: [default() if callable(default) else default for _ in range(size)])
        return (_idl_type(idl.sequence, kind, size) if size else _idl_type(idl.sequence, kind)), list


@cache
def library() -> InterfaceLibrary:
    """The process's interface library (loading it parses every definition once)."""
    return InterfaceLibrary()
