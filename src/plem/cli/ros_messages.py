"""ROS 2 messages on the command line: filled in from YAML, printed as YAML or as rclpy prints them.

`plem topic pub`, `plem service call` and `plem action send_goal` fill their messages with the same code,
and every command prints messages the same way.
"""

from __future__ import annotations

import contextlib
import dataclasses
import difflib
import json
import math
import sys
from typing import TYPE_CHECKING, Any

from plem.errors import UsageError

if TYPE_CHECKING:
    from plem.middleware.types import InterfaceLibrary

#: The field rosidl adds to an empty message; ROS 2 tools neither show it nor take it.
PLACEHOLDER = "structure_needs_at_least_one_member"
#: The request header rmw puts in front of a service part's fields (see plem.middleware.types.REQUEST_HEADER).
REQUEST_HEADER = ("rmw_guid", "rmw_seq")
_INTEGERS = {"int8": 8, "int16": 16, "int32": 32, "int64": 64}
_UNSIGNED = {"uint8": 8, "byte": 8, "char": 8, "uint16": 16, "uint32": 32, "uint64": 64}
_FLOAT32_MAX = 3.4028234663852886e38


# -- messages from YAML --------------------------------------------------------------------------------------
def message_from_yaml(library: InterfaceLibrary, ros_type: str, text: str, argument: str) -> Any:
    """A message of `ros_type` filled from the YAML mapping `text` (the command line's `argument`, e.g. VALUES).

    Nested mappings fill nested messages (builtin_interfaces Time and Duration as `{sec: , nanosec: }`), lists
    fill arrays and sequences; fields left out keep their zero value. Malformed YAML, an unknown field, a value
    of the wrong type or out of the field's range is a usage error naming the field's path.
    """
    import yaml

    try:
        values = yaml.safe_load(text)
    except yaml.YAMLError as error:
        mark = getattr(error, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        problem = getattr(error, "problem", None) or type(error).__name__
        raise UsageError(f"{argument} is not valid YAML", what=f"{argument} as a YAML mapping, e.g. "
                         f"\"{_prototype(library, ros_type)}\"", why=f"{problem}{where} of {text!r}",
                         how=f"quote {argument} for the shell and close every bracket and quote") from None
    except RecursionError:   # the YAML parser recurses once per level of nesting
        raise UsageError(f"{argument} is nested too deeply", what=f"{argument} as a YAML mapping nested as deeply "
                         f"as {ros_type}'s fields are, e.g. \"{_prototype(library, ros_type)}\"",
                         why=f"its mappings and lists nest deeper than the YAML parser follows ({len(text)} "
                             "characters); no ROS message nests that deep",
                         how=f"give {argument} one mapping per nested message, as in the example") from None
    return _Filler(library, ros_type, argument).message(ros_type, values, "")


@dataclasses.dataclass(frozen=True)
class _Filler:
    """Fills one message of `root` from YAML values; errors name `argument` and the path of the field."""

    library: InterfaceLibrary
    root: str
    argument: str

    def error(self, path: str, why: str, how: str) -> UsageError:
        where = f"field {path}" if path else "the top level"
        return UsageError(f"{self.argument} does not fit {self.root} at {where}",
                          what=f"{self.argument} as YAML with the fields of {self.root}, e.g. "
                               f"\"{_prototype(self.library, self.root)}\"", why=why, how=how)

    def message(self, ros_type: str, values: Any, path: str) -> Any:
        fields = self.fields(ros_type)
        if values is None:
            values = {}
        if not isinstance(values, dict):
            raise self.error(path, f"{path or self.argument} is a {ros_type} message, got {_kind(values)}",
                             f"give {path or self.argument} as a mapping of its fields, e.g. "
                             f"{_prototype(self.library, ros_type)}")
        filled = {}
        for key, value in values.items():
            if key not in fields:
                close = difflib.get_close_matches(str(key), list(fields), n=1)
                listed = ", ".join(f"{name} ({_spec_text(spec)})" for name, spec in fields.items())
                raise self.error(_join(path, str(key)), f"{ros_type} has no field {key!r}"
                                 + (f" (did you mean {close[0]!r}?)" if close else ""),
                                 f"use its fields: {listed}" if listed else f"{ros_type} has no fields: give {{}}")
            filled[key] = self.value(fields[key], value, _join(path, key))
        return self.library.new(ros_type, **filled)

    def fields(self, ros_type: str) -> dict[str, Any]:
        return {name: spec for name, spec in self.library.store.fielddefs[ros_type][1] if name != PLACEHOLDER}

    def value(self, spec: tuple[Any, Any], value: Any, path: str) -> Any:
        from rosbags.interfaces import Nodetype

        node, detail = spec
        if node == Nodetype.BASE:
            return self.base(detail[0], detail[1], value, path)
        if node == Nodetype.NAME:
            return self.message(detail, value, path)
        element, size = detail
        if not isinstance(value, list):
            raise self.error(path, f"{path} is {_spec_text(spec)}, got {_kind(value)}",
                             f"give {path} as a list, e.g. {path}: [...]")
        if node == Nodetype.ARRAY and len(value) != size:
            raise self.error(path, f"{path} is {_spec_text(spec)}: exactly {size} items, got {len(value)}",
                             f"give {path} {size} items")
        if node != Nodetype.ARRAY and size and len(value) > size:
            raise self.error(path, f"{path} is {_spec_text(spec)}: at most {size} items, got {len(value)}",
                             f"give {path} at most {size} items")
        return [self.value(element, item, f"{path}[{index}]") for index, item in enumerate(value)]

    def base(self, base: str, bound: int, value: Any, path: str) -> Any:
        if base == "bool":
            if isinstance(value, bool):
                return value
            raise self.error(path, f"{path} is bool, got {_kind(value)}", f"give {path} true or false")
        if base == "string":
            if not isinstance(value, str):
                raise self.error(path, f"{path} is a string, got {_kind(value)}",
                                 f"give {path} a string; quote a number or boolean to make it one, e.g. "
                                 f"'{json.dumps(value)}'" if isinstance(value, (int, float)) else
                                 f"give {path} a string")
            if bound and len(value) > bound:
                raise self.error(path, f"{path} is string<={bound}, got {len(value)} characters",
                                 f"shorten {path} to at most {bound} characters")
            return value
        if base in _INTEGERS or base in _UNSIGNED:
            bits = _INTEGERS.get(base) or _UNSIGNED[base]
            low, high = (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if base in _INTEGERS else (0, (1 << bits) - 1)
            if isinstance(value, int) and not isinstance(value, bool) and low <= value <= high:
                return value
            got = f"{value}, out of range" if isinstance(value, int) and not isinstance(value, bool) else _kind(value)
            raise self.error(path, f"{path} is {base}, got {got}", f"give {path} a whole number from {low} to {high}")
        if isinstance(value, str):   # YAML reads 1e-3 (no '.') as a string; ros2 converts it too
            with contextlib.suppress(ValueError):
                value = float(value)
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            if base == "float32" and math.isfinite(value) and abs(value) > _FLOAT32_MAX:
                raise self.error(path, f"{path} is float32, got {value}, out of range",
                                 f"give {path} a number within ±{_FLOAT32_MAX:.7g}")
            return float(value)
        raise self.error(path, f"{path} is {base}, got {_kind(value)}", f"give {path} a number, e.g. 0.5")


def _join(path: str, key: str) -> str:
    return f"{path}.{key}" if path else key


def _kind(value: Any) -> str:
    """How a YAML value reads in an error: 'a string "a"', 'a list [1, 2]', ..."""
    kinds = ((bool, "a boolean"), (int, "an integer"), (float, "a number"), (str, "a string"), (list, "a list"),
             (dict, "a mapping"))
    if value is None:
        return "nothing (null)"
    kind = next((text for kind, text in kinds if isinstance(value, kind)), type(value).__name__)
    return f"{kind} {json.dumps(value, default=str)}"


def _spec_text(spec: tuple[Any, Any]) -> str:
    """A field's type as a .msg file writes it: float64, string<=10, pkg/msg/Name, float64[3], int32[]..."""
    from rosbags.interfaces import Nodetype

    node, detail = spec
    if node == Nodetype.BASE:
        return f"{detail[0]}<={detail[1]}" if detail[1] else str(detail[0])
    if node == Nodetype.NAME:
        return str(detail)
    element, size = detail
    if node == Nodetype.ARRAY:
        return f"{_spec_text(element)}[{size}]"
    return f"{_spec_text(element)}[<={size}]" if size else f"{_spec_text(element)}[]"


def _prototype(library: InterfaceLibrary, ros_type: str) -> str:
    """A message of `ros_type` with its zero values, as one line of YAML (what ros2 completes VALUES with)."""
    import yaml

    return yaml.safe_dump(plain(library.new(ros_type), False), default_flow_style=True, sort_keys=False,
                          width=sys.maxsize).strip()


def message_fields(message: Any) -> dict[str, Any]:
    """A message's fields by name, to build a request or goal that carries them."""
    return {field.name: getattr(message, field.name) for field in dataclasses.fields(message)}


# -- messages printed ----------------------------------------------------------------------------------------
def plain(value: Any, no_arr: bool = False) -> Any:
    """A message as dicts, lists and scalars in field order; with `no_arr`, sequences as their length.

    The placeholder field of empty messages and the request header of service parts are left out.
    """
    if dataclasses.is_dataclass(value):
        return {field.name: plain(getattr(value, field.name), no_arr) for field in dataclasses.fields(value)
                if field.name != PLACEHOLDER and field.name not in REQUEST_HEADER}
    if isinstance(value, (list, tuple, bytes)):
        return f"<sequence length: {len(value)}>" if no_arr else [plain(item, no_arr) for item in value]
    return value


def to_yaml(message: Any, no_arr: bool = False, indent: int = 0) -> str:
    """The message as block-style YAML, each line indented by `indent` spaces (no trailing newline)."""
    import yaml

    text = yaml.safe_dump(plain(message, no_arr), sort_keys=False, default_flow_style=False, allow_unicode=True,
                          width=sys.maxsize).rstrip("\n")
    return "\n".join(" " * indent + line for line in text.splitlines())


def message_repr(value: Any) -> str:
    """A message as rclpy prints one: `std_msgs.msg.String(data='hello')`, nested messages alike."""
    from plem.middleware import names

    if dataclasses.is_dataclass(value):
        dds_name = getattr(type(value), "__idl_typename__", type(value).__name__)
        python_name = (names.ros_type_name(dds_name) or dds_name).replace("/", ".")
        fields = ", ".join(f"{field.name}={message_repr(getattr(value, field.name))}"
                           for field in dataclasses.fields(value)
                           if field.name != PLACEHOLDER and field.name not in REQUEST_HEADER)
        return f"{python_name}({fields})"
    if isinstance(value, (list, tuple, bytes)):
        return f"[{', '.join(message_repr(item) for item in value)}]"
    return repr(value)
