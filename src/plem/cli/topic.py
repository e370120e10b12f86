"""`plem topic list|info|echo|hz|pub`: inspect and publish ROS 2 topics on the DDS domain without a ROS install.

Discovery settings come from ROS_DOMAIN_ID and ROS_AUTOMATIC_DISCOVERY_RANGE, as for `ros2 topic`.
The middleware (Cyclone DDS, the interface library) is imported inside the commands so other commands
start fast.

The helpers `plem service`, `plem action` and `plem node` share live here too: option validation, names and
types given on the command line, messages filled from YAML and messages printed as YAML.
"""

from __future__ import annotations

import contextlib
import dataclasses
import difflib
import math
import sys
import time
from collections import deque
from collections.abc import Iterable
from enum import StrEnum
from typing import TYPE_CHECKING, Annotated, Any

import typer

from plem.cli.output import print_warnings
from plem.errors import ConfigError, PlemError, UsageError

if TYPE_CHECKING:
    from plem.middleware.graph import Endpoint, Graph
    from plem.middleware.node import Node, Subscription
    from plem.middleware.types import InterfaceLibrary

app = typer.Typer(help="Inspect and publish ROS 2 topics on the DDS domain (no ROS install needed).",
                  no_args_is_help=True)

#: How often a waiting command wakes up, so Ctrl-C is noticed promptly.
WAKE_S = 0.2
#: Reader history for `hz`: room for about 0.1 s at 10 kHz between two takes.
HZ_DEPTH = 1000
#: Reader history for `echo`, as ros2 topic echo uses.
ECHO_DEPTH = 10
#: Writer history for `pub`.
PUB_DEPTH = 10
#: How long `pub --once` or `--times` waits, after its last message, for the subscribers to acknowledge it.
ACK_WAIT_S = 2.0
#: Discovery window of the commands that list what exists (`list`, `info`).
LIST_TIMEOUT_S = 1.5

#: Longest `--timeout` or `--duration` (30 days): DDS waits are counted in int64 nanoseconds.
MAX_SECONDS = 30 * 24 * 3600
#: Highest `--rate`: one message a microsecond.
MAX_RATE = 1e6

#: The field rosidl adds to an empty message; ROS 2 tools neither show it nor take it.
PLACEHOLDER = "structure_needs_at_least_one_member"
#: The request header rmw puts in front of a service part's fields (see plem.middleware.types.REQUEST_HEADER).
REQUEST_HEADER = ("rmw_guid", "rmw_seq")
_INTEGERS = {"int8": 8, "int16": 16, "int32": 32, "int64": 64}
_UNSIGNED = {"uint8": 8, "byte": 8, "char": 8, "uint16": 16, "uint32": 32, "uint64": 64}
_FLOAT32_MAX = 3.4028234663852886e38
#: The interface kinds a TYPE argument names, and the part of the type that holds what the command fills in.
_KINDS = {"msg": ("message", ""), "srv": ("service", "_Request"), "action": ("action", "_Goal")}


def seconds(value: float | None, param: typer.CallbackParam) -> float | None:
    """A `--timeout`/`--duration` as given; NaN, infinite, negative or huge seconds are a usage error naming it."""
    if value is not None and not 0 <= value <= MAX_SECONDS:   # false for NaN too
        flag = param.opts[0]
        raise UsageError(f"{flag} must be a number of seconds from 0 to {MAX_SECONDS}",
                         what=f"{flag} SECONDS: a finite number from 0 to {MAX_SECONDS} (30 days)",
                         why=f"{flag} is {value}", how=f"give {flag} a number of seconds, e.g. {flag} 5")
    return value


def _rate(value: float, param: typer.CallbackParam) -> float:
    """`--rate` in Hz: more than 0, at most MAX_RATE."""
    if not 0 < value <= MAX_RATE:   # false for NaN too
        flag = param.opts[0]
        raise UsageError(f"{flag} must be a rate in Hz above 0",
                         what=f"{flag} HZ: a number above 0, at most {MAX_RATE:g}", why=f"{flag} is {value}",
                         how=f"give {flag} the messages per second, e.g. {flag} 10")
    return value


Topic = Annotated[str, typer.Argument(help="ROS 2 topic, e.g. /indy/joint_states.")]
Timeout = Annotated[float, typer.Option("--timeout", callback=seconds,
                                        help="Seconds to wait for a publisher of the topic.")]
ListTimeout = Annotated[float, typer.Option("--timeout", callback=seconds, help="Seconds of discovery.")]


