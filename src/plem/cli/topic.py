"""`plem topic list|info|echo|hz|pub`: inspect and publish ROS 2 topics on the DDS domain without a ROS install.

Discovery settings come from ROS_DOMAIN_ID and ROS_AUTOMATIC_DISCOVERY_RANGE, as for `ros2 topic`.
The middleware (Cyclone DDS, the interface library) is imported inside the commands so other commands
start fast.
"""

from __future__ import annotations

import contextlib
import math
import signal
import threading
import time
from collections import deque
from collections.abc import Iterator
from enum import StrEnum
from typing import TYPE_CHECKING, Annotated, Any

import typer

from plem.cli.output import print_warnings
from plem.cli.ros_arguments import (
    LIST_TIMEOUT_S,
    ListTimeout,
    interface_type,
    listed,
    not_found,
    ros_name,
    seconds,
)
from plem.cli.ros_messages import message_from_yaml, message_repr, to_yaml
from plem.errors import PlemError, UsageError

if TYPE_CHECKING:
    from cyclonedds.core import WaitSet

    from plem.middleware.graph import Endpoint, Graph
    from plem.middleware.node import Node, Subscription

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
#: Highest `--rate`: one message a microsecond.
MAX_RATE = 1e6


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


class Reliability(StrEnum):
    """`--qos-reliability` choices."""

    best_effort = "best_effort"
    reliable = "reliable"


class Durability(StrEnum):
    """`--qos-durability` choices."""

    volatile = "volatile"
    transient_local = "transient_local"


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
                         f"topics with publishers: {listed(seen)}",
                     how="check the name with `plem topic list`, use the publisher's ROS_DOMAIN_ID and "
                         "ROS_AUTOMATIC_DISCOVERY_RANGE, or wait longer with --timeout")


def _unknown_type(name: str, ros_type: str, node: Node) -> PlemError:
    packages = sorted({known.split("/")[0] for known in node.library.store.fielddefs})
    return PlemError(f"cannot decode {name}: type {ros_type} is not known to plem",
                     what=f"a message type of plem's interface library (packages: {', '.join(packages)})",
                     why=f"{name} carries {ros_type}",
                     how="use `ros2 topic echo` from a ROS 2 install, or add the .msg definition under "
                         "src/plem/middleware/interfaces/<package>/msg/")


@contextlib.contextmanager
def _ctrl_c_noted() -> Iterator[threading.Event]:
    """Ctrl-C sets the event instead of raising KeyboardInterrupt in the middle of a DDS call; the command's loop
    sees it at its next wake-up, stops and exits 130."""
    interrupted = threading.Event()
    previous = signal.signal(signal.SIGINT, lambda _signum, _frame: interrupted.set())
    try:
        yield interrupted
    finally:
        signal.signal(signal.SIGINT, previous)
    if interrupted.is_set():
        raise typer.Exit(130)


def _woken(waitset: WaitSet, seconds: float, interrupted: threading.Event) -> bool:
    """Wait up to `seconds` for data; False once Ctrl-C was pressed (a wait the signal cut short fails in Cyclone,
    which is then no error)."""
    from cyclonedds.core import DDSException

    try:
        waitset.wait(int(seconds * 1e9))
    except DDSException:
        if not interrupted.is_set():
            raise
    return not interrupted.is_set()


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
    with _ctrl_c_noted() as interrupted:
        while (not limit or received < limit) and _woken(waitset, WAKE_S, interrupted):
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
    with _ctrl_c_noted() as interrupted:
        while True:
            now = time.monotonic()
            if now >= next_report:
                _report(stamps, new)
                new, next_report = 0, next_report + 1.0
            if now >= end or not _woken(waitset, min(next_report - now, end - now, WAKE_S), interrupted):
                return
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
