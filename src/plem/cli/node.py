"""`plem node list|info`: the ROS 2 nodes on the DDS domain and their endpoints, without a ROS install.

Nodes come from `ros_discovery_info`, where every participant announces its nodes with the GIDs of their
readers and writers; matching those against DDS discovery gives each node's topics, services and actions,
as `ros2 node info` shows them. Discovery settings come from ROS_DOMAIN_ID and ROS_AUTOMATIC_DISCOVERY_RANGE.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated

import typer

from plem.cli.output import print_warnings
from plem.cli.ros_arguments import LIST_TIMEOUT_S, not_found, ros_name, seconds

if TYPE_CHECKING:
    from plem.middleware.graph import Endpoint, Graph, NodeInfo

app = typer.Typer(help="List the ROS 2 nodes on the DDS domain and show their endpoints (no ROS install needed).",
                  no_args_is_help=True)

ListTimeout = Annotated[float, typer.Option("--timeout", callback=seconds, help="Seconds of discovery.")]


@app.command("list")
def list_nodes(
    timeout: ListTimeout = LIST_TIMEOUT_S,
    show_all: Annotated[bool, typer.Option("--all", "-a", help="Also list hidden nodes (a name starting with "
                                           "'_').")] = False,
    count: Annotated[bool, typer.Option("--count-nodes", "-c", help="Print only the number of nodes.")] = False,
) -> None:
    """List the fully qualified names of the nodes every participant on the domain announces, sorted."""
    from plem.middleware.graph import Graph
    from plem.middleware.node import Node

    node = Node()
    graph = Graph(node, nodes=True)
    graph.discover(timeout)
    names = [found.full_name for found in graph.nodes() if show_all or not found.name.startswith("_")]
    if not names:
        print_warnings([f"no ROS 2 nodes announced within {timeout} s ({node.settings.describe()})"])
    if count:
        typer.echo(str(len(names)))
        return
    if len(set(names)) < len(names):
        print_warnings(["Be aware that there are nodes in the graph that share an exact name, which can have "
                        "unintended side effects."])
    for name in names:
        typer.echo(name)


def _section(title: str, entries: dict[str, list[str]]) -> list[str]:
    """One section of `ros2 node info`: its title, then `name: type` lines (an empty line when there are none)."""
    lines = [f"    {name}: {', '.join(types)}" for name, types in sorted(entries.items())]
    return [f"  {title}:", *(lines or [""])]


def _add(entries: dict[str, list[str]], name: str, ros_type: str) -> None:
    types = entries.setdefault(name, [])
    if ros_type not in types:
        types.append(ros_type)


def _node_text(name: str, owned: list[Endpoint], include_hidden: bool) -> str:
    """The node's endpoints grouped as `ros2 node info` prints them; actions in place of their `_action/` parts."""
    from plem.middleware.graph import SEND_GOAL, SEND_GOAL_TYPE, hidden

    sections: dict[str, dict[str, list[str]]] = {title: {} for title in (
        "Subscribers", "Publishers", "Service Servers", "Service Clients", "Action Servers", "Action Clients")}
    for endpoint in owned:
        if endpoint.kind == "topic":
            title, endpoint_name, ros_type = ("Publishers" if endpoint.publisher else "Subscribers"), endpoint.name, \
                endpoint.type_name
        elif endpoint.kind == "service request":   # a server reads requests, a client writes them
            title, endpoint_name, ros_type = ("Service Clients" if endpoint.publisher else "Service Servers"), \
                endpoint.name, endpoint.service_type
            if endpoint.name.endswith(SEND_GOAL):
                _add(sections[title.replace("Service", "Action")], endpoint.name.removesuffix(SEND_GOAL),
                     ros_type.removesuffix(SEND_GOAL_TYPE))
        else:
            continue   # a reply's endpoint says nothing its request's does not
        if include_hidden or not hidden(endpoint_name):
            _add(sections[title], endpoint_name, ros_type)
    lines = [name]
    for title, entries in sections.items():
        lines += _section(title, entries)
    return "\n".join(lines)


@app.command("info")
def info(
    node_name: Annotated[str, typer.Argument(metavar="NODE", help="Fully qualified node name, e.g. "
                                             "/indy/joint_trajectory_controller.")],
    timeout: ListTimeout = LIST_TIMEOUT_S,
    include_hidden: Annotated[bool, typer.Option("--include-hidden", help="Also list hidden topics and services "
                                                 "(e.g. actions' `_action/` parts).")] = False,
) -> None:
    """Print the node's subscribers, publishers, service servers and clients, action servers and clients."""
    from plem.middleware.graph import Graph
    from plem.middleware.node import Node

    name = ros_name(node_name, "node")
    node = Node()
    graph = Graph(node, nodes=True)

    def named(seen: Graph) -> list[NodeInfo]:
        return [found for found in seen.nodes() if found.full_name == name]

    def complete(seen: Graph) -> bool:   # the node is announced and every endpoint it names is discovered
        nodes = named(seen)
        known = {endpoint.gid for endpoint in seen.endpoints()}
        return bool(nodes) and all(found.readers | found.writers <= known for found in nodes)

    graph.discover(timeout, until=complete)
    nodes = named(graph)
    if not nodes:
        raise not_found("node", name, node, timeout, {found.full_name for found in graph.nodes()})
    if len(nodes) > 1:
        print_warnings([f"There are {len(nodes)} nodes in the graph with the exact name \"{name}\". You are seeing "
                        "information about only one of them."])
    owned = [endpoint for endpoint in graph.endpoints() if nodes[0].owns(endpoint)]
    typer.echo(_node_text(name, owned, include_hidden))