class Reliability(StrEnum):
    """`--qos-reliability` choices."""

    best_effort = "best_effort"
    reliable = "reliable"


class Durability(StrEnum):
    """`--qos-durability` choices."""

    volatile = "volatile"
    transient_local = "transient_local"


# -- names and types given on the command line -----------------------------------------------------------
def ros_name(name: str, kind: str) -> str:
    """The absolute ROS 2 name of a TOPIC, SERVICE, ACTION or NODE argument (a leading '/' may be left out)."""
    from plem.middleware import names

    try:
        return names.check_name(name if name.startswith("/") else f"/{name}")
    except ConfigError as error:
        raise UsageError(f"{kind} '{name}' is not a valid ROS 2 name", what=error.what, why=error.why,
                         how=f"give the {kind}'s absolute name, e.g. /indy/joint_states; list them with "
                             f"`plem {kind} list`") from None


def interface_type(library: InterfaceLibrary, given: str, kind: str) -> str:
    """The full name (`pkg/KIND/Name`) of a TYPE argument of `kind` msg, srv or action; `pkg/Name` may leave the
    kind out. A malformed name, one of another kind or one the library does not know is a usage error."""
    label, part = _KINDS[kind]
    tokens = given.split("/")
    if len(tokens) == 2:
        tokens.insert(1, kind)
    ros_type = "/".join(tokens)
    if len(tokens) != 3 or tokens[1] != kind or not all(tokens):
        raise UsageError(f"'{given}' is not a ROS 2 {label} type", what=f"a {label} type as pkg/{kind}/Name",
                         why=f"got '{given}'",
                         how=f"e.g. {_example(kind)}; `plem {_command(kind)} list -t` shows each one's type")
    if not library.known(ros_type + part):
        package = tokens[0]
        same_package = sorted({known.removesuffix(part) for known in library.store.fielddefs
                               if known.startswith(f"{package}/{kind}/") and known.endswith(part)})
        if same_package:
            why = f"{package} has no {label} {tokens[2]}; its {label}s: {_listed(same_package)}"
        else:
            packages = sorted({known.split("/")[0] for known in library.store.fielddefs if f"/{kind}/" in known})
            why = f"no package {package} with {label}s; packages with {label}s: {', '.join(packages)}"
        raise UsageError(f"{label} type {ros_type} is not known to plem",
                         what=f"a {label} type of plem's interface library", why=why,
                         how=f"check the spelling, or add the .{kind} definition under "
                             f"src/plem/middleware/interfaces/{package}/{kind}/")
    return ros_type


def _example(kind: str) -> str:
    return {"msg": "std_msgs/msg/String", "srv": "controller_manager_msgs/srv/ListControllers",
            "action": "plem_msgs/action/SetMode"}[kind]


def _command(kind: str) -> str:
    return {"msg": "topic", "srv": "service", "action": "action"}[kind]


def _listed(items: list[str], limit: int = 10) -> str:
    return ", ".join(items[:limit]) + (", ..." if len(items) > limit else "") if items else "none"


def not_found(kind: str, name: str, node: Node, timeout: float, seen: Iterable[str]) -> PlemError:
    """The error for a topic, service, action or node that discovery did not show: what exists, what is close."""
    from plem.middleware.graph import hidden

    known = sorted(seen if hidden(name) else (item for item in seen if not hidden(item)))
    close = difflib.get_close_matches(name, known, n=3)
    why = f"none announced itself within {timeout} s ({node.settings.describe()}); {kind}s seen: {_listed(known)}"
    return PlemError(f"unknown {kind} {name} on ROS_DOMAIN_ID={node.domain_id}",
                     what=f"a {kind} {name} on the domain",
                     why=why + (f"; did you mean {' or '.join(close)}?" if close else ""),
                     how=f"list them with `plem {kind} list`, use the robot's ROS_DOMAIN_ID and "
                         "ROS_AUTOMATIC_DISCOVERY_RANGE, or wait longer with --timeout")


def wrong_type(kind: str, name: str, given: str, announced: list[str]) -> PlemError:
    """The error for a service or action whose endpoints announce another type than the one given."""
    return PlemError(f"{kind} {name} is not of type {given}", what=f"TYPE as the {kind}'s type",
                     why=f"{name} announces {', '.join(announced)}",
                     how=f"give {announced[0]}; `plem {kind} list -t` shows each {kind}'s type")


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
                                 f"'{value}'" if isinstance(value, (int, float)) else f"give {path} a string")
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
    import json

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


