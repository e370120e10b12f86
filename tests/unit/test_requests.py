"""Requests checked identically by client and driver: every malformed payload is a CommandRejected."""

from __future__ import annotations

import contextlib
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from plem.control.limits import ArmLimits
from plem.control.modes import Mode
from plem.control.spline import JointNamesRejected
from plem.control.trajectory import TrajectoryOutcome, TrajectoryResult, TrajectoryTolerances
from plem.errors import CommandRejected, PlemError, RobotFault
from plem.ipc.requests import (
    check_request,
    decode,
    encode,
    error_from_json,
    reply,
    request_id_of,
    result_from_json,
    tolerances_json,
)

JOINTS = ("a", "b", "c")
LIMITS = ArmLimits(JOINTS, -np.ones(3), np.ones(3), np.full(3, 2.0), np.full(3, 4.0), np.full(3, 40.0),
                   np.full(3, 10.0))


def request(op: str, **args: object) -> dict:
    return {"id": "1-1-abc", "op": op, **args}


def test_valid_requests_come_back_in_the_robot_api_types():
    move = check_request(request("move_joints", target=[0.1, 0.2, 0.3], speed_scale=0.5,
                                 tolerances={"goal": [0.01, 0, 0.01]}), LIMITS)
    assert np.array_equal(move.args["target"], [0.1, 0.2, 0.3]) and move.args["speed_scale"] == 0.5
    assert math.isinf(move.args["tolerances"].goal[1])  # 0 leaves a joint unchecked, as in ROS
    trajectory = check_request(request("execute_trajectory", joint_names=["c", "a", "b"], points=[
        {"positions": [0.5, 0.1, 0.2], "time_from_start": 1.0}]), LIMITS).args["trajectory"]
    assert trajectory.joint_names == ("c", "a", "b")
    assert check_request(request("set_mode", mode="free_drive"), LIMITS).args["mode"] is Mode.FREE_DRIVE
    assert check_request(request("stop"), LIMITS).args == {}


@pytest.mark.parametrize("payload, words", [
    (request("fly"), "not a plem request"),
    ({"op": "stop"}, "request id is malformed"),
    ({"id": "x" * 5000, "op": "stop"}, "request id is malformed"),
    ({"id": "1-1-abc\n", "op": "stop"}, "request id is malformed"),
    (request("stop", goal="ü" * 3), "request id is malformed"),
    (request("stop", now=True), "unknown arguments"),
    (request("move_joints", target=[0.1, 0.2]), "got 2 values"),
    (request("move_joints", target=[0.1, float("nan"), 0.2]), "out of range"),
    (request("move_joints", target=[0.1, 10**400, 0.2]), "out of range"),
    (request("move_joints", target=[0.1, "0.2", 0.3]), "not a number"),
    (request("move_joints", target=[0.1, False, 0.3]), "not a number"),
    (request("move_joints", target=[0, 0, 0], tolerances={"goal_time": 1e306}), "goal_time is out of range"),
    (request("move_joints", target=[0, 0, 0], tolerances={"goal_time": True}), "goal_time is not a number"),
    (request("move_joints", target=[0, 0, 0], tolerances={"stopped_velocity_tolerance": 0}), "out of range"),
    (request("stop", **{f"k{i}": 1 for i in range(2000)}), "more characters"),
    (request("execute_trajectory", joint_names=["a", "b", "c"], points=[
        {"positions": [0, 0, 0], "time_from_start": i + 1} for i in range(5001)]), "too many points"),
    (request("execute_trajectory", joint_names=["a", "b", "c" * 5000], points=[
        {"positions": [0, 0, 0], "time_from_start": 1}]), "not a valid name"),
    (request("execute_trajectory", joint_names=["a", "b", "c"], points=[
        {"positions": [0, 0, 0], "time_from_start": 1e306}]), "time_from_start is out of range"),
    (request("move_joints", target=[0.1, 0.2, 0.3], speed_scale=0), "speed_scale"),
    (request("move_joints", target=[0.1, 0.2, 0.3], speed_scale=True), "speed_scale"),
    (request("move_joints", target="0.1,0.2,0.3"), "a list of 3 numbers"),
    (request("move_joints", target=[0, 0, 0], tolerances={"gaol": [1, 1, 1]}), "tolerances are malformed"),
    (request("execute_trajectory", joint_names=["a", "b"], points=[{"positions": [0, 0], "time_from_start": 1}]),
     "joints do not match"),
    (request("execute_trajectory", joint_names=["a", "b", "c"], points=[]), "no points"),
    (request("execute_trajectory", joint_names=["a", "b", "c"], points=[
        {"positions": [0, 0, 0], "time_from_start": 2}, {"positions": [0, 0, 0], "time_from_start": 1}]),
     "out of time order"),
    (request("set_mode", mode="trajectory"), "cannot be requested"),
    (request("set_mode", mode="sideways"), "unknown mode"),
])
def test_malformed_requests_are_rejected_with_the_reason(payload, words):
    with pytest.raises(CommandRejected) as caught:
        check_request(payload, LIMITS)
    assert words in caught.value.render()


