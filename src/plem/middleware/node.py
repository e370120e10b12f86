"""A DDS participant that speaks ROS 2: publishers, subscriptions, service servers and clients.

Topics, services and types are named by the ROS 2 rules (see `names`), endpoints announce their type
hash the way rmw does for ROS 2 Iron and later, and requests and replies carry rmw_cyclonedds's
request header, so ROS 2 nodes on the same domain talk to plem as to any other node.
"""

from __future__ import annotations

import itertools
import threading
import time
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any, Generic, TypeVar
from uuid import UUID

from cyclonedds._clayer import ddspy_take, ddspy_write
from cyclonedds.core import DDSException, InstanceState, ReadCondition, SampleState, ViewState, WaitSet
from cyclonedds.domain import Domain, DomainParticipant
from cyclonedds.pub import DataWriter
from cyclonedds.qos import Policy, Qos
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration

from plem.errors import ConfigError
from plem.middleware import names
from plem.middleware.discovery import DiscoverySettings
from plem.middleware.qos import SERVICES, QosProfile
from plem.middleware.samples import SampleDrops, undecodable
from plem.middleware.types import InterfaceLibrary, library

M = TypeVar("M")
_ANY_SAMPLE = SampleState.Any | ViewState.Any | InstanceState.Any
#: How long a reply waits for its client's reply reader to be matched.
REPLY_WAIT_S = 5.0
#: What rmw_cyclonedds announces for a participant; ROS 2 graph tools list only participants that carry it.
PARTICIPANT_USER_DATA = b"enclave=/;"


@dataclass(frozen=True)
class Entities:
    """The GUIDs of DDS readers and writers that one ROS endpoint (or a node's set of them) consists of."""

    readers: tuple[UUID, ...] = ()
    writers: tuple[UUID, ...] = ()

    def __add__(self, other: Entities) -> Entities:
        return Entities(self.readers + other.readers, self.writers + other.writers)


class Publisher(Generic[M]):
    """Writes messages of one type on one ROS 2 topic."""

    def __init__(self, writer: DataWriter[Any], message: type[M], node: Node) -> None:
        self.node = node  # the participant must outlive its endpoints
        self.writer = writer
        self.message = message
        self.published = 0
        self.dropped = 0

    def publish(self, message: M) -> bool:
        """Write one message; a write refused by DDS (history full past MAX_BLOCKING) is counted, not raised."""
        try:
            self.writer.write(message)
        except DDSException:
            return self._count(False)
        return self._count(True)

    def publish_cdr(self, data: bytes) -> bool:
        """Write a message already in CDR (with its encapsulation), as a fixed-layout encoder makes it."""
        padded = data.ljust((len(data) + 3) & ~3, b"\0")   # Cyclone takes whole 4-byte words, as write() pads
        return self._count(ddspy_write(self.writer._ref, padded) >= 0)

    def _count(self, written: bool) -> bool:
        if written:
            self.published += 1
        else:
            self.dropped += 1
        return written

    def entities(self) -> Entities:
        """The DDS endpoints behind it, as a ROS node lists them."""
        return Entities(writers=(self.writer.guid,))

    @property
    def subscribers(self) -> int:
        """Readers currently matched with this publisher."""
        status = self.writer.get_publication_matched_status()  # type: ignore[no-untyped-call]  # cyclonedds: untyped
        return int(status.current_count)


