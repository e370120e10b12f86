"""MoveIt's interfaces (moveit_msgs 2.6, as ROS 2 Jazzy ships it) on plem's wire: bytes, fields and type hashes."""

from __future__ import annotations

import struct
import threading
from typing import Any

import pytest
from rosbags.interfaces import Nodetype

from plem.middleware.types import INTERFACES, ON_DEMAND, InterfaceLibrary
from tests.wire_values import (
    ACTION_PARTS,
    LIB,
    Filler,
    constants_of,
    fields,
    fields_of,
    plain_of,
    reference_bytes,
    to_plem,
)

SERVICES = ("GetPositionIK", "GetPositionFK", "GetMotionPlan", "GetCartesianPath", "ApplyPlanningScene",
            "GetPlanningScene", "GetMotionSequence")
EXECUTE = "moveit_msgs/action/ExecuteTrajectory"
#: Requests and replies of the seven services and of ExecuteTrajectory's goal and result calls.
SERVICE_PARTS = [f"moveit_msgs/srv/{name}_{part}" for name in SERVICES for part in ("Request", "Response")] + [
    f"{EXECUTE}_{part}" for part in ACTION_PARTS if "_Re" in part]
PARTS = SERVICE_PARTS + [f"{EXECUTE}_{part}" for part in ("Goal", "Result", "Feedback", "FeedbackMessage")]
SEEDS = range(4)  # seeds 0 and 3: every sequence empty; 1 and 2: empty and non-empty mixed


def _reached(roots: list[str]) -> list[str]:
    """Every message of the on-demand packages that the roots hold, however deep."""
    seen: set[str] = set()
    todo = list(roots)
    while todo:
        for _, (node, detail) in fields(todo.pop()):
            while node in (Nodetype.ARRAY, Nodetype.SEQUENCE):
                node, detail = detail[0]
            if node == Nodetype.NAME and detail not in seen:
                seen.add(detail)
                todo.append(detail)
    return sorted(name for name in seen if name.split("/")[0] in ON_DEMAND and "/msg/" in name)


REACHED = _reached(PARTS)


def test_every_definition_file_is_reached() -> None:
    """The shipped definitions are exactly what the eight interfaces need: nothing missing, nothing unused."""
    shipped = {path.relative_to(INTERFACES).with_suffix("").as_posix()
               for package in ON_DEMAND for path in (INTERFACES / package).glob("*/*.*")}
    interfaces = {f"moveit_msgs/srv/{name}" for name in SERVICES} | {EXECUTE}
    assert shipped == set(REACHED) | interfaces
    assert len(REACHED) == 34


# -- CDR equality ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("ros_type", PARTS)
def test_parts_bytes_equal_rosbags_bytes(ros_type: str, seed: int) -> None:
    """Same content, same CDR bytes; plem reads rosbags' bytes back to the same content."""
    plain = Filler(seed).message(ros_type)
    reference = reference_bytes(ros_type, plain)
    assert to_plem(ros_type, plain).serialize() == reference
    assert plain_of(ros_type, LIB.message(ros_type).deserialize(reference)) == plain


@pytest.mark.parametrize("ros_type", REACHED)
def test_reached_types_bytes_equal_rosbags_bytes(ros_type: str) -> None:
    """Each nested type on its own, filled with non-empty sequences, and all-zero."""
    for plain in (Filler(1).message(ros_type), Filler(0, zero=True).message(ros_type)):
        reference = reference_bytes(ros_type, plain)
        assert to_plem(ros_type, plain).serialize() == reference
        assert plain_of(ros_type, LIB.message(ros_type).deserialize(reference)) == plain


@pytest.mark.parametrize("ros_type", PARTS + REACHED)
def test_defaults_match_rosbags_zero_message(ros_type: str) -> None:
    """A struct built with no fields is rosbags' all-zero, all-empty message, nested structs included."""
    plain = Filler(0, zero=True).message(ros_type)
    zero = LIB.message(ros_type)()
    assert plain_of(ros_type, zero) == plain
    assert zero.serialize() == reference_bytes(ros_type, plain)


