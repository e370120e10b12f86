"""plem's run-time DDS structs produce exactly the CDR bytes rosbags (the ROS 2 reference) produces."""

from __future__ import annotations

import re
import struct
import subprocess
import sys
from typing import Any

import numpy as np
import pytest

from tests.wire_values import ACTION_PARTS, LIB, Filler, constants_of, fields_of, plain_of, reference_bytes, to_plem

FJT = "control_msgs/action/FollowJointTrajectory"
SET_MODE = "plem_msgs/action/SetMode"
SPEED_SLIDER = "ur_msgs/srv/SetSpeedSliderFraction"
SERVICE_PARTS = [f"{action}_{part}" for action in (FJT, SET_MODE) for part in ACTION_PARTS if "_Re" in part] + [
    "action_msgs/srv/CancelGoal_Request", "action_msgs/srv/CancelGoal_Response", f"{SPEED_SLIDER}_Request",
    f"{SPEED_SLIDER}_Response"]
PLEM_MSGS = [f"plem_msgs/msg/{name}" for name in ("RtRaw", "RtEvent", "RtMonitorStats", "TimingStats", "QueueStats")]
#: Every type plem publishes or accepts on the wire.
WIRE_TYPES = [
    "sensor_msgs/msg/JointState", "std_msgs/msg/String", *PLEM_MSGS, "trajectory_msgs/msg/JointTrajectory",
    *(f"{action}_{part}" for action in (FJT, SET_MODE) for part in ACTION_PARTS),
    "action_msgs/srv/CancelGoal_Request", "action_msgs/srv/CancelGoal_Response", "action_msgs/msg/GoalStatusArray",
    "control_msgs/msg/JointJog", "geometry_msgs/msg/TwistStamped", "std_msgs/msg/Float64", f"{SPEED_SLIDER}_Request",
    f"{SPEED_SLIDER}_Response",
]
SEEDS = range(5)  # seeds 0 and 3: every sequence empty; others: empty and non-empty mixed


# -- CDR equality ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("ros_type", WIRE_TYPES)
def test_plem_bytes_equal_rosbags_bytes(ros_type: str, seed: int) -> None:
    """Same content, same CDR bytes; plem reads rosbags' bytes back to the same content."""
    plain = Filler(seed).message(ros_type)
    reference = reference_bytes(ros_type, plain)
    assert reference[:4] == b"\x00\x01\x00\x00"   # CDR little endian, as ROS 2 sends
    assert to_plem(ros_type, plain).serialize() == reference
    assert plain_of(ros_type, LIB.message(ros_type).deserialize(reference)) == plain


@pytest.mark.parametrize("ros_type", WIRE_TYPES)
def test_defaults_match_rosbags_zero_message(ros_type: str) -> None:
    """A struct built with no fields is rosbags' all-zero, all-empty message, nested structs included."""
    plain = Filler(0, zero=True).message(ros_type)
    zero = LIB.message(ros_type)()
    assert plain_of(ros_type, zero) == plain
    assert zero.serialize() == reference_bytes(ros_type, plain)


def test_filler_covers_the_edge_cases() -> None:
    """The examples hold negative ints, non-ASCII text, empty and non-empty sequences and 16-byte UUIDs."""
    seen: dict[str, bool] = {}

    def walk(value: Any) -> None:
        if isinstance(value, dict):
            for item in value.values():
                walk(item)
        elif isinstance(value, list):
            seen["empty" if not value else "non-empty"] = True
            if len(value) == 16 and all(isinstance(v, int) and 0 <= v <= 255 for v in value):
                seen["uuid"] = True
            for item in value:
                walk(item)
        elif isinstance(value, bool):
            pass
        elif isinstance(value, int) and value < 0:
            seen["negative"] = True
        elif isinstance(value, str) and not value.isascii():
            seen["non-ascii"] = True

    for seed in SEEDS:
        for ros_type in WIRE_TYPES:
            walk(Filler(seed).message(ros_type))
    assert set(seen) == {"empty", "non-empty", "uuid", "negative", "non-ascii"}


# -- rmw_cyclonedds's request header -------------------------------------------------------------------------
@pytest.mark.parametrize("ros_type", SERVICE_PARTS)
def test_service_part_is_rmw_header_then_fields(ros_type: str) -> None:
    """Requests and replies: encapsulation, uint64 writer guid, int64 sequence, then the fields."""
    guid, sequence = 0xF1E2_D3C4_B5A6_9788, 0x0123_4567_89AB
    plain = Filler(7).message(ros_type)
    reference = reference_bytes(ros_type, plain)
    expected = reference[:4] + struct.pack("<Qq", guid, sequence) + reference[4:]
    wire = to_plem(ros_type, plain, with_header=True, rmw_guid=guid, rmw_seq=sequence).serialize()
    assert wire == expected
    back = LIB.service_part(ros_type).deserialize(expected)
    assert (back.rmw_guid, back.rmw_seq) == (guid, sequence)
    assert plain_of(ros_type, back) == plain