# -- list ------------------------------------------------------------------------------------------------------
@app.command("list")
def list_topics(
    show_types: Annotated[bool, typer.Option("--show-types", "-t", help="Print each topic's type.")] = False,
    timeout: ListTimeout = LIST_TIMEOUT_S,
    include_hidden: Annotated[bool, typer.Option("--include-hidden-topics", help="Also list topics with a "
                                                 "token starting with '_' (e.g. actions' status).")] = False,
) -> None:
    """List the ROS 2 topics that publishers or subscriptions on the domain announce."""
    from plem.middleware.graph import Graph, hidden
    from plem.middleware.node import Node

    node = Node()
    graph = Graph(node)
    graph.discover(timeout)
    topics = graph.topics()
    if not topics:
        print_warnings([f"no ROS 2 topics seen within {timeout} s ({node.settings.describe()})"])
    for name, info in topics.items():
        if include_hidden or not hidden(name):
            typer.echo(f"{name} [{', '.join(info.types)}]" if show_types else name)


# -- info ------------------------------------------------------------------------------------------------------
def _qos_lines(endpoint: Endpoint) -> list[str]:
    profile = endpoint.profile
    history = f"KEEP_LAST ({profile.depth})" if profile.depth else "KEEP_ALL"   # keep-all has no depth
    return ["QoS profile:", f"  Reliability: {'RELIABLE' if profile.reliable else 'BEST_EFFORT'}",
            f"  History (Depth): {history}",
            f"  Durability: {'TRANSIENT_LOCAL' if profile.transient_local else 'VOLATILE'}"]


def _endpoint_text(endpoint: Endpoint, graph: Graph) -> str:
    """One endpoint as `ros2 topic info -v` prints it."""
    from plem.middleware.graph import UNKNOWN_NODE_NAME, UNKNOWN_NODE_NAMESPACE

    owner = graph.node_of(endpoint)
    return "\n".join([
        f"Node name: {owner.name if owner else UNKNOWN_NODE_NAME}",
        f"Node namespace: {owner.namespace if owner else UNKNOWN_NODE_NAMESPACE}",
        f"Topic type: {endpoint.type_name}",
        f"Topic type hash: {endpoint.type_hash or 'INVALID'}",
        f"Endpoint type: {'PUBLISHER' if endpoint.publisher else 'SUBSCRIPTION'}",
        f"GID: {endpoint.gid_text}",
        *_qos_lines(endpoint),
    ])


@app.command("info")
def info(
    topic: Topic,
    verbose: Annotated[bool, typer.Option("--verbose", "-v", help="Print each endpoint: its node, GID and "
                                          "QoS.")] = False,
    timeout: ListTimeout = LIST_TIMEOUT_S,
) -> None:
    """Print the topic's type and its publisher and subscription counts (like `ros2 topic info`)."""
    from plem.middleware.graph import Graph
    from plem.middleware.node import Node

    name = ros_name(topic, "topic")
    node = Node()
    graph = Graph(node, nodes=True)

    def complete(seen: Graph) -> bool:   # every endpoint of the topic belongs to an announced node
        found = seen.topics().get(name)
        nodes = seen.nodes()
        return found is not None and all(seen.node_of(endpoint, nodes) for endpoint in seen.endpoints()
                                         if endpoint.name == name and endpoint.kind == "topic")

    graph.discover(timeout, until=complete)
    topics = graph.topics()
    found = topics.get(name)
    if found is None:
        raise not_found("topic", name, node, timeout, topics)
    end = "\n" if verbose else ""   # ros2 separates the blocks of the verbose form by blank lines
    typer.echo(f"Type: {', '.join(found.types)}{end}")
    for label, endpoints in (("Publisher", found.publishers), ("Subscription", found.subscriptions)):
        typer.echo(f"{label} count: {len(endpoints)}{end}")
        if verbose:
            for endpoint in endpoints:
                typer.echo(_endpoint_text(endpoint, graph) + "\n")


# -- echo and hz -------------------------------------------------------------------------------------------------
def _no_publisher(name: str, node: Node, timeout: float, seen: list[str]) -> PlemError:
    return PlemError(f"no publisher of {name} on ROS_DOMAIN_ID={node.domain_id}",
                     what=f"a ROS 2 node or plem robot publishing {name}",
                     why=f"none announced itself within {timeout} s ({node.settings.describe()}); "
                         f"topics with publishers: {_listed(seen)}",
                     how="check the name with `plem topic list`, use the publisher's ROS_DOMAIN_ID and "
                         "ROS_AUTOMATIC_DISCOVERY_RANGE, or wait longer with --timeout")


