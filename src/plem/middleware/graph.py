"""The ROS 2 graph seen from DDS discovery: which topics exist, their types and their endpoints' QoS.

Cyclone DDS reports every writer and reader it discovers on the built-in DCPSPublication and
DCPSSubscription topics; reading them for a short window shows what `ros2 topic list` shows, with no
ROS install. Only DDS topics that follow the ROS 2 mapping (`rt/...`) count as topics.
"""

from __future__ import annotations

import time
import uuid
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from cyclonedds.builtin import BuiltinDataReader, BuiltinTopicDcpsPublication, BuiltinTopicDcpsSubscription
from cyclonedds.core import InstanceState, ReadCondition, SampleState, ViewState, WaitSet
from cyclonedds.qos import Policy, Qos
from cyclonedds.util import duration

from plem.middleware import names
from plem.middleware.node import Node
from plem.middleware.qos import QosProfile

_ANY_SAMPLE = SampleState.Any | ViewState.Any | InstanceState.Any
_LATE_JOINER_DURABILITY = (Policy.Durability.TransientLocal, Policy.Durability.Transient,
                           Policy.Durability.Persistent)


@dataclass(frozen=True)
class Endpoint:
    """One writer or reader of a ROS 2 topic, as discovery announced it."""

    topic: str
    type_name: str
    publisher: bool
    profile: QosProfile


@dataclass
class TopicInfo:
    """A ROS 2 topic: its types (ROS names where they follow the mapping), its publishers, its subscriptions."""

    name: str
    types: list[str] = field(default_factory=list)
    publishers: list[Endpoint] = field(default_factory=list)
    subscriptions: int = 0

    def reader_profile(self, depth: int, reliable: bool | None = None) -> QosProfile:
        """A reader QoS every publisher seen can serve: reliable and transient local only if all offer it."""
        offered = [publisher.profile for publisher in self.publishers]
        all_reliable = all(profile.reliable for profile in offered)
        all_latched = bool(offered) and all(profile.transient_local for profile in offered)
        return QosProfile(reliable=all_reliable if reliable is None else reliable, depth=depth,
                          transient_local=all_latched)


def _profile(qos: Qos) -> QosProfile:
    """The ROS 2 view of a discovered endpoint's QoS (absent policies take the DDS writer defaults)."""
    history = qos[Policy.History]
    return QosProfile(reliable=qos[Policy.Reliability] != Policy.Reliability.BestEffort,
                      depth=getattr(history, "depth", 0),
                      transient_local=qos[Policy.Durability] in _LATE_JOINER_DURABILITY)


class Graph:
    """Collects the endpoints a node discovers; `topics()` groups them by ROS 2 topic."""

    def __init__(self, node: Node) -> None:
        self._readers = {
            True: BuiltinDataReader(node.participant, BuiltinTopicDcpsPublication),
            False: BuiltinDataReader(node.participant, BuiltinTopicDcpsSubscription),
        }
        self._waitset = WaitSet(node.participant)
        for reader in self._readers.values():
            self._waitset.attach(ReadCondition(reader, _ANY_SAMPLE))
        self._endpoints: dict[uuid.UUID, Endpoint] = {}

    def discover(self, window: float, until: Callable[[Graph], bool] | None = None) -> None:
        """Take discovery news for `window` seconds, or until `until(graph)` holds."""
        deadline = time.monotonic() + window
        while True:
            self._take()
            remaining = deadline - time.monotonic()
            if remaining <= 0 or (until is not None and until(self)):
                return
            self._waitset.wait(duration(seconds=remaining))

    def topics(self) -> dict[str, TopicInfo]:
        """ROS 2 topic name → its types and endpoints, sorted by name."""
        topics: dict[str, TopicInfo] = {}
        for endpoint in sorted(self._endpoints.values(), key=lambda endpoint: endpoint.topic):
            info = topics.setdefault(endpoint.topic, TopicInfo(endpoint.topic))
            if endpoint.type_name not in info.types:
                info.types.append(endpoint.type_name)
            if endpoint.publisher:
                info.publishers.append(endpoint)
            else:
                info.subscriptions += 1
        return topics

    def _take(self) -> None:
        for publisher, reader in self._readers.items():
            for sample in reader.take(N=1024):
                self._update(sample, publisher)

    def _update(self, sample: Any, publisher: bool) -> None:
        # An endpoint that went away comes back as an invalid sample without topic or type name.
        if not sample.sample_info.valid_data:
            self._endpoints.pop(sample.key, None)
            return
        ros_name = names.ros_topic(sample.topic_name)
        if ros_name is None or ros_name[0] != "topic":
            return
        type_name = names.ros_type_name(sample.type_name) or sample.type_name
        self._endpoints[sample.key] = Endpoint(ros_name[1], type_name, publisher, _profile(sample.qos))