def test_positions_are_checked_where_the_motion_is_planned_from_the_arms_state():
    """A request alone cannot tell a motion away from the range from one back into it: the planning step, which
    knows where the arm is, checks the positions (tests/unit/test_limits_reaching.py)."""
    move = check_request(request("move_joints", target=[0.1, 1.5, 0.2]), LIMITS)
    assert move.args["target"].tolist() == [0.1, 1.5, 0.2]
    trajectory = check_request(request("execute_trajectory", joint_names=["a", "b", "c"], points=[
        {"positions": [0, 0, 3], "time_from_start": 1}]), LIMITS)
    assert trajectory.args["trajectory"].points[0].positions == (0, 0, 3)


def test_wrong_joint_names_map_to_invalid_joints():
    with pytest.raises(JointNamesRejected):
        check_request(request("execute_trajectory", joint_names=["a", "b", "x"],
                              points=[{"positions": [0, 0, 0], "time_from_start": 1}]), LIMITS)


json_values = st.recursive(st.none() | st.booleans() | st.integers() | st.floats(allow_nan=False, allow_infinity=False)
                           | st.text(),
                           lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(), inner, max_size=4),
                           max_leaves=20)


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=200) | json_values.map(lambda v: encode({"v": v}))
       | st.fixed_dictionaries({"id": st.text(), "op": st.sampled_from(["move_joints", "execute_trajectory",
                                                                         "set_mode", "stop", "x"])},
                               optional={"target": json_values, "points": json_values, "joint_names": json_values,
                                         "mode": json_values, "speed_scale": json_values,
                                         "tolerances": json_values}).map(encode))
def test_garbage_records_only_ever_raise_command_rejected(record):
    with contextlib.suppress(CommandRejected):
        check_request(decode(record), LIMITS)


def test_replies_round_trip_results_and_errors():
    result = TrajectoryResult(TrajectoryOutcome.ABORTED, "tracking error", -4)
    error = RobotFault("the motion was aborted", what="w", why="y", how="h")
    payload = decode(reply("9-9-x", "failed", result, error))
    assert payload["stage"] == "failed" and request_id_of(payload) == "9-9-x"
    assert result_from_json(payload["result"]) == result
    rebuilt = error_from_json(payload["error"])
    assert type(rebuilt) is RobotFault and rebuilt.render() == error.render()
    assert result_from_json(decode(reply("1", "finished", Mode.HOLD))["result"]) is Mode.HOLD
    assert type(error_from_json({"error": "SomethingElse", "summary": "s"})) is PlemError


def test_non_json_and_non_objects_are_unreadable():
    for record in (b"\xff\xfe", b"[1, 2]", b"nope"):
        with pytest.raises(CommandRejected, match="unreadable request"):
            decode(record)
    with pytest.raises(CommandRejected, match="cannot be encoded"):
        encode({"target": [float("inf")]})
    for constant in (b"Infinity", b"-Infinity", b"NaN"):
        with pytest.raises(CommandRejected, match="not a JSON number"):
            decode(b'{"id": "1", "op": "move_joints", "target": [' + constant + b', 0, 0]}')


def test_a_reply_is_bounded_whatever_the_error_says():
    error = CommandRejected("s" * 10_000, what="w" * 10_000, why="y" * 10_000, how="h")
    payload = decode(reply("1-1-abc", "rejected", error=error))
    assert all(len(payload["error"][key]) <= 2000 for key in ("summary", "what", "why"))
    assert payload["error"]["why"].endswith("more characters]")


def test_tolerances_travel_as_requests_carry_them_and_come_back_the_same():
    tolerances = TrajectoryTolerances(path=np.array([0.1, 0.0, 0.2]), goal_time=math.inf)
    sent = tolerances_json(tolerances)
    assert sent["path"] == [0.1, 0.0, 0.2] and sent["goal"] is None and sent["goal_time"] == 86_400.0
    back = check_request(request("move_joints", target=[0, 0, 0], tolerances=sent), LIMITS).args["tolerances"]
    assert back.path.tolist() == [0.1, math.inf, 0.2] and back.goal_time == 86_400.0
