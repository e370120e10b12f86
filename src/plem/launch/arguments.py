"""The arguments `plem launch` takes, with their defaults and help, and their parsing from a command line."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from plem.control.limits import CONTACT_SHARE, ArmLimits
from plem.control.payload import PAYLOAD_RULES, Payload
from plem.core.config.launch_args import number_list, parse_launch_arguments, shown
from plem.core.config.settings import Setting
from plem.errors import ConfigError, PlemError
from plem.robot.config import ARM_SETTINGS
from plem.robot.models import DEFAULT_ROBOT_TYPE, model_for

#: The buses whose arm is simulated, and so can start anywhere inside its limits.
SIMULATED_BUSES = ("mock", "ethercat_sim")


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
    LaunchArgument("robot_id", "indy", "instance id (a ROS 2 name token, at most 64 characters): prefix of shared "
                   "memory, namespace of topics"),
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
    LaunchArgument("initial_positions", "", "where the simulated arm starts (bus:=mock or ethercat_sim): "
                   "comma-separated rad (m for "
                   "a prismatic joint), one per joint in drive order, each inside its range; default: zero, else the "
                   "SRDF's home, else the middle of each range"),
    LaunchArgument("payload", "", "what the flange carries: mass,x,y,z (kg; centre of mass in m in the flange "
                   "frame) or mass,x,y,z,ixx,ixy,ixz,iyy,iyz,izz (and its inertia in kg·m², URDF order); default: "
                   "the robot profile's, else none"),
    LaunchArgument("contact_share", f"{CONTACT_SHARE:g}", "the contact stop: estimated external torque, as a share of "
                   "each joint's effort limit, past which the arm stops (0 to 1), or off (docs/motion.md)"),
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
    LaunchArgument("export_dir", "", "export each closed bag segment into this Parquet dataset, a directory or "
                   "s3://BUCKET/PREFIX (docs/fleet.md); default: no export"),
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


def initial_positions(text: str, bus: str, limits: ArmLimits) -> tuple[float, ...]:
    """The simulated arm's start from `initial_positions:=` on `bus`: one number per joint, each inside its range
    (`limits`); else a ConfigError saying what to give."""
    names = ", ".join(limits.joint_names)
    inside = np.clip(0.0, limits.min_position, limits.max_position)
    middle = (limits.min_position + limits.max_position) / 2
    example = ",".join(f"{value:.3g}" for value in np.where(np.isfinite(middle), middle, inside))

    def refused(why: str, how: str) -> ConfigError:
        return ConfigError(f"invalid launch argument initial_positions:={shown(text)}",
                           what=f"{limits.dof} comma-separated positions (rad, m for a prismatic joint), one for each "
                                f"of {names}, each inside its range, on a simulated arm (bus:=mock or ethercat_sim)",
                           why=why, how=how)

    if bus not in SIMULATED_BUSES:
        raise refused(f"bus:={bus} drives a real arm, which starts where it is",
                      "use bus:=mock or bus:=ethercat_sim to start a simulated arm elsewhere, or leave "
                      "initial_positions out")
    values = number_list(text)
    if values is None:
        raise refused(f"'{shown(text)}' is not a list of plain numbers (digits 0-9, an optional sign and point)",
                      f"e.g. initial_positions:={example}")
    if len(values) != limits.dof:
        raise refused(f"{len(values)} number{'s' if len(values) != 1 else ''} for {limits.dof} joints",
                      f"give one per joint ({names}), e.g. initial_positions:={example}")
    position = np.array(values)
    outside = [f"{name} = {value:g} is outside [{low:g}, {high:g}]" for name, value, low, high in
               zip(limits.joint_names, position, limits.min_position, limits.max_position, strict=True)
               if not low <= value <= high]
    if outside:
        raise refused("; ".join(outside), "give each joint a position inside its range (the URDF and "
                      "config/joint_limits.yaml), or leave initial_positions out to start at zero, the SRDF's home "
                      "or the middle of each range")
    return tuple(values)


def payload(text: str) -> Payload | None:
    """The payload of `payload:=` (None when empty): 4 or 10 comma-separated numbers meeting the payload rules;
    else a ConfigError saying what to give."""
    if not text.strip():
        return None
    values = number_list(text)
    try:
        if values is None:
            raise Payload.refused(f"'{shown(text)}' is not a list of plain numbers (digits 0-9, an optional sign "
                                  "and point)")
        return Payload.from_numbers(values)
    except ConfigError as error:
        raise ConfigError(f"invalid launch argument payload:={shown(text)}",
                          what=f"4 comma-separated numbers (mass, x, y, z) or 10 (and ixx, ixy, ixz, iyy, iyz, izz): "
                               f"{PAYLOAD_RULES}",
                          why=error.why,
                          how="e.g. payload:=1.5,0,0,0.05 for 1.5 kg 5 cm past the flange, or leave payload out "
                              "for none") from None


def export_dir(text: str, record: bool) -> str | None:
    """The dataset of `export_dir:=` (None when empty), checked without touching it; else a ConfigError."""
    from plem.fleet.destination import destination_problem

    if not text.strip():
        return None
    problem: PlemError | None = destination_problem(text, "export_dir:=")
    if problem is None and not record:
        problem = ConfigError("nothing to export", what="recording on, to export its segments",
                              why="record:=false", how="leave record on, or leave export_dir out")
    if problem is not None:
        raise ConfigError(f"invalid launch argument export_dir:={shown(text)}", what=problem.what, why=problem.why,
                          how=problem.how)
    return text


def contact_share(text: str) -> float:
    """The contact stop's threshold of `contact_share:=`, a share of each joint's effort limit (inf: off); else a
    ConfigError saying what to give."""
    if text.strip().lower() == "off":
        return float("inf")
    values = number_list(text)
    if values is not None and len(values) == 1 and 0 < values[0] <= 1:
        return values[0]
    raise ConfigError(f"invalid launch argument contact_share:={shown(text)}",
                      what="a share of each joint's effort limit above 0 and at most 1, or off",
                      why=f"'{shown(text)}' is not a number in that range",
                      how=f"e.g. contact_share:=0.4 for a stop past 40 % of the effort limits, contact_share:=off "
                          f"for none, or leave it out for {CONTACT_SHARE:g}")


def help_text() -> str:
    """One line per argument with its default, for `plem launch --help`."""
    width = max(len(name) for name in NAMES) + 2
    lines = []
    for argument in LAUNCH_ARGUMENTS:
        default = f" [default: {argument.default}]" if argument.default else ""
        lines.append(f"  {argument.name + ':=':<{width + 2}}{argument.help}{default}")
    return "\n".join(lines)