class Subscription(Generic[M]):
    """Takes messages of one type from one ROS 2 topic."""

    def __init__(self, reader: DataReader[Any], message: type[M], node: Node, dds_topic: str) -> None:
        self.node = node  # the participant must outlive its endpoints
        self.reader = reader
        self.message = message
        self.condition = ReadCondition(reader, _ANY_SAMPLE)
        kind, name = names.ros_topic(dds_topic) or ("DDS topic", dds_topic)
        self.name = f"{kind} {name}"
        #: The largest serialized sample decoded; a larger one is dropped before it costs any Python work.
        self.max_bytes: int | None = None
        self._drops = SampleDrops(self.name)

    def take(self, limit: int = 256) -> list[M]:
        """Every message waiting (up to `limit`), oldest first, decoded one by one: a sample too large or that
        does not decode is dropped with a warning, and the others are still returned."""
        taken = ddspy_take(self.reader._ref, _ANY_SAMPLE, limit)
        if isinstance(taken, int):
            raise DDSException(taken, f"Occurred while taking data from the {self.name}")
        messages: list[M] = []
        for data, info in taken:
            if not info.valid_data:
                continue
            if self.max_bytes is not None and len(data) > self.max_bytes:
                self._drops.drop(f"its {len(data):,} bytes exceed the {self.max_bytes:,} this endpoint accepts")
                continue
            try:
                message = self.message.deserialize(data)  # type: ignore[attr-defined]  # an IdlStruct class
            except Exception as error:  # noqa: BLE001 - any malformed sample is the sender's fault, never ours
                self._drops.drop(undecodable(error))
                continue
            message.sample_info = info
            messages.append(message)
        return messages

    def entities(self) -> Entities:
        """The DDS endpoints behind it, as a ROS node lists them."""
        return Entities(readers=(self.reader.guid,))

    @property
    def publishers(self) -> int:
        """Writers currently matched with this subscription."""
        status = self.reader.get_subscription_matched_status()  # type: ignore[no-untyped-call]  # cyclonedds: untyped
        return int(status.current_count)


def _service_part(node: Node, service: str, ros_type: str, part: str) -> tuple[str, type, QosProfile, bytes]:
    """The DDS topic, struct, QoS and user data of a service's "Request" or "Response" side."""
    topic = names.request_topic(service) if part == "Request" else names.reply_topic(service)
    return topic, node.library.service_part(f"{ros_type}_{part}"), SERVICES, node.type_user_data(f"{ros_type}_{part}")


class ServiceServer:
    """Takes requests of one service and sends each reply back to the client that asked.

    A reply waits until the client's reply reader is matched (as rmw_cyclonedds does): the reply
    topic keeps no history, so a reply written before that would be lost. Replies whose client does not
    show up within REPLY_WAIT_S are dropped.
    """

    def __init__(self, node: Node, service: str, ros_type: str) -> None:
        self.requests = node.subscription_of(*_service_part(node, service, ros_type, "Request"))
        self._replies = node.publisher_of(*_service_part(node, service, ros_type, "Response"))
        self._pending: list[tuple[float, UUID | None, Any]] = []

    def take(self) -> list[Any]:
        """Waiting requests; each keeps rmw's header (`rmw_guid`, `rmw_seq`) for its reply."""
        return self.requests.take()

    def entities(self) -> Entities:
        """The DDS endpoints behind it: the request reader and the reply writer."""
        return self.requests.entities() + self._replies.entities()

    def reply(self, request: Any, /, **fields: Any) -> None:
        """Answer `request`, now or (see the class) as soon as its client can receive the answer.

        `fields` are the response's fields, any names its type has (`request` is positional only)."""
        message = self._replies.message(**{**fields, "rmw_guid": request.rmw_guid, "rmw_seq": request.rmw_seq})
        client = _participant_of(self.requests.reader, request.sample_info.publication_handle)
        self._pending.append((time.monotonic() + REPLY_WAIT_S, client, message))
        self.flush()

    def flush(self) -> None:
        """Send the replies whose clients are matched by now; drop those that waited too long."""
        if not self._pending:
            return
        try:
            writer = self._replies.writer
            matched = {data.participant_key for handle in writer.get_matched_subscriptions()
                       if (data := writer.get_matched_subscription_data(handle)) is not None}
        except (IndexError, DDSException):  # a match changed while listing them: try again on the next call
            return
        now = time.monotonic()
        waiting: list[tuple[float, UUID | None, Any]] = []
        for deadline, client, message in self._pending:
            if client is None or client in matched:
                self._replies.publish(message)
            elif now < deadline:
                waiting.append((deadline, client, message))
        self._pending = waiting


def _participant_of(reader: DataReader[Any], publication_handle: int) -> UUID | None:
    """The participant of the writer that sent a sample, or None when it is already gone."""
    try:
        data = reader.get_matched_publication_data(publication_handle)
    except (IndexError, DDSException):
        return None
    return None if data is None else data.participant_key