@pytest.mark.parametrize("ros_type", SERVICE_PARTS)
def test_service_part_is_rmw_header_then_fields(ros_type: str) -> None:
    """Requests and replies: encapsulation, uint64 writer guid, int64 sequence, then the fields."""
    guid, sequence = 0x0102_0304_0506_0708, 0x7FFF_FFFF_FFFF
    plain = Filler(2).message(ros_type)
    reference = reference_bytes(ros_type, plain)
    expected = reference[:4] + struct.pack("<Qq", guid, sequence) + reference[4:]
    assert to_plem(ros_type, plain, with_header=True, rmw_guid=guid, rmw_seq=sequence).serialize() == expected
    back = LIB.service_part(ros_type).deserialize(expected)
    assert (back.rmw_guid, back.rmw_seq) == (guid, sequence)
    assert plain_of(ros_type, back) == plain


def test_error_code_bytes_spelled_out() -> None:
    """MoveItErrorCodes by hand: int32 val, then two CDR strings (length with the NUL, 4-byte aligned)."""
    codes = LIB.new("moveit_msgs/msg/MoveItErrorCodes", val=-31, message="no", source="ik")
    assert codes.serialize() == (b"\x00\x01\x00\x00" + struct.pack("<i", -31) + struct.pack("<I", 3) + b"no\x00"
                                 + b"\x00" + struct.pack("<I", 3) + b"ik\x00")


@pytest.mark.parametrize("ros_type", PARTS)
def test_dds_type_names(ros_type: str) -> None:
    """The DDS type names rmw_cyclonedds gives the parts, e.g. moveit_msgs::srv::dds_::GetPositionIK_Request_."""
    package, kind, name = ros_type.split("/")
    assert LIB.message(ros_type).__idl_typename__ == f"{package}::{kind}::dds_::{name}_"