def test_send_goal_request_and_get_result_reply_layout() -> None:
    """The two action calls the brief names, spelled out: header bytes sit right after the encapsulation."""
    for ros_type in (f"{FJT}_SendGoal_Request", f"{SET_MODE}_GetResult_Response"):
        plain = Filler(1).message(ros_type)
        wire = to_plem(ros_type, plain, with_header=True, rmw_guid=2**64 - 1, rmw_seq=42).serialize()
        assert wire[4:20] == b"\xff" * 8 + (42).to_bytes(8, "little")
        assert wire[20:] == reference_bytes(ros_type, plain)[4:]


# -- the definitions plem ships for standard packages match upstream -----------------------------------------
_JTP, _MJTP = "trajectory_msgs/msg/JointTrajectoryPoint", "trajectory_msgs/msg/MultiDOFJointTrajectoryPoint"
#: control_msgs (Jazzy, 5.x) and action_msgs as ROS 2 publishes them.
UPSTREAM = {
    f"{FJT}_Goal": [
        ("trajectory", "trajectory_msgs/msg/JointTrajectory"),
        ("multi_dof_trajectory", "trajectory_msgs/msg/MultiDOFJointTrajectory"),
        ("path_tolerance", "control_msgs/msg/JointTolerance[]"),
        ("component_path_tolerance", "control_msgs/msg/JointComponentTolerance[]"),
        ("goal_tolerance", "control_msgs/msg/JointTolerance[]"),
        ("component_goal_tolerance", "control_msgs/msg/JointComponentTolerance[]"),
        ("goal_time_tolerance", "builtin_interfaces/msg/Duration"),
    ],
    f"{FJT}_Result": [("error_code", "int32"), ("error_string", "string")],
    f"{FJT}_Feedback": [
        ("header", "std_msgs/msg/Header"), ("joint_names", "string[]"),
        ("desired", _JTP), ("actual", _JTP), ("error", _JTP),
        ("multi_dof_joint_names", "string[]"),
        ("multi_dof_desired", _MJTP), ("multi_dof_actual", _MJTP), ("multi_dof_error", _MJTP),
    ],
    "control_msgs/msg/JointTolerance": [
        ("name", "string"), ("position", "float64"), ("velocity", "float64"), ("acceleration", "float64")],
    "control_msgs/msg/JointComponentTolerance": [
        ("joint_name", "string"), ("component", "uint16"), ("position", "float64"), ("velocity", "float64"),
        ("acceleration", "float64")],
    "action_msgs/srv/CancelGoal_Request": [("goal_info", "action_msgs/msg/GoalInfo")],
    "control_msgs/msg/JointJog": [("header", "std_msgs/msg/Header"), ("joint_names", "string[]"),
                                  ("displacements", "float64[]"), ("velocities", "float64[]"), ("duration", "float64")],
    f"{SPEED_SLIDER}_Request": [("speed_slider_fraction", "float64")],
    f"{SPEED_SLIDER}_Response": [("success", "bool")],
    "action_msgs/srv/CancelGoal_Response": [
        ("return_code", "int8"), ("goals_canceling", "action_msgs/msg/GoalInfo[]")],
}
UPSTREAM_CONSTANTS = {
    f"{FJT}_Result": [("SUCCESSFUL", "int32", 0), ("INVALID_GOAL", "int32", -1), ("INVALID_JOINTS", "int32", -2),
                      ("OLD_HEADER_TIMESTAMP", "int32", -3), ("PATH_TOLERANCE_VIOLATED", "int32", -4),
                      ("GOAL_TOLERANCE_VIOLATED", "int32", -5)],
    "control_msgs/msg/JointComponentTolerance": [("X_AXIS", "uint16", 1), ("Y_AXIS", "uint16", 2),
                                                 ("Z_AXIS", "uint16", 3), ("TRANSLATION", "uint16", 4),
                                                 ("ROTATION", "uint16", 5)],
    "action_msgs/srv/CancelGoal_Response": [("ERROR_NONE", "int8", 0), ("ERROR_REJECTED", "int8", 1),
                                            ("ERROR_UNKNOWN_GOAL_ID", "int8", 2),
                                            ("ERROR_GOAL_TERMINATED", "int8", 3)],
}


@pytest.mark.parametrize("ros_type", sorted(UPSTREAM))
def test_shipped_definitions_match_upstream(ros_type: str) -> None:
    assert fields_of(ros_type) == UPSTREAM[ros_type]
    assert sorted(constants_of(ros_type)) == sorted(UPSTREAM_CONSTANTS.get(ros_type, []))