def _unknown_type(name: str, ros_type: str, node: Node) -> PlemError:
    packages = sorted({known.split("/")[0] for known in node.library.store.fielddefs})
    return PlemError(f"cannot decode {name}: type {ros_type} is not known to plem",
                     what=f"a message type of plem's interface library (packages: {', '.join(packages)})",
                     why=f"{name} carries {ros_type}",
                     how="use `ros2 topic echo` from a ROS 2 install, or add the .msg definition under "
                         "src/plem/middleware/interfaces/<package>/msg/")


def _subscribe(topic: str, timeout: float, depth: int, reliable: bool | None = None) -> tuple[Node, Subscription[Any]]:
    """Wait for a publisher of `topic`, then subscribe with its type and a QoS it can serve."""
    from plem.middleware.graph import Graph
    from plem.middleware.node import Node

    name = ros_name(topic, "topic")
    node = Node()
    graph = Graph(node)
    graph.discover(timeout, until=lambda seen: name in seen.topics() and bool(seen.topics()[name].publishers))
    topics = graph.topics()
    found = topics.get(name)
    if found is None or not found.publishers:
        raise _no_publisher(name, node, timeout, [seen for seen, other in topics.items() if other.publishers])
    published = sorted({publisher.type_name for publisher in found.publishers})
    if len(published) > 1:
        raise PlemError(f"{name} is published with several types", what="one type per topic",
                        why=f"publishers announce {', '.join(published)}",
                        how="stop the publishers of the wrong type, or rename one of the topics")
    ros_type = published[0]
    if not node.library.known(ros_type):
        raise _unknown_type(name, ros_type, node)
    if reliable and not all(publisher.profile.reliable for publisher in found.publishers):
        print_warnings([f"a best-effort publisher of {name} does not serve a reliable reader; "
                        "drop --qos-reliability reliable to hear it"])
    return node, node.subscription(name, ros_type, found.reader_profile(depth, reliable))


@app.command("echo")
def echo(
    topic: Topic,
    once: Annotated[bool, typer.Option("--once", help="Print one message and exit.")] = False,
    count: Annotated[int, typer.Option("--count", min=0, help="Exit after N messages (0: until Ctrl-C).")] = 0,
    timeout: Timeout = 5.0,
    qos_reliability: Annotated[Reliability | None, typer.Option(
        "--qos-reliability", help="Reader reliability (default: what every publisher offers).",
        show_default=False)] = None,
    no_arr: Annotated[bool, typer.Option("--no-arr", help="Print sequences as their length only.")] = False,
) -> None:
    """Print the topic's messages as YAML, separated by `---` (like `ros2 topic echo`)."""
    limit = 1 if once else count
    reliable = None if qos_reliability is None else qos_reliability is Reliability.reliable
    node, subscription = _subscribe(topic, timeout, ECHO_DEPTH, reliable)
    waitset = node.waitset([subscription])
    received = 0
    while not limit or received < limit:
        waitset.wait(int(WAKE_S * 1e9))
        for message in subscription.take(limit - received if limit else 256):
            if message.sample_info.valid_data:
                typer.echo(to_yaml(message, no_arr) + "\n---")
                received += 1


def _report(stamps: deque[int], new: int) -> None:
    """One `ros2 topic hz` report from the source timestamps (ns) in the window."""
    import numpy as np

    if not new:
        typer.echo("no new messages")
        return
    periods = np.diff(np.sort(np.fromiter(stamps, dtype=np.int64, count=len(stamps)))) / 1e9
    if not len(periods) or periods.mean() <= 0:
        return
    typer.echo(f"average rate: {1 / periods.mean():.3f}\n\tmin: {periods.min():.3f}s max: {periods.max():.3f}s "
               f"std dev: {periods.std():.5f}s window: {len(stamps)}")


