"""ROS 2 names on the DDS wire: topic prefixes, service and action topics, DDS type names."""

from __future__ import annotations

import inspect
import re

import pytest

from plem.errors import ConfigError
from plem.middleware import controller_manager, robot_bridge
from plem.middleware.discovery import DiscoverySettings
from plem.middleware.monitor_feed import DESCRIPTION_TOPIC, MONITOR_TOPICS
from plem.middleware.names import (
    ActionNames,
    check_name,
    dds_type_name,
    reply_topic,
    request_topic,
    ros_topic,
    ros_type_name,
    topic,
)
from plem.middleware.node import Node
from plem.middleware.types import library
from tests.conftest import fresh_domain

FJT_ACTION = "/indy/joint_trajectory_controller/follow_joint_trajectory"


def test_topic_prefix() -> None:
    assert topic("/indy/joint_states") == "rt/indy/joint_states"
    assert topic("/a") == "rt/a"


def test_service_topics() -> None:
    assert request_topic("/t/add") == "rq/t/addRequest"
    assert reply_topic("/t/add") == "rr/t/addReply"


def test_action_topics() -> None:
    action = ActionNames(FJT_ACTION)
    assert request_topic(action.service("send_goal")) == f"rq{FJT_ACTION}/_action/send_goalRequest"
    assert reply_topic(action.service("send_goal")) == f"rr{FJT_ACTION}/_action/send_goalReply"
    assert request_topic(action.service("cancel_goal")) == f"rq{FJT_ACTION}/_action/cancel_goalRequest"
    assert reply_topic(action.service("get_result")) == f"rr{FJT_ACTION}/_action/get_resultReply"
    assert topic(action.feedback) == f"rt{FJT_ACTION}/_action/feedback"
    assert topic(action.status) == f"rt{FJT_ACTION}/_action/status"
    assert reply_topic(action.service("get_result")) == \
        "rr/indy/joint_trajectory_controller/follow_joint_trajectory/_action/get_resultReply"


def test_action_names_reject_a_bad_action_name() -> None:
    with pytest.raises(ConfigError):
        ActionNames("indy/relative").service("send_goal")
    with pytest.raises(ConfigError):
        _ = ActionNames("/indy/").feedback


def test_ros_topic_inverts_the_mapping() -> None:
    assert ros_topic("rt/indy/joint_states") == ("topic", "/indy/joint_states")
    assert ros_topic(request_topic("/t/add")) == ("service request", "/t/add")
    assert ros_topic(reply_topic("/t/add")) == ("service reply", "/t/add")
    assert ros_topic("rq/t/addReply") is None
    assert ros_topic("DCPSParticipant") is None
    assert ros_topic("ros_discovery_info") is None


@pytest.mark.parametrize(("ros_type", "dds_type"), [
    ("sensor_msgs/msg/JointState", "sensor_msgs::msg::dds_::JointState_"),
    ("plem_msgs/msg/RtRaw", "plem_msgs::msg::dds_::RtRaw_"),
    ("action_msgs/srv/CancelGoal_Response", "action_msgs::srv::dds_::CancelGoal_Response_"),
    ("control_msgs/action/FollowJointTrajectory_SendGoal_Request",
     "control_msgs::action::dds_::FollowJointTrajectory_SendGoal_Request_"),
    ("control_msgs/action/FollowJointTrajectory_FeedbackMessage",
     "control_msgs::action::dds_::FollowJointTrajectory_FeedbackMessage_"),
    ("plem_msgs/action/SetMode_GetResult_Response", "plem_msgs::action::dds_::SetMode_GetResult_Response_"),
])
def test_dds_type_names(ros_type: str, dds_type: str) -> None:
    assert dds_type_name(ros_type) == dds_type
    assert ros_type_name(dds_type) == ros_type


@pytest.mark.parametrize("dds_type", [
    "sensor_msgs::msg::JointState_", "sensor_msgs::msg::dds_::JointState", "std_msgs::idl::dds_::String_",
    "DDS::ParticipantBuiltinTopicData", "",
])
def test_foreign_dds_type_names(dds_type: str) -> None:
    assert ros_type_name(dds_type) is None


