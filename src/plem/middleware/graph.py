"""The ROS 2 graph seen from DDS discovery: topics, services, actions and nodes, with their endpoints' QoS.

Cyclone DDS reports every writer and reader it discovers on the built-in DCPSPublication and
DCPSSubscription topics; reading them for a short window shows what `ros2 topic list` shows, with no
ROS install. Only DDS topics that follow the ROS 2 mapping count: `rt/...` are topics, the pairs
`rq/...Request` / `rr/...Reply` are services, and an action is the services under `<action>/_action/`.

Nodes are not a DDS concept: each participant announces its nodes on `ros_discovery_info` with the GIDs
of their readers and writers (rmw_dds_common's ParticipantEntitiesInfo, ROS 2 Jazzy layout). A GID's 16
bytes are the DDS GUID of the endpoint, so matching them against discovery tells which node owns which
endpoint. A graph reads that topic only when asked to (`nodes=True`).
"""

from __future__ import annotations

import logging
import time
import uuid
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any

from cyclonedds.builtin import (
    BuiltinDataReader,
    BuiltinTopicDcpsParticipant,
    BuiltinTopicDcpsPublication,
    BuiltinTopicDcpsSubscription,
)
from cyclonedds.core import InstanceState, ReadCondition, SampleState, ViewState, WaitSet
from cyclonedds.qos import Policy, Qos
from cyclonedds.util import duration

from plem.middleware import names
from plem.middleware.node import Node, Subscription
from plem.middleware.node_graph import DISCOVERY_TOPIC, DISCOVERY_TYPE
from plem.middleware.qos import QosProfile

_ANY_SAMPLE = SampleState.Any | ViewState.Any | InstanceState.Any
#: At most this many samples in a row that the binding cannot convert are skipped in one pass (then the next
#: pass goes on): a bound, so a reader that fails for another reason cannot spin.
MAX_UNCONVERTIBLE = 64
_log = logging.getLogger("plem.dds")
_LATE_JOINER_DURABILITY = (Policy.Durability.TransientLocal, Policy.Durability.Transient,
                           Policy.Durability.Persistent)
#: How ROS 2 tools name an endpoint that no node on ros_discovery_info claims.
UNKNOWN_NODE_NAME = "_NODE_NAME_UNKNOWN_"
UNKNOWN_NODE_NAMESPACE = "_NODE_NAMESPACE_UNKNOWN_"
#: Reader of ros_discovery_info: the topic has no key, so it keeps room for the latest announcement of many
#: participants (each writer offers its last one, transient local).
NODES_QOS = QosProfile(reliable=True, depth=100, transient_local=True)
#: The service under an action's name that makes it an action, and the suffix its type gets there.
SEND_GOAL = "/_action/send_goal"
SEND_GOAL_TYPE = "_SendGoal"
_SERVICE_PARTS = {"service request": "_Request", "service reply": "_Response"}


@dataclass(frozen=True)
class Endpoint:
    """One writer or reader of a ROS 2 topic or service, as discovery announced it.

    `name` is the topic or service name; `kind` says which (`topic`, `service request` or `service reply`, as
    `names.ros_topic` calls them). `type_name` is the ROS type, or the DDS type name when it does not follow the
    ROS 2 mapping. `gid` is the endpoint's DDS GUID, the GID a node lists it under; `participant` the GUID of its
    participant. `type_hash` is the RIHS01 hash the endpoint announces, if any.
    """

    name: str
    type_name: str
    publisher: bool
    profile: QosProfile
    kind: str = "topic"
    gid: bytes = b""
    participant: bytes = b""
    type_hash: str = ""

    @property
    def service_type(self) -> str:
        """For a service's request or reply: the service type (`pkg/srv/Name` without `_Request`/`_Response`)."""
        return self.type_name.removesuffix(_SERVICE_PARTS.get(self.kind, ""))

    @property
    def gid_text(self) -> str:
        """The GID as ROS 2 tools print it: bytes in hex, separated by dots."""
        return ".".join(f"{byte:02x}" for byte in self.gid)


@dataclass
class TopicInfo:
    """A ROS 2 topic: its types (ROS names where they follow the mapping), its publishers, its subscriptions."""

    name: str
    types: list[str] = field(default_factory=list)
    publishers: list[Endpoint] = field(default_factory=list)
    subscriptions: list[Endpoint] = field(default_factory=list)

    def reader_profile(self, depth: int, reliable: bool | None = None) -> QosProfile:
        """A reader QoS every publisher seen can serve: reliable and transient local only if all offer it."""
        offered = [publisher.profile for publisher in self.publishers]
        all_reliable = all(profile.reliable for profile in offered)
        all_latched = bool(offered) and all(profile.transient_local for profile in offered)
        return QosProfile(reliable=all_reliable if reliable is None else reliable, depth=depth,
                          transient_local=all_latched)


