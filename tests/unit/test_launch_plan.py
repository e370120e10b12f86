"""`plem launch` arguments: parsing, checks collected before anything starts, robots files."""

from __future__ import annotations

import pytest

from plem.errors import ConfigError, MultipleErrors, UsageError
from plem.launch.arguments import DEFAULTS, NAMES, help_text, parse
from plem.launch.plan import plan_robot
from plem.launch.robots_file import load_robots

SPEC_ARGUMENTS = ("eth_interface", "robot_type", "description_package", "urdf_file", "srdf_file", "robot_name",
                  "record", "bag_dir", "retention_minutes", "disk_threshold", "robot_id")


def test_every_spec_argument_is_known_with_its_spec_default():
    assert set(SPEC_ARGUMENTS) <= set(NAMES) and {"bus", "rt_priority", "cycle_time"} <= set(NAMES)
    assert DEFAULTS["robot_id"] == "indy" and DEFAULTS["record"] == "true" and DEFAULTS["disk_threshold"] == "70"
    assert DEFAULTS["retention_minutes"] == "60" and DEFAULTS["bag_dir"] == "~/bags/rt_monitoring"
    assert DEFAULTS["bus"] == "ethercat" and DEFAULTS["description_package"] == "wim_description"
    text = help_text()
    for name in NAMES:
        assert f"{name}:=" in text


def test_both_argument_spellings_parse():
    assert parse(["bus:=mock", "--robot_id", "arm", "--rt-priority=80"]) == {"bus": "mock", "robot_id": "arm",
                                                                              "rt_priority": "80"}
    with pytest.raises(UsageError, match="Unknown argument 'buss'"):
        parse(["buss:=mock"])


def test_plan_of_the_builtin_arm_resolves_package_config_and_poses():
    plan = plan_robot({"bus": "mock", "robot_type": "indy7_v2", "rt_priority": "80"}, generate=False)
    assert plan.package.name == "indy7_v2_description" and plan.config.rt_priority == 80
    assert plan.robot_id == "indy" and plan.robot_name == "indy7_v2" and plan.record
    poses = plan.poses(("joint0", "joint1", "joint2", "joint3", "joint4", "joint5"))
    assert poses["home"] == [0, 0, -1.570796, 0, -1.570796, 0] and poses["zero"] == [0.0] * 6


def test_all_bad_launch_arguments_are_reported_together():
    with pytest.raises(MultipleErrors) as caught:
        plan_robot({"bus": "can", "record": "maybe", "disk_threshold": "150", "retention_minutes": "-1",
                    "shm_group": "no_such_group_xyz"}, generate=False)
    text = caught.value.render()
    for words in ("bus:=can", "record:=maybe", "disk_threshold:=150", "retention_minutes:=-1", "shm_group"):
        assert words in text


def test_config_overrides_go_through_the_config_checks():
    with pytest.raises(ConfigError, match="rt_priority"):
        plan_robot({"bus": "mock", "rt_priority": "99"}, generate=False)


def test_robots_file_merges_command_line_and_entries(tmp_path):
    path = tmp_path / "robots.yaml"
    path.write_text("robots:\n  - {robot_id: left, bus: mock}\n  - {robot_id: right, record: false}\n")
    robots = load_robots(path, {"bus": "ethercat", "rt_priority": "80", "robots": str(path)})
    assert robots == [{"bus": "mock", "rt_priority": "80", "robot_id": "left"},
                      {"bus": "ethercat", "rt_priority": "80", "robot_id": "right", "record": "false"}]


@pytest.mark.parametrize("text, words", [
    ("robots: []\n", "lists no robots"),
    ("- a\n", "lists no robots"),
    ("robots:\n  - {bus: mock}\n", "has no robot_id"),
    ("robots:\n  - {robot_id: a}\n  - {robot_id: a}\n", "appears twice"),
    ("robots:\n  - {robot_id: a, colour: red}\n", "unknown keys"),
    ("robots: [\n", "not valid YAML"),
])
def test_bad_robots_files_are_explained(tmp_path, text, words):
    path = tmp_path / "robots.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=words):
        load_robots(path, {})
    with pytest.raises(ConfigError, match="cannot read"):
        load_robots(tmp_path / "missing.yaml", {})


@pytest.mark.parametrize(("text", "expected"), [
    ("controller_manager:\n  ros__parameters:\n    update_rate: 50\n", 50.0),
    ("controller_manager:\n  ros__parameters:\n    update_rate: 500\n", 100.0),   # capped
    ("controller_manager: not a mapping\n", 100.0),                               # loop rate, capped
    ("- a list\n", 100.0),
])
def test_joint_state_rate_follows_controllers_yaml_capped(tmp_path, text, expected):
    plan = plan_robot({"bus": "mock", "robot_type": "indy7_v2"}, generate=False)
    controllers = tmp_path / "controllers.yaml"
    controllers.write_text(text)
    plan.report.files.controllers = controllers
    assert plan.joint_state_rate() == expected


def test_joint_state_rate_argument_wins_and_is_checked():
    assert plan_robot({"bus": "mock", "joint_states_rate": "25"}, generate=False).joint_state_rate() == 25.0
    with pytest.raises((ConfigError, MultipleErrors), match="joint_states_rate"):
        plan_robot({"bus": "mock", "joint_states_rate": "0"}, generate=False)