# -- the definitions match upstream's --------------------------------------------------------------------------
_RS, _EC, _C = "moveit_msgs/msg/RobotState", "moveit_msgs/msg/MoveItErrorCodes", "moveit_msgs/msg/Constraints"
_RT, _PS, _POSE = "moveit_msgs/msg/RobotTrajectory", "moveit_msgs/msg/PlanningScene", "geometry_msgs/msg/Pose"
_HEADER, _STAMPED = "std_msgs/msg/Header", "geometry_msgs/msg/PoseStamped"
#: moveit_msgs 2.6 (ROS 2 Jazzy), octomap_msgs and object_recognition_msgs (ros2 branches), field by field.
UPSTREAM = {
    "moveit_msgs/srv/GetPositionIK_Request": [("ik_request", "moveit_msgs/msg/PositionIKRequest")],
    "moveit_msgs/srv/GetPositionIK_Response": [("solution", _RS), ("error_code", _EC)],
    "moveit_msgs/msg/PositionIKRequest": [
        ("group_name", "string"), ("robot_state", _RS), ("constraints", _C), ("avoid_collisions", "bool"),
        ("ik_link_name", "string"), ("pose_stamped", _STAMPED), ("ik_link_names", "string[]"),
        ("pose_stamped_vector", f"{_STAMPED}[]"), ("timeout", "builtin_interfaces/msg/Duration")],
    "moveit_msgs/srv/GetPositionFK_Request": [
        ("header", _HEADER), ("fk_link_names", "string[]"), ("robot_state", _RS)],
    "moveit_msgs/srv/GetPositionFK_Response": [
        ("pose_stamped", f"{_STAMPED}[]"), ("fk_link_names", "string[]"), ("error_code", _EC)],
    "moveit_msgs/srv/GetMotionPlan_Request": [("motion_plan_request", "moveit_msgs/msg/MotionPlanRequest")],
    "moveit_msgs/srv/GetMotionPlan_Response": [("motion_plan_response", "moveit_msgs/msg/MotionPlanResponse")],
    "moveit_msgs/msg/MotionPlanRequest": [
        ("workspace_parameters", "moveit_msgs/msg/WorkspaceParameters"), ("start_state", _RS),
        ("goal_constraints", f"{_C}[]"), ("path_constraints", _C),
        ("trajectory_constraints", "moveit_msgs/msg/TrajectoryConstraints"),
        ("reference_trajectories", "moveit_msgs/msg/GenericTrajectory[]"), ("pipeline_id", "string"),
        ("planner_id", "string"), ("group_name", "string"), ("num_planning_attempts", "int32"),
        ("allowed_planning_time", "float64"), ("max_velocity_scaling_factor", "float64"),
        ("max_acceleration_scaling_factor", "float64"), ("cartesian_speed_limited_link", "string"),
        ("max_cartesian_speed", "float64")],
    "moveit_msgs/msg/MotionPlanResponse": [
        ("trajectory_start", _RS), ("group_name", "string"), ("trajectory", _RT), ("planning_time", "float64"),
        ("error_code", _EC)],
    "moveit_msgs/srv/GetMotionSequence_Request": [("request", "moveit_msgs/msg/MotionSequenceRequest")],
    "moveit_msgs/srv/GetMotionSequence_Response": [("response", "moveit_msgs/msg/MotionSequenceResponse")],
    "moveit_msgs/msg/MotionSequenceRequest": [("items", "moveit_msgs/msg/MotionSequenceItem[]")],
    "moveit_msgs/msg/MotionSequenceItem": [("req", "moveit_msgs/msg/MotionPlanRequest"), ("blend_radius", "float64")],
    "moveit_msgs/msg/MotionSequenceResponse": [
        ("error_code", _EC), ("sequence_start", _RS), ("planned_trajectories", f"{_RT}[]"),
        ("planning_time", "float64")],
    "moveit_msgs/srv/GetCartesianPath_Request": [
        ("header", _HEADER), ("start_state", _RS), ("group_name", "string"), ("link_name", "string"),
        ("waypoints", f"{_POSE}[]"), ("max_step", "float64"), ("jump_threshold", "float64"),
        ("prismatic_jump_threshold", "float64"), ("revolute_jump_threshold", "float64"),
        ("avoid_collisions", "bool"), ("path_constraints", _C), ("max_velocity_scaling_factor", "float64"),
        ("max_acceleration_scaling_factor", "float64"), ("cartesian_speed_limited_link", "string"),
        ("max_cartesian_speed", "float64")],
    "moveit_msgs/srv/GetCartesianPath_Response": [
        ("start_state", _RS), ("solution", _RT), ("fraction", "float64"), ("error_code", _EC)],
    f"{EXECUTE}_Goal": [("trajectory", _RT), ("controller_names", "string[]")],
    f"{EXECUTE}_Result": [("error_code", _EC)],
    f"{EXECUTE}_Feedback": [("state", "string")],
    f"{EXECUTE}_SendGoal_Request": [("goal_id", "unique_identifier_msgs/msg/UUID"), ("goal", f"{EXECUTE}_Goal")],
    f"{EXECUTE}_SendGoal_Response": [("accepted", "bool"), ("stamp", "builtin_interfaces/msg/Time")],
    f"{EXECUTE}_GetResult_Request": [("goal_id", "unique_identifier_msgs/msg/UUID")],
    f"{EXECUTE}_GetResult_Response": [("status", "int8"), ("result", f"{EXECUTE}_Result")],
    f"{EXECUTE}_FeedbackMessage": [
        ("goal_id", "unique_identifier_msgs/msg/UUID"), ("feedback", f"{EXECUTE}_Feedback")],
    "moveit_msgs/srv/ApplyPlanningScene_Request": [("scene", _PS)],
    "moveit_msgs/srv/ApplyPlanningScene_Response": [("success", "bool")],
    "moveit_msgs/srv/GetPlanningScene_Request": [("components", "moveit_msgs/msg/PlanningSceneComponents")],
    "moveit_msgs/srv/GetPlanningScene_Response": [("scene", _PS)],
    "moveit_msgs/msg/PlanningSceneComponents": [("components", "uint32")],
    _EC: [("val", "int32"), ("message", "string"), ("source", "string")],
    _RS: [("joint_state", "sensor_msgs/msg/JointState"),
          ("multi_dof_joint_state", "sensor_msgs/msg/MultiDOFJointState"),
          ("attached_collision_objects", "moveit_msgs/msg/AttachedCollisionObject[]"), ("is_diff", "bool")],
    _RT: [("joint_trajectory", "trajectory_msgs/msg/JointTrajectory"),
          ("multi_dof_joint_trajectory", "trajectory_msgs/msg/MultiDOFJointTrajectory")],
    _C: [("name", "string"), ("joint_constraints", "moveit_msgs/msg/JointConstraint[]"),
         ("position_constraints", "moveit_msgs/msg/PositionConstraint[]"),
         ("orientation_constraints", "moveit_msgs/msg/OrientationConstraint[]"),
         ("visibility_constraints", "moveit_msgs/msg/VisibilityConstraint[]")],
    _PS: [("name", "string"), ("robot_state", _RS), ("robot_model_name", "string"),
          ("fixed_frame_transforms", "geometry_msgs/msg/TransformStamped[]"),
          ("allowed_collision_matrix", "moveit_msgs/msg/AllowedCollisionMatrix"),
          ("link_padding", "moveit_msgs/msg/LinkPadding[]"), ("link_scale", "moveit_msgs/msg/LinkScale[]"),
          ("object_colors", "moveit_msgs/msg/ObjectColor[]"), ("world", "moveit_msgs/msg/PlanningSceneWorld"),
          ("is_diff", "bool")],
    "moveit_msgs/msg/PlanningSceneWorld": [
        ("collision_objects", "moveit_msgs/msg/CollisionObject[]"), ("octomap", "octomap_msgs/msg/OctomapWithPose")],
    "moveit_msgs/msg/AttachedCollisionObject": [
        ("link_name", "string"), ("object", "moveit_msgs/msg/CollisionObject"), ("touch_links", "string[]"),
        ("detach_posture", "trajectory_msgs/msg/JointTrajectory"), ("weight", "float64")],
    "moveit_msgs/msg/CollisionObject": [
        ("header", _HEADER), ("pose", _POSE), ("id", "string"), ("type", "object_recognition_msgs/msg/ObjectType"),
        ("primitives", "shape_msgs/msg/SolidPrimitive[]"), ("primitive_poses", f"{_POSE}[]"),
        ("meshes", "shape_msgs/msg/Mesh[]"), ("mesh_poses", f"{_POSE}[]"), ("planes", "shape_msgs/msg/Plane[]"),
        ("plane_poses", f"{_POSE}[]"), ("subframe_names", "string[]"), ("subframe_poses", f"{_POSE}[]"),
        ("operation", "byte")],
    "octomap_msgs/msg/OctomapWithPose": [
        ("header", _HEADER), ("origin", _POSE), ("octomap", "octomap_msgs/msg/Octomap")],
    "octomap_msgs/msg/Octomap": [
        ("header", _HEADER), ("binary", "bool"), ("id", "string"), ("resolution", "float64"), ("data", "int8[]")],
    "object_recognition_msgs/msg/ObjectType": [("key", "string"), ("db", "string")],
}
UPSTREAM_CONSTANTS = {
    _EC: [("SUCCESS", "int32", 1), ("UNDEFINED", "int32", 0), ("FAILURE", "int32", 99999),
          ("PLANNING_FAILED", "int32", -1), ("INVALID_MOTION_PLAN", "int32", -2),
          ("MOTION_PLAN_INVALIDATED_BY_ENVIRONMENT_CHANGE", "int32", -3), ("CONTROL_FAILED", "int32", -4),
          ("UNABLE_TO_AQUIRE_SENSOR_DATA", "int32", -5), ("TIMED_OUT", "int32", -6), ("PREEMPTED", "int32", -7),
          ("START_STATE_IN_COLLISION", "int32", -10), ("START_STATE_VIOLATES_PATH_CONSTRAINTS", "int32", -11),
          ("START_STATE_INVALID", "int32", -26), ("GOAL_IN_COLLISION", "int32", -12),
          ("GOAL_VIOLATES_PATH_CONSTRAINTS", "int32", -13), ("GOAL_CONSTRAINTS_VIOLATED", "int32", -14),
          ("GOAL_STATE_INVALID", "int32", -27), ("UNRECOGNIZED_GOAL_TYPE", "int32", -28),
          ("INVALID_GROUP_NAME", "int32", -15), ("INVALID_GOAL_CONSTRAINTS", "int32", -16),
          ("INVALID_ROBOT_STATE", "int32", -17), ("INVALID_LINK_NAME", "int32", -18),
          ("INVALID_OBJECT_NAME", "int32", -19), ("FRAME_TRANSFORM_FAILURE", "int32", -21),
          ("COLLISION_CHECKING_UNAVAILABLE", "int32", -22), ("ROBOT_STATE_STALE", "int32", -23),
          ("SENSOR_INFO_STALE", "int32", -24), ("COMMUNICATION_FAILURE", "int32", -25), ("CRASH", "int32", -29),
          ("ABORT", "int32", -30), ("NO_IK_SOLUTION", "int32", -31)],
    "moveit_msgs/msg/PlanningSceneComponents": [
        ("SCENE_SETTINGS", "uint32", 1), ("ROBOT_STATE", "uint32", 2), ("ROBOT_STATE_ATTACHED_OBJECTS", "uint32", 4),
        ("WORLD_OBJECT_NAMES", "uint32", 8), ("WORLD_OBJECT_GEOMETRY", "uint32", 16), ("OCTOMAP", "uint32", 32),
        ("TRANSFORMS", "uint32", 64), ("ALLOWED_COLLISION_MATRIX", "uint32", 128),
        ("LINK_PADDING_AND_SCALING", "uint32", 256), ("OBJECT_COLORS", "uint32", 512)],
    "moveit_msgs/msg/CollisionObject": [("ADD", "byte", 0), ("REMOVE", "byte", 1), ("APPEND", "byte", 2),
                                        ("MOVE", "byte", 3)],
}


