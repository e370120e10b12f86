"""The arguments `plem launch` takes, with their defaults and help, and their parsing from a command line."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from plem.core.config.launch_args import parse_launch_arguments
from plem.core.config.settings import Setting
from plem.robot.config import ARM_SETTINGS
from plem.robot.models import DEFAULT_ROBOT_TYPE, model_for


def model_default(setting: Setting) -> object:
    """The value of a configuration setting in the default arm's preset (e.g. 98 for rt_priority)."""
    return getattr(model_for(DEFAULT_ROBOT_TYPE)(), setting.name)


@dataclass(frozen=True)
class LaunchArgument:
    """One `name:=value` argument of `plem launch`: its default ('' for none) and its help line."""

    name: str
    default: str
    help: str


#: Every argument of `plem launch`; config fields without a launch default come from the config layers.
LAUNCH_ARGUMENTS: tuple[LaunchArgument, ...] = (
    LaunchArgument("bus", "ethercat", "fieldbus: ethercat, ethercat_sim (the virtual EtherCAT network), or mock "
                                      "for the simulated arm"),
    LaunchArgument("robot_id", "indy", "instance id: prefix of shared memory, namespace of topics"),
    LaunchArgument("robot_type", DEFAULT_ROBOT_TYPE, "built-in arm (used when description_package is "
                                                      "wim_description)"),
    LaunchArgument("description_package", "wim_description", "description package name or directory"),
    LaunchArgument("urdf_file", "", "URDF override (absolute, or relative to the package); default: discovered"),
    LaunchArgument("srdf_file", "", "SRDF override (absolute, or relative to the package); default: discovered"),
    LaunchArgument("robot_name", "", "robot name for topics and the planning group; default: from the package"),
    LaunchArgument("eth_interface", "", "EtherCAT network interface, e.g. enp3s0 (bus:=ethercat)"),
    LaunchArgument("bridge", "true", "publish the robot on ROS 2 over DDS (topics and actions under /{robot_id}/)"),
    LaunchArgument("bridge_commands", "true", "let ROS 2 command the robot through the bridge (joint_trajectory "
                   "topic, follow_joint_trajectory and set_mode actions); false: topics only, read-only"),
    LaunchArgument("frame_prefix", "", "prefix of the arm's frame names on /tf and /tf_static; default: "
                   "{robot_id}/ (frame_prefix:=none for none)"),
    LaunchArgument("start_enabled", "", "enable the drives and hold, trajectory controller active, once started; "
                   "default: true on bus:=mock and ethercat_sim, false on ethercat (docs/ros2.md)"),
    LaunchArgument("joint_states_rate", "", "Hz of /{robot_id}/joint_states; default: controllers.yaml update_rate, "
                   "at most 100"),
    LaunchArgument("planner", "true", "start the motion planner when the package has an SRDF (IK, collision "
                   "checking, OMPL; MoveIt's services under /{robot_id}/)"),
    LaunchArgument("scene", "", "YAML file of collision objects the planner starts with (docs/planning.md)"),
    LaunchArgument("record", "true", "record the monitoring topics into rosbag2 bags"),
    LaunchArgument("bag_dir", "~/bags/rt_monitoring", "directory of the bags"),
    LaunchArgument("retention_minutes", "60", "delete bags older than this (a circular buffer)"),
    LaunchArgument("disk_threshold", "70", "delete the oldest bags when the disk is fuller than this percent"),
    LaunchArgument("bag_storage", "mcap", "bag storage: mcap or sqlite3"),
    LaunchArgument("bag_segment_seconds", "60", "length of one bag segment (the unit retention deletes)"),
    LaunchArgument("flight_recorder_seconds", "10", "seconds before a fault whose segments are never deleted "
                   "automatically"),
    LaunchArgument("shm_group", "", "group allowed to read the shared memory; default: owner only"),
    LaunchArgument("max_consecutive_overruns", "", "overrun cycles in a row that fault the arm; default: 10 on "
                   "EtherCAT, 1000 on bus:=mock (docs/runtime.md)"),
    LaunchArgument("robots", "", "YAML file with several robots (each its own robot_id, bus, interface)"),
    *(LaunchArgument(s.launch, "", f"{s.description} [default: ${s.env}, else "
                                   f"{model_default(s)} for {DEFAULT_ROBOT_TYPE}]")
      for s in ARM_SETTINGS if s.launch and s.launch not in ("robot_id", "eth_interface")),
)
NAMES: tuple[str, ...] = tuple(argument.name for argument in LAUNCH_ARGUMENTS)
DEFAULTS: dict[str, str] = {argument.name: argument.default for argument in LAUNCH_ARGUMENTS}


def parse(tokens: Sequence[str]) -> dict[str, str]:
    """The launch arguments given on a command line (`name:=value` or `--name value`), defaults not filled in."""
    return parse_launch_arguments(tokens, NAMES)


def help_text() -> str:
    """One line per argument with its default, for `plem launch --help`."""
    width = max(len(name) for name in NAMES) + 2
    lines = []
    for argument in LAUNCH_ARGUMENTS:
        default = f" [default: {argument.default}]" if argument.default else ""
        lines.append(f"  {argument.name + ':=':<{width + 2}}{argument.help}{default}")
    return "\n".join(lines)
