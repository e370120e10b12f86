"""A ROS node's parameter services (rcl_interfaces), read-only, so `ros2 param get/list/describe` answer.

plem's parameters come from controllers.yaml, the URDF and the launch arguments, which are fixed while
the robot runs; setting one is refused with where to change it instead.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from plem.middleware.node import Entities, Node, ServiceServer

#: A parameter value: what Python type maps to which rcl_interfaces/msg/ParameterType and field.
ParameterValue = bool | int | float | str | Sequence[str] | Sequence[float] | Sequence[int]
SERVICES = {"get_parameters": "GetParameters", "list_parameters": "ListParameters",
            "describe_parameters": "DescribeParameters", "get_parameter_types": "GetParameterTypes",
            "set_parameters": "SetParameters", "set_parameters_atomically": "SetParametersAtomically"}
NOT_SET, BOOL, INTEGER, DOUBLE, STRING = 0, 1, 2, 3, 4
INTEGER_ARRAY, DOUBLE_ARRAY, STRING_ARRAY = 7, 8, 9
_FIELDS = {BOOL: "bool_value", INTEGER: "integer_value", DOUBLE: "double_value", STRING: "string_value",
           INTEGER_ARRAY: "integer_array_value", DOUBLE_ARRAY: "double_array_value",
           STRING_ARRAY: "string_array_value"}


def parameter_type(value: ParameterValue) -> int:
    """The rcl_interfaces ParameterType of a Python value."""
    if isinstance(value, bool):
        return BOOL
    if isinstance(value, int):
        return INTEGER
    if isinstance(value, float):
        return DOUBLE
    if isinstance(value, str):
        return STRING
    items = list(value)
    if items and all(isinstance(item, str) for item in items) or not items:
        return STRING_ARRAY
    if all(isinstance(item, int) and not isinstance(item, bool) for item in items):
        return INTEGER_ARRAY
    return DOUBLE_ARRAY


class ParameterServices:
    """The six parameter services of the node `fully_qualified_name` (e.g. /indy/controller_manager)."""

    def __init__(self, node: Node, fully_qualified_name: str, parameters: Mapping[str, ParameterValue],
                 set_how: str) -> None:
        self.node = node
        self.parameters = dict(parameters)
        self.set_how = set_how
        self.servers = {name: node.service(f"{fully_qualified_name}/{name}", f"rcl_interfaces/srv/{kind}")
                        for name, kind in SERVICES.items()}

    @property
    def services(self) -> tuple[ServiceServer, ...]:
        """The service servers, for a wait set."""
        return tuple(self.servers.values())

    def entities(self) -> Entities:
        """The DDS endpoints of all six services."""
        total = Entities()
        for server in self.services:
            total = total + server.entities()
        return total

    def value(self, name: str) -> Any:
        """rcl_interfaces/msg/ParameterValue of `name` (type NOT_SET when the node has no such parameter)."""
        new = self.node.library.new
        if name not in self.parameters:
            return new("rcl_interfaces/msg/ParameterValue", type=NOT_SET)
        value = self.parameters[name]
        kind = parameter_type(value)
        given = list(value) if isinstance(value, Sequence) and not isinstance(value, str) else value
        return new("rcl_interfaces/msg/ParameterValue", type=kind, **{_FIELDS[kind]: given})

    def spin_once(self) -> None:
        """Answer every waiting request."""
        new = self.node.library.new
        for name, server in self.servers.items():
            for request in server.take():
                if name == "get_parameters":
                    server.reply(request, values=[self.value(n) for n in request.names])
                elif name == "get_parameter_types":
                    server.reply(request, types=[parameter_type(self.parameters[n]) if n in self.parameters
                                                 else NOT_SET for n in request.names])
                elif name == "list_parameters":
                    names = sorted(n for n in self.parameters
                                   if not request.prefixes or any(n.startswith(p) for p in request.prefixes))
                    prefixes = sorted({n.rsplit(".", 1)[0] for n in names if "." in n})
                    server.reply(request, result=new("rcl_interfaces/msg/ListParametersResult", names=names,
                                                     prefixes=prefixes))
                elif name == "describe_parameters":
                    server.reply(request, descriptors=[new(
                        "rcl_interfaces/msg/ParameterDescriptor", name=n, read_only=True,
                        type=parameter_type(self.parameters[n]) if n in self.parameters else NOT_SET,
                        description=self.set_how) for n in request.names])
                elif name == "set_parameters":
                    server.reply(request, results=[self._refused(p.name) for p in request.parameters])
                else:
                    server.reply(request, result=self._refused(", ".join(p.name for p in request.parameters)))
            server.flush()

    def _refused(self, name: str) -> Any:
        return self.node.library.new("rcl_interfaces/msg/SetParametersResult", successful=False,
                                     reason=f"parameter {name} is read-only while the robot runs: {self.set_how}")
