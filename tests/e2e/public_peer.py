"""A ROS 2 peer of a launched robot written from the public ROS 2 Jazzy interface definitions alone.

Nothing here comes from plem's own DDS code: every struct below is written out as rosidl generates it for
the definition it names, under the DDS type name rmw_cyclonedds gives it (`pkg::msg::dds_::Name_`), and the
peer opens plain Cyclone DDS readers and writers with the topic names and QoS of a ROS 2 node. What works
through it works for any ROS 2 tool that knows nothing of plem: the controller manager's services,
FollowJointTrajectory, joint_states, /tf and /tf_static, and the node graph on `ros_discovery_info`.

The ROS 2 names on the wire:

- a topic `/a/b` is the DDS topic `rt/a/b`;
- a service `/a/s` is a request topic `rq/a/sRequest` and a reply topic `rr/a/sReply`, and both parts carry
  rmw_cyclonedds's header in front of their own fields: the id of the client's request writer and the
  request's sequence number, which the server echoes so that each client picks out its own replies;
- an action `/a/act` is the services `/a/act/_action/{send_goal,cancel_goal,get_result}` and the topics
  `/a/act/_action/{feedback,status}`.
"""

# No postponed annotations here: Cyclone DDS reads the structs' field annotations as the IDL types they name.
import itertools
import time
import uuid
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import cyclonedds.idl.types as types
from cyclonedds.builtin import BuiltinDataReader, BuiltinTopicDcpsPublication, BuiltinTopicDcpsSubscription
from cyclonedds.domain import Domain, DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.pub import DataWriter
from cyclonedds.qos import Policy, Qos
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration

from tests.e2e.launched import wait_for

# ====================================================================================================
# Message types (ROS 2 Jazzy), nested types first
# ====================================================================================================


# -- builtin_interfaces, std_msgs, lifecycle_msgs, unique_identifier_msgs ---------------------------
@dataclass
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: types.int32 = 0
    nanosec: types.uint32 = 0


@dataclass
class Duration(IdlStruct, typename="builtin_interfaces::msg::dds_::Duration_"):
    sec: types.int32 = 0
    nanosec: types.uint32 = 0


@dataclass
class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    stamp: Time = field(default_factory=Time)
    frame_id: str = ""


@dataclass
class String(IdlStruct, typename="std_msgs::msg::dds_::String_"):
    data: str = ""


@dataclass
class State(IdlStruct, typename="lifecycle_msgs::msg::dds_::State_"):
    id: types.uint8 = 0
    label: str = ""


PRIMARY_STATE_UNCONFIGURED, PRIMARY_STATE_INACTIVE, PRIMARY_STATE_ACTIVE, PRIMARY_STATE_FINALIZED = 1, 2, 3, 4


@dataclass
class UUID(IdlStruct, typename="unique_identifier_msgs::msg::dds_::UUID_"):
    uuid: types.array[types.uint8, 16] = field(default_factory=lambda: [0] * 16)


