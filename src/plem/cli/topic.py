"""`plem topic list|echo|hz`: inspect ROS 2 topics on the DDS domain without a ROS install.

Discovery settings come from ROS_DOMAIN_ID and ROS_AUTOMATIC_DISCOVERY_RANGE, as for `ros2 topic`.
The middleware (Cyclone DDS, the interface library) is imported inside the commands so other commands
start fast.
"""

from __future__ import annotations

import dataclasses
import math
import sys
import time
from collections import deque
from enum import StrEnum
from typing import TYPE_CHECKING, Annotated, Any

import typer

from plem.cli.output import print_warnings
from plem.errors import PlemError, UsageError

if TYPE_CHECKING:
    from plem.middleware.node import Node, Subscription

app = typer.Typer(help="Inspect ROS 2 topics on the DDS domain (no ROS install needed).", no_args_is_help=True)

#: How often a waiting command wakes up, so Ctrl-C is noticed promptly.
WAKE_S = 0.2
#: Reader history for `hz`: room for about 0.1 s at 10 kHz between two takes.
HZ_DEPTH = 1000
#: Reader history for `echo`, as ros2 topic echo uses.
ECHO_DEPTH = 10

#: Longest `--timeout` or `--duration` (30 days): DDS waits are counted in int64 nanoseconds.
MAX_SECONDS = 30 * 24 * 3600


def _seconds(value: float | None, param: typer.CallbackParam) -> float | None:
    """A `--timeout`/`--duration` as given; NaN, infinite, negative or huge seconds are a usage error naming it."""
    if value is not None and not 0 <= value <= MAX_SECONDS:   # false for NaN too
        flag = param.opts[0]
        raise UsageError(f"{flag} must be a number of seconds from 0 to {MAX_SECONDS}",
                         what=f"{flag} SECONDS: a finite number from 0 to {MAX_SECONDS} (30 days)",
                         why=f"{flag} is {value}", how=f"give {flag} a number of seconds, e.g. {flag} 5")
    return value


Topic = Annotated[str, typer.Argument(help="ROS 2 topic, e.g. /indy/joint_states.")]
Timeout = Annotated[float, typer.Option("--timeout", callback=_seconds,
                                        help="Seconds to wait for a publisher of the topic.")]


class Reliability(StrEnum):
    """`--qos-reliability` choices."""

    best_effort = "best_effort"
    reliable = "reliable"


@app.command("list")
def list_topics(
    show_types: Annotated[bool, typer.Option("--show-types", "-t", help="Print each topic's type.")] = False,
    timeout: Annotated[float, typer.Option("--timeout", callback=_seconds, help="Seconds of discovery.")] = 1.5,
    include_hidden: Annotated[bool, typer.Option("--include-hidden-topics", help="Also list topics with a "
                                                 "token starting with '_' (e.g. actions' status).")] = False,
) -> None:
    """List the ROS 2 topics that publishers or subscriptions on the domain announce."""
    from plem.middleware.graph import Graph
    from plem.middleware.node import Node

    node = Node()
    graph = Graph(node)
    graph.discover(timeout)
    topics = graph.topics()
    if not topics:
        print_warnings([f"no ROS 2 topics seen within {timeout} s ({node.settings.describe()})"])
    for name, info in topics.items():
        if include_hidden or not any(token.startswith("_") for token in name.split("/")):
            typer.echo(f"{name} [{', '.join(info.types)}]" if show_types else name)


def _no_publisher(name: str, node: Node, timeout: float, seen: list[str]) -> PlemError:
    listed = ", ".join(seen[:10]) + (", ..." if len(seen) > 10 else "") if seen else "none"
    return PlemError(f"no publisher of {name} on ROS_DOMAIN_ID={node.domain_id}",
                     what=f"a ROS 2 node or plem robot publishing {name}",
                     why=f"none announced itself within {timeout} s ({node.settings.describe()}); "
                         f"topics with publishers: {listed}",
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
    from plem.middleware import names
    from plem.middleware.graph import Graph
    from plem.middleware.node import Node

    name = names.check_name(topic if topic.startswith("/") else f"/{topic}")
    node = Node()
    graph = Graph(node)
    graph.discover(timeout, until=lambda seen: name in seen.topics() and bool(seen.topics()[name].publishers))
    topics = graph.topics()
    info = topics.get(name)
    if info is None or not info.publishers:
        raise _no_publisher(name, node, timeout, [seen for seen, other in topics.items() if other.publishers])
    published = sorted({publisher.type_name for publisher in info.publishers})
    if len(published) > 1:
        raise PlemError(f"{name} is published with several types", what="one type per topic",
                        why=f"publishers announce {', '.join(published)}",
                        how="stop the publishers of the wrong type, or rename one of the topics")
    ros_type = published[0]
    if not node.library.known(ros_type):
        raise _unknown_type(name, ros_type, node)
    if reliable and not all(publisher.profile.reliable for publisher in info.publishers):
        print_warnings([f"a best-effort publisher of {name} does not serve a reliable reader; "
                        "drop --qos-reliability reliable to hear it"])
    return node, node.subscription(name, ros_type, info.reader_profile(depth, reliable))


def _plain(value: Any, no_arr: bool) -> Any:
    """A message as dicts, lists and scalars in field order; with `no_arr`, sequences as their length."""
    if dataclasses.is_dataclass(value):
        return {field.name: _plain(getattr(value, field.name), no_arr) for field in dataclasses.fields(value)}
    if isinstance(value, (list, tuple, bytes)):
        return f"<sequence length: {len(value)}>" if no_arr else [_plain(item, no_arr) for item in value]
    return value


def _yaml(message: Any, no_arr: bool) -> str:
    import yaml

    return yaml.safe_dump(_plain(message, no_arr), sort_keys=False, default_flow_style=False, allow_unicode=True,
                          width=sys.maxsize)


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
                typer.echo(_yaml(message, no_arr) + "---")
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
        "--duration", callback=_seconds, help="Stop after S seconds (default: run until Ctrl-C).",
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