STRUCTS = ["sensor_msgs/msg/JointState", "std_msgs/msg/String", "plem_msgs/msg/RtRaw",
           "action_msgs/msg/GoalStatusArray", "control_msgs/action/FollowJointTrajectory_FeedbackMessage"]
SERVICE_PARTS = ["control_msgs/action/FollowJointTrajectory_SendGoal_Request",
                 "plem_msgs/action/SetMode_GetResult_Response", "action_msgs/srv/CancelGoal_Response"]


def test_struct_type_name_is_the_dds_type_name() -> None:
    """The name cyclonedds registers for each struct (a topic's type name) is the ROS 2 DDS type name."""
    lib = library()
    node = Node(DiscoverySettings(domain_id=fresh_domain(), discovery_range="OFF"))
    try:
        parts = [(ros_type, lib.message(ros_type)) for ros_type in STRUCTS + SERVICE_PARTS]
        parts += [(ros_type, lib.service_part(ros_type)) for ros_type in SERVICE_PARTS]
        for index, (ros_type, struct) in enumerate(parts):
            assert struct.__idl_typename__ == dds_type_name(ros_type)
            assert node._topic(f"rt/type_check_{index}", struct).typename == dds_type_name(ros_type)
            assert ros_type_name(struct.__idl_typename__) == ros_type
    finally:
        node.close()


@pytest.mark.parametrize("name", ["/indy/joint_states", "/a", "/_hidden/x", "/ur5e_1/A9/b_c",
                                  FJT_ACTION + "/_action/send_goal"])
def test_valid_names(name: str) -> None:
    assert check_name(name) == name


@pytest.mark.parametrize("name", [
    "", "/", "relative/name", "joint_states", "/1indy/joint_states", "/indy/9joints", "/indy__x/a", "/indy/a__b",
    "/indy//joint_states", "/indy/joint_states/", "/indy/joint states", "/indy/joint-states", "~/joint_states",
    "/indy/jöint", "//indy",
])
def test_invalid_names_raise_config_error(name: str) -> None:
    with pytest.raises(ConfigError) as caught:
        check_name(name)
    rendered = caught.value.render()
    assert all(label in rendered for label in ("WHAT:", "WHY:", "HOW:"))
    assert repr(name) in rendered
    with pytest.raises(ConfigError):
        topic(name)
    with pytest.raises(ConfigError):
        request_topic(name)


#: Endpoints under /{robot_id}/ the bridge creates, as the ROS 2 tools know them; {trajectory} is the trajectory
#: controller's name from controllers.yaml.
BRIDGE_ENDPOINTS = {
    "joint_states", "dynamic_joint_states", "robot_description", "robot_description_semantic", "rt_raw", "rt_events",
    "rt_monitor_stats", "{trajectory}/controller_state", "{trajectory}/joint_trajectory",
    "{trajectory}/follow_joint_trajectory", "wim_rt_driver/set_mode",
    *(f"controller_manager/{service}" for service in controller_manager.SERVICES),
}


def test_bridge_endpoint_names_are_valid() -> None:
    """The names robot_bridge.py uses are these, and each is a valid name for a valid robot id."""
    source = inspect.getsource(robot_bridge)
    used = (set(re.findall(r'f"\{ns\}/([^"{]+)"', source)) | set(MONITOR_TOPICS) | {DESCRIPTION_TOPIC}
            | {f"{{trajectory}}/{name}" for name in re.findall(r'f"\{trajectory\}/([^"{]+)"', source)}
            | {f"controller_manager/{service}" for service in controller_manager.SERVICES})
    assert 'f"{self.namespace}/controller_manager"' in inspect.getsource(controller_manager)
    assert used == BRIDGE_ENDPOINTS
    for robot_id in ("indy", "ur5e_1", "Arm7"):
        used = {endpoint.replace("{trajectory}", "arm_controller") for endpoint in used}
        for endpoint in used:
            name = f"/{robot_id}/{endpoint}"
            assert check_name(name) == name
            assert topic(name) == f"rt{name}"
        action = ActionNames(f"/{robot_id}/wim_rt_driver/set_mode")
        assert request_topic(action.service("send_goal")) == \
            f"rq/{robot_id}/wim_rt_driver/set_mode/_action/send_goalRequest"
    with pytest.raises(ConfigError):     # a robot id that is not a token makes every endpoint invalid
        check_name("/7dof/joint_states")

