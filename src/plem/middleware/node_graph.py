"""The ROS nodes a bridge presents, announced as rmw announces nodes, and their /rosout log.

ROS 2 tools learn which nodes exist, and which readers and writers belong to each, from the
`ros_discovery_info` topic: every participant publishes its nodes there with the GIDs of their endpoints
(rmw_dds_common's ParticipantEntitiesInfo, ROS 2 Jazzy layout: 16-byte GIDs, which are the DDS GUIDs).
plem's bridge is one DDS participant that presents the nodes a ros2_control robot has, so `ros2 node list`,
`ros2 node info` and rqt find them. Every node also has its own /rosout writer (rcl_interfaces/msg/Log), where
the bridge's warnings and refusals appear under the node's logger name.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass, field
from typing import Any, Protocol

from plem.middleware.node import Entities, Node, Publisher
from plem.middleware.qos import QosProfile

#: rmw's graph topic: no `rt/` prefix, the newest announcement reaches late joiners.
DISCOVERY_TOPIC = "ros_discovery_info"
DISCOVERY_TYPE = "rmw_dds_common/msg/ParticipantEntitiesInfo"
DISCOVERY_QOS = QosProfile(reliable=True, depth=1, transient_local=True)
#: rcl's /rosout profile (without its 10 s lifespan, which Cyclone's Python binding does not set here).
ROSOUT_QOS = QosProfile(reliable=True, depth=1000, transient_local=True)
#: rcl_interfaces/msg/Log levels by Python logging level.
LEVELS = {logging.DEBUG: 10, logging.INFO: 20, logging.WARNING: 30, logging.ERROR: 40, logging.CRITICAL: 50}


class HasEntities(Protocol):
    """A publisher, subscription, service server or action server."""

    def entities(self) -> Entities:
        """Its DDS readers and writers."""
        ...


@dataclass
class GraphNode:
    """One ROS node: its namespace, name, its own /rosout writer and the endpoints that belong to it."""

    namespace: str
    name: str
    rosout: Publisher[Any]
    endpoints: list[HasEntities] = field(default_factory=list)

    @property
    def logger(self) -> str:
        """The node's logger name as rcl forms it: namespace and name joined by dots
        (`indy.joint_trajectory_controller`)."""
        return ".".join([*self.namespace.strip("/").split("/"), self.name]).strip(".")


class NodeGraph:
    """The nodes of one participant: announced on ros_discovery_info, each with a share of /rosout."""

    def __init__(self, node: Node) -> None:
        self.node = node
        library = node.library
        self._announcer = node.publisher_of(DISCOVERY_TOPIC, library.message(DISCOVERY_TYPE), DISCOVERY_QOS,
                                            node.type_user_data(DISCOVERY_TYPE))
        self.nodes: list[GraphNode] = []

    def add(self, namespace: str, name: str, *endpoints: HasEntities) -> GraphNode:
        """A node with `endpoints` (more may be added to its list before `announce`) and a /rosout writer of its
        own, as every rcl node has."""
        rosout = self.node.publisher("/rosout", "rcl_interfaces/msg/Log", ROSOUT_QOS)
        graph_node = GraphNode(namespace, name, rosout, [rosout, *endpoints])
        self.nodes.append(graph_node)
        return graph_node

    def announce(self) -> None:
        """Publish the participant's nodes with their endpoints' GIDs (again after any change)."""
        new = self.node.library.new

        def gid(guid: Any) -> Any:
            return new("rmw_dds_common/msg/Gid", data=list(guid.bytes))

        infos = []
        for graph_node in self.nodes:
            total = Entities()
            for endpoint in graph_node.endpoints:
                total = total + endpoint.entities()
            infos.append(new("rmw_dds_common/msg/NodeEntitiesInfo", node_namespace=graph_node.namespace,
                             node_name=graph_node.name, reader_gid_seq=[gid(g) for g in total.readers],
                             writer_gid_seq=[gid(g) for g in total.writers]))
        self._announcer.publish(new(DISCOVERY_TYPE, gid=gid(self.node.participant.guid), node_entities_info_seq=infos))

    def log(self, graph_node: GraphNode, level: int, message: str) -> None:
        """One rcl_interfaces/msg/Log on /rosout under the node's logger name."""
        graph_node.rosout.publish(self.node.library.new(
            "rcl_interfaces/msg/Log", stamp=self.node.library.stamp(), level=LEVELS.get(level, 30),
            name=graph_node.logger, msg=message, file="", function="", line=0))


class RosoutHandler(logging.Handler):
    """Sends a Python logger's records to /rosout under one node's name (WARNING and above by default)."""

    def __init__(self, graph: NodeGraph, graph_node: GraphNode, level: int = logging.WARNING) -> None:
        super().__init__(level)
        self.graph = graph
        self.graph_node = graph_node
        self._pid = os.getpid()

    def emit(self, record: logging.LogRecord) -> None:
        """Publish the record's message; a record that cannot be sent is dropped, never raised."""
        if os.getpid() != self._pid:
            return
        try:
            self.graph.log(self.graph_node, record.levelno, record.getMessage())
        except Exception:  # noqa: BLE001 - logging must never take the bridge down
            self.handleError(record)
