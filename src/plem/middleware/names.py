"""ROS 2 names on the DDS wire: topic prefixes, service and action topics, DDS type names.

ROS 2 maps a topic `/ns/name` to the DDS topic `rt/ns/name`, a service to the pair
`rq/ns/nameRequest` / `rr/ns/nameReply`, and a type `pkg/msg/Name` to `pkg::msg::dds_::Name_`.
An action is three services and two topics under `<action>/_action/`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from plem.errors import ConfigError

_TOKEN = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def check_name(name: str) -> str:
    """An absolute ROS 2 name (`/a/b_c`), or a ConfigError saying which rule it breaks."""
    tokens = name[1:].split("/") if name.startswith("/") else []
    if not tokens or not all(_TOKEN.fullmatch(token) for token in tokens) or "__" in name:
        raise ConfigError(f"'{name}' is not a valid ROS 2 name",
                          what="an absolute name of '/'-separated tokens of letters, digits and '_', "
                               "none starting with a digit, no '__'",
                          why=f"got {name!r}", how="e.g. /indy/joint_states (robot_id must be a valid token)")
    return name


def topic(name: str) -> str:
    """DDS topic of a ROS 2 topic."""
    return "rt" + check_name(name)


def request_topic(service: str) -> str:
    """DDS topic of a ROS 2 service's requests."""
    return f"rq{check_name(service)}Request"


def reply_topic(service: str) -> str:
    """DDS topic of a ROS 2 service's replies."""
    return f"rr{check_name(service)}Reply"


def ros_topic(dds_topic: str) -> tuple[str, str] | None:
    """(kind, ROS name) of a DDS topic that follows the ROS 2 mapping, e.g. ('topic', '/indy/rt_raw')."""
    if dds_topic.startswith("rt/"):
        return "topic", dds_topic[2:]
    for prefix, suffix, kind in (("rq/", "Request", "service request"), ("rr/", "Reply", "service reply")):
        if dds_topic.startswith(prefix) and dds_topic.endswith(suffix):
            return kind, dds_topic[2:-len(suffix)]
    return None


def dds_type_name(ros_type: str) -> str:
    """`sensor_msgs/msg/JointState` → `sensor_msgs::msg::dds_::JointState_`."""
    package, kind, name = ros_type.split("/")
    return f"{package}::{kind}::dds_::{name}_"


def ros_type_name(dds_type: str) -> str | None:
    """The inverse of dds_type_name, or None for a type that does not follow the ROS 2 mapping."""
    match = re.fullmatch(r"(\w+)::(msg|srv|action)::dds_::(\w+)_", dds_type)
    return None if match is None else "/".join(match.groups())


@dataclass(frozen=True)
class ActionNames:
    """The DDS topics of one action, e.g. /indy/joint_trajectory_controller/follow_joint_trajectory."""

    name: str

    def service(self, part: str) -> str:
        """The ROS service of a part: send_goal, cancel_goal or get_result."""
        return f"{check_name(self.name)}/_action/{part}"

    def services(self, ros_type: str) -> tuple[tuple[str, str], tuple[str, str], tuple[str, str]]:
        """(service, service type) of send_goal, cancel_goal and get_result for an action of `ros_type`."""
        return ((self.service("send_goal"), f"{ros_type}_SendGoal"),
                (self.service("cancel_goal"), "action_msgs/srv/CancelGoal"),
                (self.service("get_result"), f"{ros_type}_GetResult"))

    @property
    def feedback(self) -> str:
        """The ROS topic the action's feedback messages go to."""
        return f"{check_name(self.name)}/_action/feedback"

    @property
    def status(self) -> str:
        """The ROS topic of the action's goal status array."""
        return f"{check_name(self.name)}/_action/status"