def test_action_wrappers_follow_rosidl() -> None:
    """The parts rosidl adds around every action's goal, result and feedback."""
    for action in (FJT, SET_MODE):
        assert fields_of(f"{action}_SendGoal_Request") == [
            ("goal_id", "unique_identifier_msgs/msg/UUID"), ("goal", f"{action}_Goal")]
        assert fields_of(f"{action}_SendGoal_Response") == [("accepted", "bool"),
                                                             ("stamp", "builtin_interfaces/msg/Time")]
        assert fields_of(f"{action}_GetResult_Request") == [("goal_id", "unique_identifier_msgs/msg/UUID")]
        assert fields_of(f"{action}_GetResult_Response") == [("status", "int8"), ("result", f"{action}_Result")]
        assert fields_of(f"{action}_FeedbackMessage") == [
            ("goal_id", "unique_identifier_msgs/msg/UUID"), ("feedback", f"{action}_Feedback")]
    assert fields_of("unique_identifier_msgs/msg/UUID") == [("uuid", "uint8[16]")]


def test_plem_struct_constants() -> None:
    """Constants become class attributes of the struct, not fields on the wire."""
    raw = LIB.message("plem_msgs/msg/RtRaw")
    assert (raw.MODE_IDLE, raw.MODE_FAULT) == (0, 4)
    assert LIB.message("action_msgs/srv/CancelGoal_Response").ERROR_UNKNOWN_GOAL_ID == 2
    assert "MODE_IDLE" not in raw.__dataclass_fields__


# -- type hashes ---------------------------------------------------------------------------------------------
RIHS01 = re.compile(r"RIHS01_[0-9a-f]{64}")


def test_type_hash_format_and_a_known_value() -> None:
    assert RIHS01.fullmatch(LIB.type_hash("sensor_msgs/msg/JointState"))
    # Published by ROS 2 Iron and later for std_msgs/msg/String.
    assert LIB.type_hash("std_msgs/msg/String") == \
        "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"


def test_plem_msgs_hashes_are_deterministic_and_distinct() -> None:
    """Same hashes in a fresh process with another hash seed; no two plem types share one."""
    ros_types = [*PLEM_MSGS, *(f"{SET_MODE}_{part}" for part in ACTION_PARTS)]
    here = [LIB.type_hash(ros_type) for ros_type in ros_types]
    assert all(RIHS01.fullmatch(value) for value in here)
    assert len(set(here)) == len(here)
    code = ("import sys; from plem.middleware.types import InterfaceLibrary; lib = InterfaceLibrary(); "
            "print('\\n'.join(lib.type_hash(t) for t in sys.argv[1:]))")
    fresh = subprocess.run([sys.executable, "-c", code, *ros_types], capture_output=True, text=True, timeout=60,
                           env={"PYTHONHASHSEED": "12345", "PATH": "/usr/bin:/bin"}, check=True)
    assert fresh.stdout.split() == here


def test_defaults_are_not_shared_between_instances() -> None:
    """Each new struct gets its own nested structs, lists and fixed arrays."""
    first, second = LIB.message(f"{FJT}_SendGoal_Request")(), LIB.message(f"{FJT}_SendGoal_Request")()
    first.goal.trajectory.joint_names.append("j1")
    first.goal.trajectory.header.frame_id = "base"
    first.goal_id.uuid[0] = 7
    assert second.goal.trajectory.joint_names == []
    assert second.goal.trajectory.header.frame_id == ""
    assert list(second.goal_id.uuid) == [0] * 16


@pytest.mark.parametrize("dof", [6, 7])
def test_fast_rt_raw_encoder_matches_both_serializers(dof: int) -> None:
    """The bridge's fixed-layout RtRaw encoder gives the struct's and rosbags' bytes, huge latencies clamped."""
    from plem.middleware.raw_cdr import RawEncoder

    rng = np.random.default_rng(dof)
    record = np.concatenate([[2**40 + 7, 123_456_789_012, 4, 1, 0, 2.0**33, 250_000], rng.normal(size=6 * dof), [0.25]])
    wall_ns = 1_795_000_000_987_654_321
    rows = record[7:-1].reshape(6, dof).tolist()
    plain = {"header": {"stamp": {"sec": wall_ns // 10**9, "nanosec": wall_ns % 10**9}, "frame_id": ""},
             "cycle": 2**40 + 7, "monotonic_ns": 123_456_789_012, "mode": 4, "faulted": True,
             "drives_enabled": False, "latency_ns": 0xFFFFFFFF, "compute_ns": 250_000,
             **dict(zip(("position", "velocity", "effort", "command_position", "command_velocity",
                         "command_acceleration"), rows, strict=False)), "speed_override": 0.25}
    encoded = RawEncoder(dof).encode(record, wall_ns)
    assert encoded == to_plem("plem_msgs/msg/RtRaw", plain).serialize()
    assert encoded == reference_bytes("plem_msgs/msg/RtRaw", plain)
