"""`plem launch` arguments: parsing, checks collected before anything starts, robots files."""

from __future__ import annotations

import stat
from pathlib import Path

import pytest

from plem.core.config.launch_args import decimal_number, whole_number
from plem.description.scaffold import create_package
from plem.errors import ConfigError, MultipleErrors, PlemError, UsageError
from plem.launch.arguments import DEFAULTS, NAMES, help_text, parse
from plem.launch.plan import MAX_CONSECUTIVE_OVERRUNS, plan_launch, plan_robot, prepare_bag_directory
from plem.launch.robots_file import load_robots
from plem.robot.config import RT_KERNEL_FLAG
from tests.conftest import fresh_domain
from tests.integration.packages import copy_builtin

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


def test_a_controllers_yaml_plem_cannot_read_stops_the_plan(tmp_path, monkeypatch):
    """An alias bomb in the package's controllers.yaml is refused while planning, before any component reads it."""
    monkeypatch.setenv("PLEM_PACKAGE_PATH", str(tmp_path))
    root = create_package(tmp_path, "bombed", 6).root
    [controllers] = root.glob("config/*controllers.yaml")
    controllers.write_text("a: &a [x, x, x, x, x, x, x, x, x]\n" + "".join(
        f"{name}: &{name} [{', '.join([f'*{previous}'] * 9)}]\n" for previous, name in zip("abcdefgh", "bcdefghi",
                                                                                         strict=True)))
    with pytest.raises(PlemError, match="alias"):
        plan_robot({"bus": "mock", "description_package": str(root)})


def test_joint_state_rate_argument_wins_and_is_checked():
    assert plan_robot({"bus": "mock", "joint_states_rate": "25"}, generate=False).joint_state_rate() == 25.0
    with pytest.raises((ConfigError, MultipleErrors), match="joint_states_rate"):
        plan_robot({"bus": "mock", "joint_states_rate": "0"}, generate=False)


# -- numbers, groups, bag directories ----------------------------------------------------------------
@pytest.mark.parametrize("text, whole, decimal", [
    ("80", 80, 80.0), ("0", 0, 0.0), ("2.5", None, 2.5), (".5", None, 0.5),
    ("²", None, None), ("٣", None, None), ("７０", None, None), ("1_000", None, None), ("1e3", None, None),
    ("nan", None, None), ("inf", None, None), ("-3", None, None), (" 8", None, None), ("8\n", None, None),
    ("9" * 19, None, None), ("", None, None), (".", None, None),
])
def test_launch_numbers_are_plain_ascii_decimals(text, whole, decimal):
    assert whole_number(text) == whole and decimal_number(text) == decimal


@pytest.mark.parametrize("name, value", [
    ("cycle_time", "²"), ("rt_priority", "٣"), ("master_index", "1e3"), ("retention_minutes", "²"),
    ("disk_threshold", "７０"), ("bag_segment_seconds", "9" * 40), ("flight_recorder_seconds", "-1"),
    ("joint_states_rate", "nan"), ("joint_states_rate", "inf"), ("joint_states_rate", "1e3"),
    ("max_consecutive_overruns", "0"), ("max_consecutive_overruns", "2000000"),
    ("shm_group", "99999999999"), ("shm_group", "no_such_group_xyz"), ("shm_group", "a\0b"), ("shm_group", "²"),
])
def test_a_bad_number_or_group_is_a_plem_error_naming_the_argument(name, value):
    with pytest.raises(ConfigError) as caught:
        plan_robot({"bus": "mock", "record": "false", name: value})
    error = caught.value
    assert error.summary.startswith(f"invalid launch argument {name}:=") and f"{name}:=" in error.how
    assert "digits 0-9" in error.what or name == "shm_group"


@pytest.mark.parametrize("name", ["description_package", "urdf_file", "srdf_file"])
def test_a_path_with_the_home_of_no_user_is_a_plem_error_naming_the_argument(name):
    with pytest.raises(ConfigError) as caught:
        plan_robot({"bus": "mock", "record": "false", name: "~no_such_user_xyz/pkg"})
    assert caught.value.summary == f"unknown home directory in {name}:=~no_such_user_xyz/pkg"
    assert "no user 'no_such_user_xyz'" in caught.value.why


def test_shm_group_problem_names_the_groups_of_the_user():
    with pytest.raises(ConfigError) as caught:
        plan_robot({"bus": "mock", "record": "false", "shm_group": "no_such_group_xyz"})
    assert "your groups:" in caught.value.why and "groupadd" in caught.value.how


def test_overrun_fault_threshold_defaults_by_bus_and_follows_its_argument():
    assert plan_robot({"bus": "mock"}).max_consecutive_overruns == MAX_CONSECUTIVE_OVERRUNS["mock"]
    assert plan_robot({"bus": "mock", "max_consecutive_overruns": "25"}).max_consecutive_overruns == 25
    assert MAX_CONSECUTIVE_OVERRUNS["ethercat"] < MAX_CONSECUTIVE_OVERRUNS["mock"]


def test_start_enabled_defaults_by_bus_and_follows_its_argument():
    assert plan_robot({"bus": "mock"}).start_enabled is True
    assert plan_robot({"bus": "ethercat_sim"}).start_enabled is True
    assert plan_robot({"bus": "mock", "start_enabled": "false"}).start_enabled is False
    with pytest.raises(ConfigError) as caught:
        plan_robot({"bus": "mock", "record": "false", "start_enabled": "maybe"})
    assert "start_enabled:=" in caught.value.summary and "true or false" in caught.value.what