@pytest.mark.parametrize("ros_type", sorted(UPSTREAM))
def test_definitions_match_upstream(ros_type: str) -> None:
    assert fields_of(ros_type) == UPSTREAM[ros_type]
    assert sorted(constants_of(ros_type)) == sorted(UPSTREAM_CONSTANTS.get(ros_type, []))


def test_constants_are_struct_attributes() -> None:
    """Every error code is a class attribute of the struct, none a field on the wire."""
    codes = LIB.message(_EC)
    assert {name: getattr(codes, name) for name, _, _ in UPSTREAM_CONSTANTS[_EC]} == \
        {name: value for name, _, value in UPSTREAM_CONSTANTS[_EC]}
    assert list(codes.__dataclass_fields__) == ["val", "message", "source"]
    assert LIB.message("moveit_msgs/msg/CollisionObject").REMOVE == 1


# -- type hashes ---------------------------------------------------------------------------------------------
#: RIHS01 hashes rosidl generates for moveit_msgs 2.6 and the packages it uses (ROS 2 Jazzy).
ROSIDL_HASHES = {
    "moveit_msgs/srv/GetPositionIK_Request": "2fc6ac96ee9a8523466c443f06e7c76c47bd3e6b8698edc517ea82cf0b56e747",
    "moveit_msgs/srv/GetPositionIK_Response": "e80acd352080518d3498cc09f4dd84e0303e31128237de11d4019c8a5937b19f",
    "moveit_msgs/srv/GetCartesianPath_Request": "f82f5681778f78140f106beefcea74d2ce34c5e4bb048b56c90758e0d2d41384",
    "moveit_msgs/srv/GetCartesianPath_Response": "e2dc0013e5a4c0893c54b13b0efa5997041852006a5bafdb44e11224a4cfa46b",
    "moveit_msgs/srv/ApplyPlanningScene_Request": "4303c6065226e57f263fe7e1c03df94ea3ddbc120001cbbc4e757d7801da0a56",
    "moveit_msgs/srv/ApplyPlanningScene_Response": "8e618d93f6779a2e3f95d84c363f8cc996297b586b683a53750879506e8eaaf1",
    "moveit_msgs/srv/GetPlanningScene_Request": "ac8ce45f7638bcc6d6661f66e836e4edd218107682f68e3292dac1f79f29c1ec",
    "moveit_msgs/srv/GetPlanningScene_Response": "8a2b63777b386eeffec08730a19dae73e4950fec294825d9d53f24b935e6ec95",
    f"{EXECUTE}_Goal": "5b0ac306302a16ab731a815136d6d131f49acf24227f38ff7efe2cc485c79b9f",
    f"{EXECUTE}_Result": "6b2dc870165c972c3ab2c8c39b1988d80bf59d4bced20309ffe3a6a670760af3",
    _EC: "dcda8a9950cf6dd6ac221c2c0d2509f52f136afa0403dd19beacdf07e83e4a07",
    _RS: "7c516dc15713e545cb2836c5ca745fbdcfcc10de4855a41c83e6b4bf1afc3f83",
    _RT: "af1dc87fb94d13e5f233e9c210d2662fa06143a8b3c6aec47c57ad45074fcce8",
    _C: "71718200459ae8fecdc4f2c9631215f7eba5ff686c701a32e231ba8b11b3592b",
    _PS: "0f58540ad5eab4b9ea827d53b763c793d8cabd202b3b301fcee25afa4ce1bd80",
    "moveit_msgs/msg/PositionIKRequest": "200709be614f71f4d11d0bdd672785db28d27f7a10b516d9b961706a0c7f6d7d",
    "moveit_msgs/msg/PlanningSceneComponents": "76b77cb53f7a0b680d46fad6c0056d3710a74ec335dd5f361f3df62383313d69",
    "moveit_msgs/msg/CollisionObject": "74b0acd6d56be032bf4f764b2c2633f50588b5fb2bd71e97206c59052747cf7e",
    "octomap_msgs/msg/Octomap": "9891a19a05b70ec20aa8f45db3f8300b9ab80afff32c61c549d25087da9625b0",
    "octomap_msgs/msg/OctomapWithPose": "e65f8760aa96a2acef86b6d206175cfc78420082b6159dd3fa6ebf93f5f81979",
    "object_recognition_msgs/msg/ObjectType": "5eb3ee3976403366d7c50d7dbee8bec96b3bced1e752674a7194a35841632134",
}