# -- geometry_msgs, tf2_msgs, sensor_msgs -----------------------------------------------------------
@dataclass
class Vector3(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
    x: types.float64 = 0.0
    y: types.float64 = 0.0
    z: types.float64 = 0.0


@dataclass
class Quaternion(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):
    x: types.float64 = 0.0
    y: types.float64 = 0.0
    z: types.float64 = 0.0
    w: types.float64 = 1.0


@dataclass
class Transform(IdlStruct, typename="geometry_msgs::msg::dds_::Transform_"):
    translation: Vector3 = field(default_factory=Vector3)
    rotation: Quaternion = field(default_factory=Quaternion)


@dataclass
class Twist(IdlStruct, typename="geometry_msgs::msg::dds_::Twist_"):
    linear: Vector3 = field(default_factory=Vector3)
    angular: Vector3 = field(default_factory=Vector3)


@dataclass
class TransformStamped(IdlStruct, typename="geometry_msgs::msg::dds_::TransformStamped_"):
    header: Header = field(default_factory=Header)
    child_frame_id: str = ""
    transform: Transform = field(default_factory=Transform)


@dataclass
class TFMessage(IdlStruct, typename="tf2_msgs::msg::dds_::TFMessage_"):
    transforms: types.sequence[TransformStamped] = field(default_factory=list)


@dataclass
class JointState(IdlStruct, typename="sensor_msgs::msg::dds_::JointState_"):
    header: Header = field(default_factory=Header)
    name: types.sequence[str] = field(default_factory=list)
    position: types.sequence[types.float64] = field(default_factory=list)
    velocity: types.sequence[types.float64] = field(default_factory=list)
    effort: types.sequence[types.float64] = field(default_factory=list)


# -- trajectory_msgs ---------------------------------------------------------------------------------
@dataclass
class JointTrajectoryPoint(IdlStruct, typename="trajectory_msgs::msg::dds_::JointTrajectoryPoint_"):
    positions: types.sequence[types.float64] = field(default_factory=list)
    velocities: types.sequence[types.float64] = field(default_factory=list)
    accelerations: types.sequence[types.float64] = field(default_factory=list)
    effort: types.sequence[types.float64] = field(default_factory=list)
    time_from_start: Duration = field(default_factory=Duration)


@dataclass
class JointTrajectory(IdlStruct, typename="trajectory_msgs::msg::dds_::JointTrajectory_"):
    header: Header = field(default_factory=Header)
    joint_names: types.sequence[str] = field(default_factory=list)
    points: types.sequence[JointTrajectoryPoint] = field(default_factory=list)


@dataclass
class MultiDOFJointTrajectoryPoint(IdlStruct, typename="trajectory_msgs::msg::dds_::MultiDOFJointTrajectoryPoint_"):
    transforms: types.sequence[Transform] = field(default_factory=list)
    velocities: types.sequence[Twist] = field(default_factory=list)
    accelerations: types.sequence[Twist] = field(default_factory=list)
    time_from_start: Duration = field(default_factory=Duration)


@dataclass
class MultiDOFJointTrajectory(IdlStruct, typename="trajectory_msgs::msg::dds_::MultiDOFJointTrajectory_"):
    header: Header = field(default_factory=Header)
    joint_names: types.sequence[str] = field(default_factory=list)
    points: types.sequence[MultiDOFJointTrajectoryPoint] = field(default_factory=list)


# -- controller_manager_msgs -------------------------------------------------------------------------
@dataclass
class ChainConnection(IdlStruct, typename="controller_manager_msgs::msg::dds_::ChainConnection_"):
    name: str = ""
    reference_interfaces: types.sequence[str] = field(default_factory=list)


@dataclass
class ControllerState(IdlStruct, typename="controller_manager_msgs::msg::dds_::ControllerState_"):
    name: str = ""
    state: str = ""
    type: str = ""
    is_async: bool = False
    update_rate: types.uint16 = 0
    claimed_interfaces: types.sequence[str] = field(default_factory=list)
    required_command_interfaces: types.sequence[str] = field(default_factory=list)
    required_state_interfaces: types.sequence[str] = field(default_factory=list)
    is_chainable: bool = False
    is_chained: bool = False
    exported_state_interfaces: types.sequence[str] = field(default_factory=list)
    reference_interfaces: types.sequence[str] = field(default_factory=list)
    chain_connections: types.sequence[ChainConnection] = field(default_factory=list)


@dataclass
class HardwareInterface(IdlStruct, typename="controller_manager_msgs::msg::dds_::HardwareInterface_"):
    name: str = ""
    data_type: str = ""
    is_available: bool = False
    is_claimed: bool = False


@dataclass
class HardwareComponentState(IdlStruct, typename="controller_manager_msgs::msg::dds_::HardwareComponentState_"):
    name: str = ""
    type: str = ""
    is_async: bool = False
    rw_rate: types.uint16 = 0
    class_type: str = ""
    plugin_name: str = ""
    state: State = field(default_factory=State)
    command_interfaces: types.sequence[HardwareInterface] = field(default_factory=list)
    state_interfaces: types.sequence[HardwareInterface] = field(default_factory=list)


# Requests and replies: rmw_cyclonedds's header (client_guid, sequence_number), then the part's own fields.
# A part with no fields of its own has rosidl's placeholder member, as every empty ROS 2 message does.
# The header's member names are not on the wire. A ROS 2 node never compares them (rmw_cyclonedds announces no
# XTypes type information), but these structs do carry type information (the Python binding always sends it),
# so a server whose request readers compare member names does not match this peer's requests.
@dataclass
class ListControllersRequest(IdlStruct, typename="controller_manager_msgs::srv::dds_::ListControllers_Request_"):
    client_guid: types.uint64 = 0
    sequence_number: types.int64 = 0
    structure_needs_at_least_one_member: types.uint8 = 0


@dataclass
class ListControllersResponse(IdlStruct, typename="controller_manager_msgs::srv::dds_::ListControllers_Response_"):
    client_guid: types.uint64 = 0
    sequence_number: types.int64 = 0
    controller: types.sequence[ControllerState] = field(default_factory=list)


@dataclass
class ListHardwareComponentsRequest(IdlStruct,
                                    typename="controller_manager_msgs::srv::dds_::ListHardwareComponents_Request_"):
    client_guid: types.uint64 = 0
    sequence_number: types.int64 = 0
    structure_needs_at_least_one_member: types.uint8 = 0


@dataclass
class ListHardwareComponentsResponse(IdlStruct,
                                     typename="controller_manager_msgs::srv::dds_::ListHardwareComponents_Response_"):
    client_guid: types.uint64 = 0
    sequence_number: types.int64 = 0
    component: types.sequence[HardwareComponentState] = field(default_factory=list)


BEST_EFFORT, STRICT = 1, 2


@dataclass
class SwitchControllerRequest(IdlStruct, typename="controller_manager_msgs::srv::dds_::SwitchController_Request_"):
    client_guid: types.uint64 = 0
    sequence_number: types.int64 = 0
    activate_controllers: types.sequence[str] = field(default_factory=list)
    deactivate_controllers: types.sequence[str] = field(default_factory=list)
    strictness: types.int32 = 0
    activate_asap: bool = False
    timeout: Duration = field(default_factory=Duration)


@dataclass
class SwitchControllerResponse(IdlStruct, typename="controller_manager_msgs::srv::dds_::SwitchController_Response_"):
    client_guid: types.uint64 = 0
    sequence_number: types.int64 = 0
    ok: bool = False
    message: str = ""


@dataclass
class SetHardwareComponentStateRequest(
        IdlStruct, typename="controller_manager_msgs::srv::dds_::SetHardwareComponentState_Request_"):
    client_guid: types.uint64 = 0
    sequence_number: types.int64 = 0
    name: str = ""
    target_state: State = field(default_factory=State)


@dataclass
class SetHardwareComponentStateResponse(
        IdlStruct, typename="controller_manager_msgs::srv::dds_::SetHardwareComponentState_Response_"):
    client_guid: types.uint64 = 0
    sequence_number: types.int64 = 0
    ok: bool = False
    state: State = field(default_factory=State)


# -- action_msgs ---------------------------------------------------------------------------------------
@dataclass
class GoalInfo(IdlStruct, typename="action_msgs::msg::dds_::GoalInfo_"):
    goal_id: UUID = field(default_factory=UUID)
    stamp: Time = field(default_factory=Time)


@dataclass
class GoalStatus(IdlStruct, typename="action_msgs::msg::dds_::GoalStatus_"):
    goal_info: GoalInfo = field(default_factory=GoalInfo)
    status: types.int8 = 0


@dataclass
class GoalStatusArray(IdlStruct, typename="action_msgs::msg::dds_::GoalStatusArray_"):
    status_list: types.sequence[GoalStatus] = field(default_factory=list)


STATUS_UNKNOWN, STATUS_ACCEPTED, STATUS_EXECUTING, STATUS_CANCELING = 0, 1, 2, 3
STATUS_SUCCEEDED, STATUS_CANCELED, STATUS_ABORTED = 4, 5, 6
TERMINAL = frozenset({STATUS_SUCCEEDED, STATUS_CANCELED, STATUS_ABORTED})


@dataclass
class CancelGoalRequest(IdlStruct, typename="action_msgs::srv::dds_::CancelGoal_Request_"):
    client_guid: types.uint64 = 0
    sequence_number: types.int64 = 0
    goal_info: GoalInfo = field(default_factory=GoalInfo)


@dataclass
class CancelGoalResponse(IdlStruct, typename="action_msgs::srv::dds_::CancelGoal_Response_"):
    client_guid: types.uint64 = 0
    sequence_number: types.int64 = 0
    return_code: types.int8 = 0
    goals_canceling: types.sequence[GoalInfo] = field(default_factory=list)


# -- control_msgs/action/FollowJointTrajectory ---------------------------------------------------------
@dataclass
class JointTolerance(IdlStruct, typename="control_msgs::msg::dds_::JointTolerance_"):
    name: str = ""
    position: types.float64 = 0.0
    velocity: types.float64 = 0.0
    acceleration: types.float64 = 0.0


@dataclass
class JointComponentTolerance(IdlStruct, typename="control_msgs::msg::dds_::JointComponentTolerance_"):
    joint_name: str = ""
    component: types.uint16 = 0
    position: types.float64 = 0.0
    velocity: types.float64 = 0.0
    acceleration: types.float64 = 0.0


@dataclass
class FollowJointTrajectoryGoal(IdlStruct, typename="control_msgs::action::dds_::FollowJointTrajectory_Goal_"):
    trajectory: JointTrajectory = field(default_factory=JointTrajectory)
    multi_dof_trajectory: MultiDOFJointTrajectory = field(default_factory=MultiDOFJointTrajectory)
    path_tolerance: types.sequence[JointTolerance] = field(default_factory=list)
    component_path_tolerance: types.sequence[JointComponentTolerance] = field(default_factory=list)
    goal_tolerance: types.sequence[JointTolerance] = field(default_factory=list)
    component_goal_tolerance: types.sequence[JointComponentTolerance] = field(default_factory=list)
    goal_time_tolerance: Duration = field(default_factory=Duration)


@dataclass
class FollowJointTrajectoryResult(IdlStruct, typename="control_msgs::action::dds_::FollowJointTrajectory_Result_"):
    error_code: types.int32 = 0
    error_string: str = ""


@dataclass
class FollowJointTrajectoryFeedback(IdlStruct,
                                    typename="control_msgs::action::dds_::FollowJointTrajectory_Feedback_"):
    header: Header = field(default_factory=Header)
    joint_names: types.sequence[str] = field(default_factory=list)
    desired: JointTrajectoryPoint = field(default_factory=JointTrajectoryPoint)
    actual: JointTrajectoryPoint = field(default_factory=JointTrajectoryPoint)
    error: JointTrajectoryPoint = field(default_factory=JointTrajectoryPoint)
    multi_dof_joint_names: types.sequence[str] = field(default_factory=list)
    multi_dof_desired: MultiDOFJointTrajectoryPoint = field(default_factory=MultiDOFJointTrajectoryPoint)
    multi_dof_actual: MultiDOFJointTrajectoryPoint = field(default_factory=MultiDOFJointTrajectoryPoint)
    multi_dof_error: MultiDOFJointTrajectoryPoint = field(default_factory=MultiDOFJointTrajectoryPoint)


@dataclass
class FollowJointTrajectorySendGoalRequest(
        IdlStruct, typename="control_msgs::action::dds_::FollowJointTrajectory_SendGoal_Request_"):
    client_guid: types.uint64 = 0
    sequence_number: types.int64 = 0
    goal_id: UUID = field(default_factory=UUID)
    goal: FollowJointTrajectoryGoal = field(default_factory=FollowJointTrajectoryGoal)


@dataclass
class FollowJointTrajectorySendGoalResponse(
        IdlStruct, typename="control_msgs::action::dds_::FollowJointTrajectory_SendGoal_Response_"):
    client_guid: types.uint64 = 0
    sequence_number: types.int64 = 0
    accepted: bool = False
    stamp: Time = field(default_factory=Time)


@dataclass
class FollowJointTrajectoryGetResultRequest(
        IdlStruct, typename="control_msgs::action::dds_::FollowJointTrajectory_GetResult_Request_"):
    client_guid: types.uint64 = 0
    sequence_number: types.int64 = 0
    goal_id: UUID = field(default_factory=UUID)


@dataclass
class FollowJointTrajectoryGetResultResponse(
        IdlStruct, typename="control_msgs::action::dds_::FollowJointTrajectory_GetResult_Response_"):
    client_guid: types.uint64 = 0
    sequence_number: types.int64 = 0
    status: types.int8 = 0
    result: FollowJointTrajectoryResult = field(default_factory=FollowJointTrajectoryResult)


@dataclass
class FollowJointTrajectoryFeedbackMessage(
        IdlStruct, typename="control_msgs::action::dds_::FollowJointTrajectory_FeedbackMessage_"):
    goal_id: UUID = field(default_factory=UUID)
    feedback: FollowJointTrajectoryFeedback = field(default_factory=FollowJointTrajectoryFeedback)


# -- rmw_dds_common: the node graph (Jazzy layout, 16-byte GIDs) ---------------------------------------
@dataclass
class Gid(IdlStruct, typename="rmw_dds_common::msg::dds_::Gid_"):
    data: types.array[types.uint8, 16] = field(default_factory=lambda: [0] * 16)


@dataclass
class NodeEntitiesInfo(IdlStruct, typename="rmw_dds_common::msg::dds_::NodeEntitiesInfo_"):
    node_namespace: types.bounded_str[256] = ""
    node_name: types.bounded_str[256] = ""
    reader_gid_seq: types.sequence[Gid] = field(default_factory=list)
    writer_gid_seq: types.sequence[Gid] = field(default_factory=list)


@dataclass
class ParticipantEntitiesInfo(IdlStruct, typename="rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_"):
    gid: Gid = field(default_factory=Gid)
    node_entities_info_seq: types.sequence[NodeEntitiesInfo] = field(default_factory=list)


# ====================================================================================================
# Names and QoS as a ROS 2 node uses them
# ====================================================================================================
def topic(name: str) -> str:
    """DDS topic of the ROS 2 topic `name` (absolute)."""
    return f"rt{name}"


def request_topic(service: str) -> str:
    """DDS topic of a ROS 2 service's requests."""
    return f"rq{service}Request"


def reply_topic(service: str) -> str:
    """DDS topic of a ROS 2 service's replies."""
    return f"rr{service}Reply"


#: The graph topic has no `rt` prefix: it is rmw's own, not a ROS topic.
DISCOVERY_TOPIC = "ros_discovery_info"


@dataclass(frozen=True)
class Profile:
    """A ROS 2 QoS profile: reliability, durability and keep-last depth."""

    depth: int
    transient_local: bool = False
    reliable: bool = True

    def qos(self) -> Qos:
        """The Cyclone DDS QoS of this profile, for a writer."""
        return Qos(Policy.Reliability.Reliable(duration(milliseconds=100)) if self.reliable
                   else Policy.Reliability.BestEffort,
                   Policy.Durability.TransientLocal if self.transient_local else Policy.Durability.Volatile,
                   Policy.History.KeepLast(self.depth))

    def reader_qos(self) -> Qos:
        """The Cyclone DDS QoS of this profile for a reader, which compares no member names with a writer's type.

        A ROS 2 node compares none: rmw_cyclonedds's endpoints announce no XTypes type information, so its
        readers and writers match on the DDS type name. Names are not on the wire, and those of the request
        header are given by no ROS 2 definition."""
        return Qos(*self.qos(), Policy.TypeConsistency.AllowTypeCoercion(
            ignore_sequence_bounds=True, ignore_string_bounds=True, ignore_member_names=True,
            prevent_type_widening=False, force_type_validation=False))


#: rmw_qos_profile_default and rmw_qos_profile_services_default.
DEFAULT = Profile(depth=10)
SERVICES = Profile(depth=10)
#: tf2's broadcasters and listeners.
TF = Profile(depth=100)
TF_STATIC = Profile(depth=1, transient_local=True)
#: robot_description and an action's status topic: the last sample reaches late joiners.
LATCHED = Profile(depth=1, transient_local=True)
#: ros_discovery_info as a reader of it: the topic has no key, so one slot per writer would not be enough to keep
#: every participant's latest announcement (each writer offers its last one, transient local).
GRAPH = Profile(depth=100, transient_local=True)


def cyclone_config(environ: Mapping[str, str]) -> tuple[int, str]:
    """Domain id and Cyclone DDS configuration from ROS_DOMAIN_ID and ROS_AUTOMATIC_DISCOVERY_RANGE, as a
    ROS 2 Jazzy node on rmw_cyclonedds_cpp configures its domain (SUBNET and LOCALHOST)."""
    domain_id = int(environ.get("ROS_DOMAIN_ID") or 0)
    discovery_range = environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE") or "SUBNET"
    if discovery_range not in ("SUBNET", "LOCALHOST"):
        raise ValueError(f"ROS_AUTOMATIC_DISCOVERY_RANGE={discovery_range!r}: only SUBNET and LOCALHOST are set up")
    local = discovery_range == "LOCALHOST"
    config = ("<CycloneDDS><Domain>"
              + ("<General><AllowMulticast>false</AllowMulticast></General>" if local else "")
              + "<Discovery><ParticipantIndex>auto</ParticipantIndex>"
              "<MaxAutoParticipantIndex>32</MaxAutoParticipantIndex>"
              + ('<Peers><Peer address="localhost"/></Peers>' if local else "")
              + "</Discovery></Domain></CycloneDDS>")
    return domain_id, config


def take(reader: DataReader[Any], limit: int = 256) -> list[Any]:
    """Every valid sample waiting in `reader` (up to `limit`), oldest first."""
    return [sample for sample in reader.take(N=limit) if sample.sample_info.valid_data]


def to_duration(seconds: float) -> Duration:
    """builtin_interfaces/Duration of `seconds` (not negative)."""
    whole = int(seconds)
    return Duration(sec=whole, nanosec=round((seconds - whole) * 1e9))


# ====================================================================================================
# The peer
# ====================================================================================================
class PublicPeer:
    """One DDS participant on the ROS 2 domain of `environ`, as a ROS 2 node on rmw_cyclonedds joins it."""

    #: rmw_cyclonedds announces the participant's security enclave in its user data.
    USER_DATA = b"enclave=/;"

    def __init__(self, environ: Mapping[str, str]) -> None:
        self.domain_id, config = cyclone_config(environ)
        self._domain: Domain | None = Domain(self.domain_id, config)
        self.participant: DomainParticipant | None = DomainParticipant(
            self.domain_id, qos=Qos(Policy.Userdata(self.USER_DATA)))
        self._topics: dict[str, Topic[Any]] = {}
        self._publications: BuiltinDataReader | None = None
        self._subscriptions: BuiltinDataReader | None = None
        self._discovered: dict[bool, dict[uuid.UUID, Any]] = {True: {}, False: {}}

    # -- endpoints -------------------------------------------------------------------------------------
    def _topic(self, dds_topic: str, struct: type) -> Topic[Any]:
        if dds_topic not in self._topics:
            self._topics[dds_topic] = Topic(self.participant, dds_topic, struct)
        return self._topics[dds_topic]

    def reader(self, dds_topic: str, struct: type, profile: Profile) -> DataReader[Any]:
        """A reader on a DDS topic given by its wire name."""
        return DataReader(self.participant, self._topic(dds_topic, struct), profile.reader_qos())

    def writer(self, dds_topic: str, struct: type, profile: Profile) -> DataWriter[Any]:
        """A writer on a DDS topic given by its wire name."""
        return DataWriter(self.participant, self._topic(dds_topic, struct), profile.qos())

    def subscription(self, name: str, struct: type, profile: Profile = DEFAULT) -> DataReader[Any]:
        """A reader of the ROS 2 topic `name` (absolute)."""
        return self.reader(topic(name), struct, profile)

    def publisher(self, name: str, struct: type, profile: Profile = DEFAULT) -> DataWriter[Any]:
        """A writer on the ROS 2 topic `name` (absolute)."""
        return self.writer(topic(name), struct, profile)

    def graph(self) -> DataReader[Any]:
        """A reader of `ros_discovery_info`: every participant's nodes with the GIDs of their endpoints."""
        return self.reader(DISCOVERY_TOPIC, ParticipantEntitiesInfo, GRAPH)

    # -- DDS discovery -----------------------------------------------------------------------------------
    def discovered(self, publications: bool) -> dict[uuid.UUID, Any]:
        """Every writer (or reader) discovered so far, by GUID: DCPSPublication (DCPSSubscription) samples with
        `topic_name`, `type_name` and `participant_key`; endpoints that went away are dropped."""
        if self._publications is None:
            self._publications = BuiltinDataReader(self.participant, BuiltinTopicDcpsPublication)
            self._subscriptions = BuiltinDataReader(self.participant, BuiltinTopicDcpsSubscription)
        known = self._discovered[publications]
        reader = self._publications if publications else self._subscriptions
        for sample in reader.take(N=4096):
            if sample.sample_info.valid_data:
                known[sample.key] = sample
            else:
                known.pop(sample.key, None)
        return known

    def close(self) -> None:
        """Delete the participant and everything it created (peers see the endpoints go away)."""
        self._topics.clear()
        self._publications = self._subscriptions = None
        self.participant = None  # dropping the last reference deletes the participant, then the domain
        self._domain = None


class ServiceClient:
    """Sends requests of one service and picks out the replies addressed to it."""

    def __init__(self, peer: PublicPeer, service: str, request: type, reply: type) -> None:
        self.service = service
        self.request_type = request
        self._requests = peer.writer(request_topic(service), request, SERVICES)
        self._replies = peer.reader(reply_topic(service), reply, SERVICES)
        self.guid = self._requests.instance_handle & 0xFFFF_FFFF_FFFF_FFFF  # unique to this request writer
        self._sequence = itertools.count(1)
        self._early: dict[int, Any] = {}

    @property
    def requests_matched(self) -> bool:
        """A server's request reader is matched with this client's request writer."""
        return self._requests.get_publication_matched_status().current_count > 0

    @property
    def replies_matched(self) -> bool:
        """A server's reply writer is matched with this client's reply reader."""
        return self._replies.get_subscription_matched_status().current_count > 0

    @property
    def ready(self) -> bool:
        """A server's request reader and reply writer are both matched."""
        return self.requests_matched and self.replies_matched

    def call(self, timeout: float = 5.0, /, **fields: Any) -> Any:
        """Send one request with the part's `fields` and wait for its reply; TimeoutError when none arrives within
        `timeout` (positional, so that a request may have a field of that name)."""
        sequence = next(self._sequence)
        self._requests.write(self.request_type(client_guid=self.guid, sequence_number=sequence, **fields))
        deadline = time.monotonic() + timeout
        while True:
            for reply in take(self._replies):
                if reply.client_guid == self.guid:
                    self._early[reply.sequence_number] = reply
            if sequence in self._early:
                return self._early.pop(sequence)
            if time.monotonic() > deadline:
                raise TimeoutError(f"no reply from {self.service} within {timeout} s")
            time.sleep(0.005)


class ControllerManager:
    """The services of a ros2_control controller manager, e.g. `/indy/controller_manager`."""

    def __init__(self, peer: PublicPeer, name: str) -> None:
        self.name = name
        self.list_controllers_service = ServiceClient(peer, f"{name}/list_controllers", ListControllersRequest,
                                                      ListControllersResponse)
        self.list_components_service = ServiceClient(peer, f"{name}/list_hardware_components",
                                                     ListHardwareComponentsRequest, ListHardwareComponentsResponse)
        self.switch_service = ServiceClient(peer, f"{name}/switch_controller", SwitchControllerRequest,
                                            SwitchControllerResponse)
        self.set_state_service = ServiceClient(peer, f"{name}/set_hardware_component_state",
                                               SetHardwareComponentStateRequest, SetHardwareComponentStateResponse)
        self.services = (self.list_controllers_service, self.list_components_service, self.switch_service,
                         self.set_state_service)

    def wait_for_services(self, timeout: float) -> bool:
        """True once every service is matched with a server."""
        return bool(wait_for(lambda: all(service.ready for service in self.services), timeout))

    def list_controllers(self, timeout: float = 5.0) -> dict[str, ControllerState]:
        """The controllers by name."""
        reply = self.list_controllers_service.call(timeout)
        return {controller.name: controller for controller in reply.controller}

    def states(self, timeout: float = 5.0) -> dict[str, str]:
        """Each controller's state ('active', 'inactive', ...) by name."""
        return {name: controller.state for name, controller in self.list_controllers(timeout).items()}

    def list_hardware_components(self, timeout: float = 5.0) -> list[HardwareComponentState]:
        """The hardware components."""
        return list(self.list_components_service.call(timeout).component)

    def switch_controller(self, activate: Sequence[str] = (), deactivate: Sequence[str] = (),
                          strictness: int = STRICT, timeout: float = 10.0) -> SwitchControllerResponse:
        """Activate and deactivate controllers in one request, as `ros2 control switch_controllers` does."""
        return self.switch_service.call(timeout, activate_controllers=list(activate),
                                        deactivate_controllers=list(deactivate), strictness=strictness,
                                        activate_asap=False, timeout=to_duration(timeout / 2))

    def set_hardware_component_state(self, name: str, state_id: int, label: str,
                                     timeout: float = 10.0) -> SetHardwareComponentStateResponse:
        """Drive a hardware component's lifecycle, as `ros2 control set_hardware_component_state` does."""
        return self.set_state_service.call(timeout, name=name, target_state=State(id=state_id, label=label))


class FollowJointTrajectoryClient:
    """A control_msgs/action/FollowJointTrajectory client, e.g. for
    `/indy/joint_trajectory_controller/follow_joint_trajectory`."""

    def __init__(self, peer: PublicPeer, action: str) -> None:
        base = f"{action}/_action"
        self.send_goal_service = ServiceClient(peer, f"{base}/send_goal", FollowJointTrajectorySendGoalRequest,
                                               FollowJointTrajectorySendGoalResponse)
        self.cancel_service = ServiceClient(peer, f"{base}/cancel_goal", CancelGoalRequest, CancelGoalResponse)
        self.get_result_service = ServiceClient(peer, f"{base}/get_result", FollowJointTrajectoryGetResultRequest,
                                                FollowJointTrajectoryGetResultResponse)
        self.feedback = peer.subscription(f"{base}/feedback", FollowJointTrajectoryFeedbackMessage, DEFAULT)
        self.status = peer.subscription(f"{base}/status", GoalStatusArray, LATCHED)
        self.services = (self.send_goal_service, self.cancel_service, self.get_result_service)

    def wait_for_server(self, timeout: float) -> bool:
        """True once the action's three services are matched with a server."""
        return bool(wait_for(lambda: all(service.ready for service in self.services), timeout))

    def send_goal(self, trajectory: JointTrajectory, timeout: float = 5.0) -> tuple[bytes, bool]:
        """Send a goal; (its id, accepted)."""
        goal_id = uuid.uuid4().bytes
        reply = self.send_goal_service.call(timeout, goal_id=UUID(uuid=list(goal_id)),
                                            goal=FollowJointTrajectoryGoal(trajectory=trajectory))
        return goal_id, bool(reply.accepted)

    def result(self, goal_id: bytes, timeout: float) -> tuple[int, FollowJointTrajectoryResult]:
        """Wait for the goal's end: (status, result). The server answers once the goal has ended."""
        reply = self.get_result_service.call(timeout, goal_id=UUID(uuid=list(goal_id)))
        return int(reply.status), reply.result

    def cancel(self, goal_id: bytes, timeout: float = 5.0) -> int:
        """Ask the server to cancel one goal; the CancelGoal return code."""
        reply = self.cancel_service.call(timeout, goal_info=GoalInfo(goal_id=UUID(uuid=list(goal_id))))
        return int(reply.return_code)


def trajectory(joint_names: Sequence[str], points: Sequence[JointTrajectoryPoint]) -> JointTrajectory:
    """A JointTrajectory that starts on receipt (header stamp 0)."""
    return JointTrajectory(joint_names=list(joint_names), points=list(points))


def point(positions: Sequence[float], at: float, velocities: Sequence[float] = (),
          accelerations: Sequence[float] = ()) -> JointTrajectoryPoint:
    """A JointTrajectoryPoint reached `at` seconds after the start; velocities and accelerations optional."""
    return JointTrajectoryPoint(positions=[float(p) for p in positions], velocities=[float(v) for v in velocities],
                                accelerations=[float(a) for a in accelerations], time_from_start=to_duration(at))


def gid_bytes(gid: Gid) -> bytes:
    """A GID's 16 bytes, which are the DDS GUID of the entity."""
    return bytes(gid.data)