class ServiceClient:
    """Sends requests of one service and picks out the replies addressed to it."""

    def __init__(self, node: Node, service: str, ros_type: str) -> None:
        self._requests = node.publisher_of(*_service_part(node, service, ros_type, "Request"))
        self._replies = node.subscription_of(*_service_part(node, service, ros_type, "Response"))
        self.guid = self._requests.writer.instance_handle & 0xFFFF_FFFF_FFFF_FFFF  # rmw sends it unsigned
        self._sequence = itertools.count(1)
        self._waiting: dict[int, Any] = {}
        self._lock = threading.Lock()

    @property
    def ready(self) -> bool:
        """The server's request reader and reply writer are both matched."""
        return self._requests.subscribers > 0 and self._replies.publishers > 0

    def call(self, timeout: float, /, **fields: Any) -> Any:
        """Send one request and wait for its reply; TimeoutError when none arrives in time.

        `fields` are the request's fields, any names its type has: `timeout` is positional only, so a request
        with a `timeout` field of its own (controller_manager_msgs/srv/SwitchController) passes it on."""
        sequence = next(self._sequence)
        self._requests.publish(self._requests.message(**{**fields, "rmw_guid": self.guid, "rmw_seq": sequence}))
        waitset = WaitSet(self._replies.node.participant)
        waitset.attach(self._replies.condition)
        deadline = time.monotonic() + timeout
        while True:
            with self._lock:
                for reply in self._replies.take():
                    if reply.rmw_guid == self.guid:
                        self._waiting[reply.rmw_seq] = reply
                if sequence in self._waiting:
                    return self._waiting.pop(sequence)
            remaining = deadline - time.monotonic()
            if remaining <= 0 or waitset.wait(duration(seconds=remaining)) == 0:
                raise TimeoutError(f"no reply within {timeout} s")


_DOMAINS: dict[int, tuple[str, Domain]] = {}


def _given(settings: DiscoverySettings) -> str:
    return f"CYCLONEDDS_URI={settings.user_config!r}" if settings.user_config else "no CYCLONEDDS_URI"


def _new_domain(settings: DiscoverySettings, config: str) -> Domain:
    """A Domain with `config`; a configuration Cyclone DDS refuses is a ConfigError naming CYCLONEDDS_URI."""
    try:
        return Domain(settings.domain_id, config)
    except (DDSException, UnicodeEncodeError) as error:
        cause = "it holds characters other than ASCII" if isinstance(error, UnicodeEncodeError) else str(error)
        raise ConfigError(f"Cyclone DDS refused the configuration of domain {settings.domain_id}",
                          what="plem's discovery settings, then CYCLONEDDS_URI, as a configuration Cyclone DDS "
                               "accepts",
                          why=f"{cause}, with {_given(settings)}; Cyclone DDS names what it refused on stderr",
                          how="fix or unset CYCLONEDDS_URI") from None


def _domain(settings: DiscoverySettings) -> Domain:
    """The process's Domain of this id, created once: it carries the discovery configuration, and Cyclone
    allows one configuration per domain id and process."""
    config = settings.cyclone_config()
    if settings.domain_id not in _DOMAINS:
        _DOMAINS[settings.domain_id] = (config, _new_domain(settings, config))
    existing, domain = _DOMAINS[settings.domain_id]
    if existing != config:
        raise ConfigError(f"domain {settings.domain_id} is already joined with other discovery settings",
                          what="one discovery configuration per domain id in a process",
                          why=f"this process joined it as: {existing or 'Cyclone defaults'}",
                          how="create every Node of a domain with the same DiscoverySettings")
    return domain


def check_configuration(settings: DiscoverySettings) -> None:
    """Raise the ConfigError a Node of `settings` would raise for its configuration, without joining the domain.

    The domain is created with the configuration and deleted at once (a few tens of milliseconds), so
    `plem launch` can refuse a bad CYCLONEDDS_URI before any robot starts.
    """
    if settings.domain_id in _DOMAINS:
        _domain(settings)
    else:
        _new_domain(settings, settings.cyclone_config())  # dropped at once: deleting it leaves the domain