@app.command("hz")
def hz(
    topic: Topic,
    window: Annotated[int, typer.Option("--window", "-w", min=2, help="Messages the statistics cover.")] = 10000,
    duration: Annotated[float | None, typer.Option(
        "--duration", callback=seconds, help="Stop after S seconds (default: run until Ctrl-C).",
        show_default=False)] = None,
    timeout: Timeout = 5.0,
) -> None:
    """Print the topic's publishing rate every second (like `ros2 topic hz`).

    Periods come from the publishers' source timestamps, so taking messages in batches does not skew them.
    """
    node, subscription = _subscribe(topic, timeout, HZ_DEPTH)
    waitset = node.waitset([subscription])
    stamps: deque[int] = deque(maxlen=window)
    new = 0
    start = time.monotonic()
    end = start + duration if duration is not None else math.inf
    next_report = start + 1.0
    while True:
        now = time.monotonic()
        if now >= next_report:
            _report(stamps, new)
            new, next_report = 0, next_report + 1.0
        if now >= end:
            return
        waitset.wait(int(min(next_report - now, end - now, WAKE_S) * 1e9))
        for sample in subscription.take(HZ_DEPTH):
            if sample.sample_info.valid_data:
                stamps.append(sample.sample_info.source_timestamp)
                new += 1


# -- pub -----------------------------------------------------------------------------------------------------------
@app.command("pub")
def pub(
    topic: Topic,
    message_type: Annotated[str, typer.Argument(metavar="TYPE", help="Message type, e.g. std_msgs/msg/String.")],
    values: Annotated[str, typer.Argument(help="The message's fields as a YAML mapping, e.g. \"{data: hello}\"; "
                                          "fields left out are zero.")] = "{}",
    rate: Annotated[float, typer.Option("--rate", "-r", callback=_rate, help="Messages per second.")] = 1.0,
    once: Annotated[bool, typer.Option("--once", help="Publish one message and exit.")] = False,
    times: Annotated[int, typer.Option("--times", "-t", min=0, help="Publish N messages and exit "
                                       "(0: until Ctrl-C).")] = 0,
    timeout: Annotated[float, typer.Option("--timeout", callback=seconds, help="With --once or --times: seconds to "
                                           "wait for a subscription.")] = 5.0,
    qos_reliability: Annotated[Reliability, typer.Option("--qos-reliability",
                                                         help="Writer reliability.")] = Reliability.reliable,
    qos_durability: Annotated[Durability, typer.Option("--qos-durability",
                                                       help="Writer durability.")] = Durability.volatile,
) -> None:
    """Publish a message filled from YAML, at --rate until Ctrl-C, or --once (like `ros2 topic pub`).

    With --once or --times the first message waits until a subscription is matched, and the command exits once
    the subscribers acknowledged the last one.
    """
    from cyclonedds.util import duration

    from plem.middleware.node import Node
    from plem.middleware.qos import QosProfile
    from plem.middleware.types import library

    if once and times:
        raise UsageError("--once and --times exclude each other", what="either --once or --times N",
                         why=f"got --once and --times {times}", how="drop one of them")
    count = 1 if once else times
    name = ros_name(topic, "topic")
    interfaces = library()
    ros_type = interface_type(interfaces, message_type, "msg")
    message = message_from_yaml(interfaces, ros_type, values, "VALUES")
    node = Node(interfaces=interfaces)
    profile = QosProfile(reliable=qos_reliability is Reliability.reliable, depth=PUB_DEPTH,
                         transient_local=qos_durability is Durability.transient_local)
    publisher = node.publisher(name, ros_type, profile)
    typer.echo("publisher: beginning loop")
    if count:
        _wait_for_subscription(publisher, name, node, timeout)
    period = 1.0 / rate
    start = time.monotonic()
    published = 0
    while not count or published < count:
        wait = start + published * period - time.monotonic()
        if wait > 0:
            time.sleep(wait)
        published += 1
        typer.echo(f"publishing #{published}: {message_repr(message)}\n")
        publisher.publish(message)
    publisher.writer.wait_for_acks(duration(seconds=ACK_WAIT_S))


def _wait_for_subscription(publisher: Any, name: str, node: Node, timeout: float) -> None:
    """Block until a subscription of the topic is matched; a PlemError when none is within `timeout`."""
    deadline = time.monotonic() + timeout
    if publisher.subscribers == 0:
        typer.echo("Waiting for at least 1 matching subscription(s)...")
    while publisher.subscribers == 0:
        if time.monotonic() >= deadline:
            raise PlemError(f"no subscription of {name} matched within {timeout} s",
                            what=f"a subscriber of {name} with a QoS the publisher offers, to receive the message",
                            why=f"none matched ({node.settings.describe()}); the message would be lost",
                            how="start the subscriber first, check the name with `plem topic info` (a best-effort "
                                "publisher does not serve a reliable subscription), or wait longer with --timeout")
        time.sleep(0.01)