@pytest.mark.parametrize("ros_type", sorted(ROSIDL_HASHES))
def test_type_hashes_match_rosidl(ros_type: str) -> None:
    """The hash plem announces is the one a MoveIt node computes, so ROS 2 tools accept plem's endpoints."""
    assert LIB.type_hash(ros_type) == f"RIHS01_{ROSIDL_HASHES[ros_type]}"


# -- loading on demand ---------------------------------------------------------------------------------------
def _loaded(library: InterfaceLibrary) -> set[str]:
    return {name.split("/")[0] for name in library.store.fielddefs} & ON_DEMAND


def test_moveit_packages_load_when_first_asked_for() -> None:
    """A new library holds none of them; the first hash asked for brings in the packages its types use."""
    fresh = InterfaceLibrary()
    assert _loaded(fresh) == set()
    assert fresh.known("std_msgs/msg/String") and _loaded(fresh) == set()
    request = "moveit_msgs/srv/GetPlanningScene_Response"
    assert fresh.type_hash(request) == f"RIHS01_{ROSIDL_HASHES[request]}"
    assert _loaded(fresh) == ON_DEMAND


def test_unknown_type_of_an_on_demand_package() -> None:
    """Asking for a type the package lacks loads the package once and answers no."""
    fresh = InterfaceLibrary()
    assert not fresh.known("octomap_msgs/msg/NoSuchType")
    assert _loaded(fresh) == {"octomap_msgs"}
    assert fresh.known("octomap_msgs/msg/Octomap")
    assert not fresh.known("moveit_msgs/srv/NoSuchService_Request")
    assert _loaded(fresh) == ON_DEMAND