@dataclass
class ServiceInfo:
    """A ROS 2 service (or action): its types, its servers' request readers and its clients' request writers.

    A service seen only through replies (or a reader without its writer) still counts, with no server or client.
    """

    name: str
    types: list[str] = field(default_factory=list)
    servers: list[Endpoint] = field(default_factory=list)
    clients: list[Endpoint] = field(default_factory=list)


@dataclass(frozen=True)
class NodeInfo:
    """One ROS node as its participant announces it: namespace, name and the GIDs of its readers and writers."""

    namespace: str
    name: str
    participant: bytes
    readers: frozenset[bytes]
    writers: frozenset[bytes]

    @property
    def full_name(self) -> str:
        """The fully qualified name, e.g. `/indy/joint_trajectory_controller`."""
        return f"{self.namespace.rstrip('/')}/{self.name}"

    def owns(self, endpoint: Endpoint) -> bool:
        """Whether the endpoint is one of the node's readers or writers."""
        return endpoint.gid in (self.writers if endpoint.publisher else self.readers)


def _profile(qos: Qos) -> QosProfile:
    """The ROS 2 view of a discovered endpoint's QoS (absent policies take the DDS writer defaults).

    Keep-all history has no depth: it reads as depth 0.
    """
    history = qos[Policy.History]
    return QosProfile(reliable=qos[Policy.Reliability] != Policy.Reliability.BestEffort,
                      depth=getattr(history, "depth", 0),
                      transient_local=qos[Policy.Durability] in _LATE_JOINER_DURABILITY)


def _type_hash(qos: Qos) -> str:
    """The `typehash=` an endpoint announces in its user data (ROS 2 Iron and later), or ''."""
    user_data = qos[Policy.Userdata]
    text = bytes(getattr(user_data, "data", b"")).decode("utf-8", "replace")
    for item in text.split(";"):
        key, _, value = item.partition("=")
        if key.strip() == "typehash":
            return value.strip()
    return ""


def hidden(name: str) -> bool:
    """A name ROS 2 tools hide by default: one of its tokens starts with '_' (e.g. an action's `_action/...`)."""
    return any(token.startswith("_") for token in name.split("/"))


