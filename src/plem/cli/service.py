"""`plem service list|call`: list and call ROS 2 services on the DDS domain without a ROS install.

A service is the DDS topic pair `rq/<name>Request` / `rr/<name>Reply` (see plem.middleware.names); its type
is the request's DDS type without `_Request`. Discovery settings come from ROS_DOMAIN_ID and
ROS_AUTOMATIC_DISCOVERY_RANGE, as for `ros2 service`.

Many ROS 2 replies carry no reason (controller_manager_msgs/srv/SetHardwareComponentState answers `ok: false`
alone); the server logs it on /rosout, as ros2_control does. `plem service call` prints the warnings and errors
that the server's node logs on /rosout while it answers, after the response.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Annotated, Any

import typer

from plem.cli.output import print_warnings
from plem.cli.ros_arguments import LIST_TIMEOUT_S, interface_type, not_found, ros_name, seconds, wrong_type
from plem.cli.ros_messages import message_fields, message_from_yaml, message_repr, to_yaml
from plem.errors import PlemError

if TYPE_CHECKING:
    from plem.middleware.graph import Graph
    from plem.middleware.node import Node, Subscription

app = typer.Typer(help="List and call ROS 2 services on the DDS domain (no ROS install needed).",
                  no_args_is_help=True)

#: How often a command waiting for its client to match checks again.
MATCH_POLL_S = 0.01
#: How long a failed reply waits for the server's log line on /rosout (published just before the reply).
REASON_WAIT_S = 0.5
#: rcl_interfaces/msg/Log levels by number: the ones printed after a response (WARN and above).
LOG_LEVELS = {30: "WARN", 40: "ERROR", 50: "FATAL"}


@app.command("list")
def list_services(
    show_types: Annotated[bool, typer.Option("--show-types", "-t", help="Print each service's type.")] = False,
    timeout: Annotated[float, typer.Option("--timeout", callback=seconds, help="Seconds of discovery.")]
    = LIST_TIMEOUT_S,
    include_hidden: Annotated[bool, typer.Option("--include-hidden-services", help="Also list services with a "
                                                 "token starting with '_' (e.g. actions' send_goal).")] = False,
) -> None:
    """List the ROS 2 services that servers or clients on the domain announce."""
    from plem.middleware.graph import Graph, hidden
    from plem.middleware.node import Node

    node = Node()
    graph = Graph(node)
    graph.discover(timeout)
    services = graph.services()
    if not services:
        print_warnings([f"no ROS 2 services seen within {timeout} s ({node.settings.describe()})"])
    for name, info in services.items():
        if include_hidden or not hidden(name):
            typer.echo(f"{name} [{', '.join(info.types)}]" if show_types else name)


def wait_for_server(graph: Graph, node: Node, kind: str, name: str, ros_type: str, timeout: float,
                    ready: Callable[[], bool]) -> None:
    """Wait up to `timeout` for a server of the service or action `name` and for `ready()` (the client matched).

    No server is an error that lists the servers seen; a server of another type is an error that names it.
    """
    from plem.middleware.graph import SEND_GOAL_TYPE

    deadline = time.monotonic() + timeout

    def servers(seen: Graph) -> dict[str, list[str]]:
        """Name → the types its servers announce, of every service (or action) with a server."""
        table = seen.services() if kind == "service" else seen.actions()
        suffix = SEND_GOAL_TYPE if kind == "action" else ""
        return {name: sorted({server.service_type.removesuffix(suffix) for server in info.servers})
                for name, info in table.items() if info.servers}

    graph.discover(timeout, until=lambda seen: name in servers(seen))
    served = servers(graph)
    if name not in served:
        raise not_found(kind, name, node, timeout, served)
    if ros_type not in served[name]:
        raise wrong_type(kind, name, ros_type, served[name])
    while not ready():
        if time.monotonic() >= deadline:
            raise PlemError(f"the {kind} {name} did not connect within {timeout} s",
                            what=f"the {kind}'s server matched with this client",
                            why=f"a server of {name} ({ros_type}) is on the domain, but its endpoints did not all "
                                "match this client's in time",
                            how="wait longer with --timeout; if it persists, check the server's QoS with "
                                "`plem topic info -v` and the type hash its endpoints announce")
        time.sleep(MATCH_POLL_S)


@app.command("call")
def call(
    service: Annotated[str, typer.Argument(help="ROS 2 service, e.g. /indy/controller_manager/list_controllers.")],
    service_type: Annotated[str, typer.Argument(metavar="TYPE", help="Service type, e.g. "
                                                "controller_manager_msgs/srv/ListControllers.")],
    values: Annotated[str, typer.Argument(help="The request's fields as a YAML mapping, e.g. \"{names: [a]}\"; "
                                          "fields left out are zero.")] = "{}",
    timeout: Annotated[float, typer.Option("--timeout", callback=seconds, help="Seconds to wait for the server, "
                                           "and again for its response.")] = 5.0,
) -> None:
    """Send one request and print the response as YAML (like `ros2 service call`), then the warnings the server's
    node logged on /rosout meanwhile (the reason of a reply such as `ok: false`)."""
    from plem.middleware.graph import Graph
    from plem.middleware.node import Node
    from plem.middleware.types import library

    name = ros_name(service, "service")
    interfaces = library()
    ros_type = interface_type(interfaces, service_type, "srv")
    request = message_from_yaml(interfaces, f"{ros_type}_Request", values, "VALUES")
    node = Node(interfaces=interfaces)
    client = node.client(name, ros_type)   # created first: it matches the server while discovery runs
    rosout = _rosout(node)
    typer.echo("waiting for service to become available...")
    wait_for_server(Graph(node), node, "service", name, ros_type, timeout, lambda: client.ready)
    typer.echo(f"requester: making request: {message_repr(request)}\n")
    try:
        response = client.call(timeout, **message_fields(request))
    except TimeoutError:
        raise PlemError(f"no response from {name} within {timeout} s", what="the server's response to the request",
                        why=f"the server of {name} took the request but did not answer in time",
                        how="wait longer with --timeout, or check the server's log") from None
    typer.echo("response:")
    typer.echo(to_yaml(response) + "\n")
    for line in _server_log(rosout, name, failed=_failed(response)):
        typer.echo(line)


def _rosout(node: Node) -> Subscription[Any]:
    """A /rosout reader that hears only what is logged from now on (volatile: no earlier history)."""
    from plem.middleware.qos import QosProfile

    return node.subscription("/rosout", "rcl_interfaces/msg/Log", QosProfile(reliable=True, depth=100))


def _failed(response: Any) -> bool:
    """Whether a response says it failed in its own words: an `ok` or `success` field that is false."""
    return any(getattr(response, flag, True) is False for flag in ("ok", "success"))


def _server_log(rosout: Subscription[Any], service: str, failed: bool) -> list[str]:
    """The WARN and ERROR lines the service's node logged during the call (for a failed reply, waiting briefly
    for them), as `/rosout [node] LEVEL: message`."""
    logger = service.rsplit("/", 1)[0].strip("/").replace("/", ".")   # rcl's logger name of the server's node
    deadline = time.monotonic() + (REASON_WAIT_S if failed else 0.0)
    lines: list[str] = []
    while True:
        lines += [f"/rosout [{entry.name}] {LOG_LEVELS[entry.level]}: {entry.msg}" for entry in rosout.take()
                  if entry.name == logger and entry.level in LOG_LEVELS]
        if lines or time.monotonic() >= deadline:
            return lines
        time.sleep(MATCH_POLL_S)