def test_first_requests_from_many_threads() -> None:
    """Threads that ask for MoveIt types at the same moment all get whole definitions."""
    fresh = InterfaceLibrary()
    request = "moveit_msgs/srv/GetCartesianPath_Request"
    start = threading.Barrier(8)
    hashes: list[str] = []
    failures: list[BaseException] = []

    def ask() -> None:
        start.wait()
        try:
            hashes.append(fresh.type_hash(request))
        except BaseException as error:  # noqa: BLE001 - reported by the assertion below
            failures.append(error)

    threads = [threading.Thread(target=ask) for _ in range(8)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert failures == []
    assert hashes == [f"RIHS01_{ROSIDL_HASHES[request]}"] * 8


def test_threads_building_a_struct_at_once_get_one_class() -> None:
    """Two classes for one type would be two DDS types to Cyclone: every thread must get the same."""
    fresh = InterfaceLibrary()
    start = threading.Barrier(8)
    built: list[type] = []

    def build() -> None:
        start.wait()
        built.append(fresh.service_part("moveit_msgs/srv/GetMotionPlan_Request"))

    threads = [threading.Thread(target=build) for _ in range(8)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert len(built) == 8 and len(set(built)) == 1


def test_struct_of_an_on_demand_type_in_a_new_library() -> None:
    """Structs nest across the on-demand packages: a planning scene reply holds an octomap."""
    fresh = InterfaceLibrary()
    reply: Any = fresh.service_part("moveit_msgs/srv/GetPlanningScene_Response")(rmw_seq=3)
    reply.scene.world.octomap.octomap.data.extend([-128, 127])
    assert fresh.service_part("moveit_msgs/srv/GetPlanningScene_Response").deserialize(
        reply.serialize()).scene.world.octomap.octomap.data == [-128, 127]