class Graph:
    """Collects the endpoints (and, with `nodes`, the nodes) a node discovers; grouped on request."""

    def __init__(self, node: Node, nodes: bool = False) -> None:
        self._readers = {
            True: BuiltinDataReader(node.participant, BuiltinTopicDcpsPublication),
            False: BuiltinDataReader(node.participant, BuiltinTopicDcpsSubscription),
        }
        self._waitset = WaitSet(node.participant)
        for reader in self._readers.values():
            self._waitset.attach(ReadCondition(reader, _ANY_SAMPLE))
        self._endpoints: dict[uuid.UUID, Endpoint] = {}
        self._announcements: dict[bytes, Any] = {}
        self._participants: BuiltinDataReader | None = None
        self._node_reader: Subscription[Any] | None = None
        if nodes:
            self._participants = BuiltinDataReader(node.participant, BuiltinTopicDcpsParticipant)
            self._node_reader = node.subscription_of(DISCOVERY_TOPIC, node.library.message(DISCOVERY_TYPE), NODES_QOS,
                                                     node.type_user_data(DISCOVERY_TYPE))
            self._waitset.attach(ReadCondition(self._participants, _ANY_SAMPLE))
            self._waitset.attach(self._node_reader.condition)

    def discover(self, window: float, until: Callable[[Graph], bool] | None = None) -> None:
        """Take discovery news for `window` seconds, or until `until(graph)` holds."""
        deadline = time.monotonic() + window
        while True:
            self._take()
            remaining = deadline - time.monotonic()
            if remaining <= 0 or (until is not None and until(self)):
                return
            self._waitset.wait(duration(seconds=remaining))

    def endpoints(self) -> list[Endpoint]:
        """Every endpoint of a ROS 2 topic or service seen, sorted by name."""
        return sorted(self._endpoints.values(), key=lambda endpoint: endpoint.name)

    def topics(self) -> dict[str, TopicInfo]:
        """ROS 2 topic name → its types and endpoints, sorted by name."""
        topics: dict[str, TopicInfo] = {}
        for endpoint in self.endpoints():
            if endpoint.kind != "topic":
                continue
            info = topics.setdefault(endpoint.name, TopicInfo(endpoint.name))
            if endpoint.type_name not in info.types:
                info.types.append(endpoint.type_name)
            (info.publishers if endpoint.publisher else info.subscriptions).append(endpoint)
        return topics

    def services(self) -> dict[str, ServiceInfo]:
        """ROS 2 service name → its types, servers and clients, sorted by name (actions' services included)."""
        services: dict[str, ServiceInfo] = {}
        for endpoint in self.endpoints():
            if endpoint.kind == "topic":
                continue
            info = services.setdefault(endpoint.name, ServiceInfo(endpoint.name))
            if endpoint.service_type not in info.types:
                info.types.append(endpoint.service_type)
            if endpoint.kind == "service request":   # a server reads requests, a client writes them
                (info.clients if endpoint.publisher else info.servers).append(endpoint)
        return services

    def actions(self) -> dict[str, ServiceInfo]:
        """ROS 2 action name → its types, servers and clients (those of its send_goal service), sorted by name."""
        actions: dict[str, ServiceInfo] = {}
        for name, service in self.services().items():
            if name.endswith(SEND_GOAL):
                types = [ros_type.removesuffix(SEND_GOAL_TYPE) for ros_type in service.types]
                actions[name.removesuffix(SEND_GOAL)] = ServiceInfo(name.removesuffix(SEND_GOAL), types,
                                                                   service.servers, service.clients)
        return actions

    def nodes(self) -> list[NodeInfo]:
        """Every node the participants still on the domain announce, sorted by full name (empty without `nodes`)."""
        found = []
        for participant, info in self._announcements.items():
            for entities in info.node_entities_info_seq:
                found.append(NodeInfo(entities.node_namespace, entities.node_name, participant,
                                      frozenset(_gid(gid) for gid in entities.reader_gid_seq),
                                      frozenset(_gid(gid) for gid in entities.writer_gid_seq)))
        return sorted(found, key=lambda node: (node.full_name, node.participant))

    def node_of(self, endpoint: Endpoint, nodes: Iterable[NodeInfo] | None = None) -> NodeInfo | None:
        """The node that lists the endpoint among its own, or None when no node claims it."""
        return next((node for node in (self.nodes() if nodes is None else nodes) if node.owns(endpoint)), None)

    def _take(self) -> None:
        for publisher, reader in self._readers.items():
            for sample in _take_each(reader):
                self._update(sample, publisher)
        if self._participants is not None and self._node_reader is not None:
            for sample in _take_each(self._participants):
                if not sample.sample_info.valid_data:   # the participant left: its nodes with it
                    self._announcements.pop(sample.key.bytes, None)
            for info in self._node_reader.take(1024):
                self._announcements[_gid(info.gid)] = info

    def _update(self, sample: Any, publisher: bool) -> None:
        # An endpoint that went away comes back as an invalid sample without topic or type name.
        if not sample.sample_info.valid_data:
            self._endpoints.pop(sample.key, None)
            return
        ros_name = names.ros_topic(sample.topic_name)
        if ros_name is None:
            return
        type_name = names.ros_type_name(sample.type_name) or sample.type_name
        self._endpoints[sample.key] = Endpoint(ros_name[1], type_name, publisher, _profile(sample.qos), ros_name[0],
                                               sample.key.bytes, sample.participant_key.bytes, _type_hash(sample.qos))


def _take_each(reader: BuiltinDataReader) -> Iterator[Any]:
    """The discovery samples waiting in a built-in reader, taken one at a time.

    The cyclonedds binding converts a whole batch at once and raises a bare Exception ("Callfunc endpoint
    constructor errored") when it cannot convert one endpoint of it, losing the batch: taken one by one, only
    that endpoint is skipped and every other one is still seen, so a peer the binding cannot describe never
    ends a command.
    """
    skipped = 0
    while skipped < MAX_UNCONVERTIBLE:
        try:
            samples = reader.take(N=1)
        except Exception as error:  # noqa: BLE001 - the binding raises bare Exception for one sample; it is consumed
            skipped += 1
            _log.debug("a discovery sample the cyclonedds binding cannot convert was skipped: %s", error)
            continue
        if not samples:
            return
        yield samples[0]


def _gid(gid: Any) -> bytes:
    """The 16 bytes of an rmw_dds_common/Gid."""
    return bytes(gid.data)
