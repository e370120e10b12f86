"""Where a payload is configured: the launch argument `payload:=` and a robot profile's `payload` field."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from plem.control.payload import Payload
from plem.errors import ConfigError, ProfileError
from plem.launch.arguments import DEFAULTS, help_text, parse, payload
from plem.launch.plan import plan_robot
from plem.robot import RobotProfile


def test_the_launch_argument_gives_a_payload_or_none():
    assert DEFAULTS["payload"] == "" and "payload:=" in help_text()
    assert payload(parse(["payload:=1.5,0,0,0.05"])["payload"]) == Payload(1.5, (0.0, 0.0, 0.05))
    assert payload("") is None
    assert payload("2, 0.01,0,0.1, 0.01,0,0,0.02,0,0.02").inertia == ((0.01, 0, 0), (0, 0.02, 0), (0, 0, 0.02))


@pytest.mark.parametrize(("text", "why"), [
    ("1.5 0 0 0.05", "not a list of plain numbers"),
    ("1e3,0,0,0", "not a list of plain numbers"),
    ("1,0,0", "3 numbers"),
    ("-1,0,0,0", "mass -1 kg"),
    ("1,0,0,3", "3 m from the flange"),
    ("1,0,0,0,1,0,0,1,0,5", "triangle inequality"),
])
def test_a_bad_launch_argument_says_what_to_give(text: str, why: str):
    with pytest.raises(ConfigError) as error:
        payload(text)
    assert error.value.summary == f"invalid launch argument payload:={text}"
    assert why in error.value.why
    assert "payload:=1.5,0,0,0.05" in error.value.how


def test_a_profile_keeps_its_payload(tmp_path: Path):
    path = tmp_path / "A1.json"
    written = {"mass": 2.0, "center_of_mass": [0.0, 0.01, 0.1], "inertia": [0.01, 0, 0, 0.02, 0, 0.02]}
    RobotProfile.model_validate({"robot_serial": "A1", "joint_offsets": [0] * 6, "payload": written}).save(path)
    profile = RobotProfile.load(path)
    assert json.loads(path.read_text())["payload"] == written
    assert profile.payload is not None
    assert profile.payload.to_payload() == Payload(2.0, (0.0, 0.01, 0.1), [[0.01, 0, 0], [0, 0.02, 0], [0, 0, 0.02]])


def test_a_profile_without_payload_has_none_and_writes_none(tmp_path: Path):
    path = tmp_path / "A1.json"
    RobotProfile(robot_serial="A1", joint_offsets=[0] * 6).save(path)
    assert RobotProfile.load(path).payload is None and "payload" not in json.loads(path.read_text())


@pytest.mark.parametrize(("payload_field", "why"), [
    ({"mass": 500, "center_of_mass": [0, 0, 0]}, "payload: mass 500 kg is not between 0 and 100 kg"),
    ({"mass": 1, "center_of_mass": [0, 0]}, "payload: the centre of mass has 2 values, not 3"),
    ({"mass": 1, "inertia": [1, 0, 0]}, "payload inertia has 3 values, not 6"),
    ({"mass": 1, "inertia": [1, 0, 0, -1, 0, 1]}, "payload: the inertia is not positive semi-definite"),
    ({"mass": "heavy"}, "payload.mass: input should be a valid number"),
    ({"mass": 1, "colour": "red"}, "payload.colour: extra inputs are not permitted"),
])
def test_a_profile_with_a_payload_no_arm_can_carry_is_refused(tmp_path: Path, payload_field: dict[str, object],
                                                              why: str):
    path = tmp_path / "A1.json"
    path.write_text(json.dumps({"robot_serial": "A1", "joint_offsets": [0] * 6, "payload": payload_field}))
    with pytest.raises(ProfileError) as error:
        RobotProfile.load(path)
    assert why in error.value.why
    with pytest.raises((ProfileError, ValueError)):
        RobotProfile.model_validate({"robot_serial": "A1", "joint_offsets": [0] * 6,
                                     "payload": payload_field}).save(tmp_path / "B.json")


def test_a_launch_refuses_a_bad_payload_before_starting_and_gives_a_good_one():
    with pytest.raises(ConfigError) as error:
        plan_robot({"bus": "mock", "payload": "1,0,0,3"}, generate=False)
    assert "payload:=1,0,0,3" in error.value.render() and "3 m from the flange" in error.value.render()
    assert plan_robot({"bus": "mock", "payload": "1.5,0,0,0.05"}, generate=False).payload == Payload(1.5, (0, 0, 0.05))
    assert plan_robot({"bus": "mock"}, generate=False).payload is None