def test_frame_prefix_defaults_to_the_robot_id_and_none_means_no_prefix():
    assert plan_robot({"bus": "mock", "robot_id": "arm_left"}).frame_prefix == "arm_left/"
    assert plan_robot({"bus": "mock", "frame_prefix": "left/"}).frame_prefix == "left/"
    assert plan_robot({"bus": "mock", "frame_prefix": "none"}).frame_prefix == ""
    for bad in ("/world/", "a b"):
        with pytest.raises(ConfigError) as caught:
            plan_robot({"bus": "mock", "record": "false", "frame_prefix": bad})
        assert "frame_prefix:=" in caught.value.summary and "frame_prefix:=arm_left/" in caught.value.how


def test_the_plan_reads_the_controllers_of_the_package_or_the_generated_ones(tmp_path: Path):
    plan = plan_robot({"bus": "mock"})       # the built-in arm ships the configuration reference's file
    assert plan.controllers.trajectory.name == "joint_trajectory_controller"
    assert plan.controllers.trajectory.joints == plan.joint_names
    assert plan.controllers.update_rate == 500.0
    external = plan_robot({"bus": "mock", "description_package": str(_without_controllers(tmp_path))}, generate=False)
    assert external.controllers.trajectory.name == "arm_controller"       # the protocol's generated file
    assert external.controllers.trajectory.joints == external.joint_names


def _without_controllers(directory: Path) -> Path:
    """An external package (a copy of the built-in Indy7 v2) that lacks controllers.yaml."""
    package = copy_builtin("indy7_v2", directory / "ws")
    (package / "config" / "controllers.yaml").unlink()
    return package


@pytest.mark.parametrize("text, why", [
    ("/proc/nope", "/proc/nope: No such file or directory"),
    ("/proc", "/proc/arm: No such file or directory"),
    ("/tmp/a\0b", "NUL byte"),
    ("/tmp/" + "a" * 5000, "Linux allows 4095"),
    ("/tmp/" + "a" * 300, "a file name may have 255"),
    ("/tmp/" + "a/" * 2500, "Linux allows 4095"),
    ("/etc/passwd", "/etc/passwd: Not a directory"),
    ("/etc/passwd/bags", "/etc/passwd: Not a directory"),
    ("~no_such_user_xyz/bags", "no user 'no_such_user_xyz'"),
])
def test_a_bag_directory_that_cannot_hold_bags_is_explained(text: str, why: str):
    problem = prepare_bag_directory({"bag_dir": text}, "arm", None)
    assert problem is not None and why in problem.why, problem
    assert "bag_dir:=" in problem.summary + problem.how


def test_a_missing_bag_directory_is_created_owner_only(tmp_path: Path):
    assert prepare_bag_directory({"bag_dir": str(tmp_path / "bags" / "deep")}, "arm", None) is None
    for path in (tmp_path / "bags", tmp_path / "bags" / "deep", tmp_path / "bags" / "deep" / "arm"):
        assert path.is_dir() and stat.S_IMODE(path.stat().st_mode) == 0o700


# -- the launch as a whole ---------------------------------------------------------------------------
def test_every_problem_of_every_robot_is_reported_before_anything_is_generated(tmp_path: Path):
    robots = [{"robot_id": "left", "bus": "mock", "bag_dir": "/proc/nope", "rt_priority": "99"},
              {"robot_id": "right", "bus": "mock", "cycle_time": "²", "retention_minutes": "²"}]
    with pytest.raises(MultipleErrors) as caught:
        plan_launch(robots, temp_root=tmp_path / "generated")
    text = caught.value.render()
    for words in ("robot left: cannot write into /proc/nope", "robot left: rt_priority out of range",
                  "robot right: invalid launch argument cycle_time:=²",
                  "robot right: invalid launch argument retention_minutes:=²"):
        assert words in text, text
    assert not (tmp_path / "generated").exists()


def test_an_ethercat_interface_that_does_not_exist_stops_the_other_robots_too(tmp_path: Path):
    robots = [{"robot_id": "arm_left", "bus": "mock", "record": "false"},
              {"robot_id": "arm_right", "bus": "ethercat", "eth_interface": "nosuch0", "master_index": "1",
               "record": "false"}]
    with pytest.raises(ConfigError, match="robot arm_right: Network interface does not exist: nosuch0"):
        plan_launch(robots, bridge=False, temp_root=tmp_path)
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("uri", ["<bogus", "file:///no/such/cyclonedds.xml", "<CycloneDDS>é</CycloneDDS>"])
def test_a_configuration_cyclone_refuses_stops_the_launch_and_names_cyclonedds_uri(uri, monkeypatch, tmp_path):
    monkeypatch.setenv("CYCLONEDDS_URI", uri)
    monkeypatch.setenv("ROS_DOMAIN_ID", str(fresh_domain()))  # a domain this test process has not joined
    robot = {"bus": "mock", "record": "false"}
    with pytest.raises(ConfigError) as caught:
        plan_launch([robot], temp_root=tmp_path)
    assert "CYCLONEDDS_URI" in caught.value.why and "CYCLONEDDS_URI" in caught.value.how
    assert plan_launch([robot], bridge=False, temp_root=tmp_path)            # no bridge: DDS is not needed
    assert plan_launch([{**robot, "bridge": "false"}], temp_root=tmp_path)


def test_a_good_launch_generates_the_missing_files_once_checked(tmp_path: Path):
    robot = {"bus": "mock", "record": "false", "description_package": str(_without_controllers(tmp_path))}
    (plan,) = plan_launch([robot], temp_root=tmp_path)
    assert plan.description is not None and plan.description.generated_dir.parent == tmp_path


def test_a_fast_cycle_without_an_rt_kernel_carries_the_config_warning():
    plan = plan_robot({"bus": "mock", "cycle_time": "500"})
    expected = plan.config.warnings()
    assert plan.resolved.warnings == expected
    assert bool(expected) == (not RT_KERNEL_FLAG.exists())