class Node:
    """One participant on the ROS 2 domain, with the interface library that names and builds its types."""

    def __init__(self, settings: DiscoverySettings | None = None, interfaces: InterfaceLibrary | None = None) -> None:
        self.settings = settings or DiscoverySettings.from_environment()
        self.library = interfaces or library()
        self._domain = _domain(self.settings)
        try:
            self.participant = DomainParticipant(self.settings.domain_id,
                                                 qos=Qos(Policy.Userdata(PARTICIPANT_USER_DATA)))
        except DDSException as error:
            raise ConfigError(f"cannot join DDS domain {self.settings.domain_id}",
                              what=f"a DDS participant on domain {self.settings.domain_id}",
                              why=f"Cyclone DDS refused it ({error}), with {_given(self.settings)}; it names the "
                                  "cause on stderr",
                              how="fix or unset CYCLONEDDS_URI; with ROS_AUTOMATIC_DISCOVERY_RANGE SUBNET or "
                                  "LOCALHOST at most 32 participants of one domain fit on a host") from None
        self._topics: dict[str, Topic[Any]] = {}

    @property
    def domain_id(self) -> int:
        """The DDS domain (ROS_DOMAIN_ID) this participant joined."""
        return self.settings.domain_id

    def publisher(self, topic: str, ros_type: str, profile: QosProfile) -> Publisher[Any]:
        """A publisher on the ROS 2 topic `topic` (absolute, e.g. /indy/joint_states)."""
        return self.publisher_of(names.topic(topic), self.library.message(ros_type), profile,
                                 self.type_user_data(ros_type))

    def subscription(self, topic: str, ros_type: str, profile: QosProfile) -> Subscription[Any]:
        """A subscription to the ROS 2 topic `topic` (absolute, e.g. /indy/joint_states)."""
        return self.subscription_of(names.topic(topic), self.library.message(ros_type), profile,
                                    self.type_user_data(ros_type))

    def service(self, service: str, ros_type: str) -> ServiceServer:
        """A server of `ros_type` (e.g. action_msgs/srv/CancelGoal) at the absolute name `service`."""
        return ServiceServer(self, service, ros_type)

    def client(self, service: str, ros_type: str) -> ServiceClient:
        """A client of `ros_type` (e.g. action_msgs/srv/CancelGoal) for the absolute name `service`."""
        return ServiceClient(self, service, ros_type)

    def publisher_of(self, dds_topic: str, struct: type, profile: QosProfile, user_data: bytes) -> Publisher[Any]:
        """A publisher on a DDS topic given by its wire name (for the parts of services and actions)."""
        writer = DataWriter(self.participant, self._topic(dds_topic, struct), profile.qos(user_data))
        return Publisher(writer, struct, self)

    def subscription_of(self, dds_topic: str, struct: type, profile: QosProfile,
                        user_data: bytes) -> Subscription[Any]:
        """A subscription to a DDS topic given by its wire name (for the parts of services and actions)."""
        reader = DataReader(self.participant, self._topic(dds_topic, struct), profile.qos(user_data))
        return Subscription(reader, struct, self, dds_topic)

    def type_user_data(self, ros_type: str) -> bytes:
        """The endpoint user data rmw_cyclonedds announces on Iron and later: `typehash=RIHS01_...;`."""
        return f"typehash={self.library.type_hash(ros_type)};".encode()

    def waitset(self, subscriptions: Iterable[Subscription[Any] | ServiceServer]) -> WaitSet:
        """A wait set that wakes when any of `subscriptions` has data."""
        waitset = WaitSet(self.participant)
        for item in subscriptions:
            waitset.attach((item.requests if isinstance(item, ServiceServer) else item).condition)
        return waitset

    def _topic(self, dds_topic: str, struct: type) -> Topic[Any]:
        if dds_topic not in self._topics:
            self._topics[dds_topic] = Topic(self.participant, dds_topic, struct)
        return self._topics[dds_topic]

    def close(self) -> None:
        """Delete the participant and everything it created (peers see the endpoints go away)."""
        self._topics.clear()
        self.participant = None  # type: ignore[assignment]  # dropping the last reference deletes the participant
        self._domain = None  # type: ignore[assignment]  # and then the domain; the node is unusable after close
