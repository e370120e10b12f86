"""Quality-of-service profiles, named as ROS 2 names them, and the profile of every plem endpoint.

A reliable writer also serves best-effort readers, so plem publishes reliably everywhere; a reader
that prefers freshness asks for best effort. Writers never wait long for slow readers: history is
keep-last, so a stalled subscriber loses old samples instead of slowing the writer.
"""

from __future__ import annotations

from dataclasses import dataclass

from cyclonedds.qos import Policy, Qos
from cyclonedds.util import duration

#: How long a reliable write may wait for room in the writer's history (Cyclone's default is 100 ms).
MAX_BLOCKING = duration(milliseconds=10)


@dataclass(frozen=True)
class QosProfile:
    """The three policies ROS 2 exposes: reliability, durability and keep-last depth."""

    reliable: bool
    depth: int
    transient_local: bool = False

    def qos(self, user_data: bytes | None = None) -> Qos:
        """The Cyclone DDS QoS of this profile, with rmw's user data (e.g. the type hash) when given."""
        policies = [
            Policy.Reliability.Reliable(MAX_BLOCKING) if self.reliable else Policy.Reliability.BestEffort,
            Policy.Durability.TransientLocal if self.transient_local else Policy.Durability.Volatile,
            Policy.History.KeepLast(self.depth),
        ]
        if self.transient_local:  # late joiners get durability_service's depth (default 1); rmw_cyclonedds sets it
            policies.append(Policy.DurabilityService(0, Policy.History.KeepLast(self.depth), -1, -1, -1))
        if user_data:
            policies.append(Policy.Userdata(user_data))
        # Match peers by the types' layout, as rmw does: field names are not on the wire, and a peer whose
        # generated code names a field differently (e.g. rmw's request header) must still be heard.
        policies.append(Policy.TypeConsistency.AllowTypeCoercion(ignore_member_names=True))
        return Qos(*policies)

    def describe(self) -> str:
        """e.g. 'reliable, transient local, keep last 1', as the QoS table of docs/ros2.md reads."""
        durability = "transient local" if self.transient_local else "volatile"
        return f"{'reliable' if self.reliable else 'best effort'}, {durability}, keep last {self.depth}"


#: rmw_qos_profile_default, also what joint_state_broadcaster and joint_trajectory_controller use.
DEFAULT = QosProfile(reliable=True, depth=10)
#: rmw_qos_profile_services_default.
SERVICES = QosProfile(reliable=True, depth=10)
#: A latched topic: the last sample reaches late joiners (robot_description, action status).
LATCHED = QosProfile(reliable=True, depth=1, transient_local=True)
#: /tf and /tf_static as tf2's broadcasters publish them.
TF = QosProfile(reliable=True, depth=100)
TF_STATIC = QosProfile(reliable=True, depth=1, transient_local=True)
#: rt_raw: every cycle matters to a recorder, so reliable with a deep history (about 1 s at 1 kHz).
RT_RAW = QosProfile(reliable=True, depth=1000)
#: rt_events: reliable, and the last 100 reach a monitor that starts after a fault.
EVENTS = QosProfile(reliable=True, depth=100, transient_local=True)
