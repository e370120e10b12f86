"""What one robot of a launch will be: its arguments checked, description found, configuration resolved.

The supervisor makes a plan to report every problem before anything starts (and to generate missing
description files once); the RT driver makes the same plan from the same arguments to build the robot.
"""

from __future__ import annotations

import grp
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from plem.core.paths import BUILTIN_PACKAGES_DIR
from plem.description.discover import locate_package, package_for_launch
from plem.description.generate import ResolvedDescription, resolve_description
from plem.description.validate import Stage, ValidationReport, require_valid
from plem.errors import ConfigError, PlemError, raise_collected
from plem.launch.arguments import DEFAULTS
from plem.recording.settings import RecordingSettings
from plem.robot.config import SerialArmConfig
from plem.robot.models import MODELS
from plem.robot.resolution import LAUNCH_DEFAULTS, ResolvedConfig, resolve_arm_config

BUSES = ("ethercat", "ethercat_sim", "mock")
ETHERCAT_BUSES = ("ethercat", "ethercat_sim")
#: joint_states rates: the most a user may ask for, and the most the default follows controllers.yaml.
MAX_JOINT_STATES_RATE = 1000.0
DEFAULT_JOINT_STATES_RATE_CAP = 100.0
BOOLEANS = {"true": True, "1": True, "yes": True, "false": False, "0": False, "no": False}
BAG_STORAGES = ("mcap", "sqlite3")


@dataclass
class RobotPlan:
    """One robot's launch: the arguments as given and everything derived from them."""

    arguments: dict[str, str]
    resolved: ResolvedConfig
    package: Path
    urdf_file: str | None
    srdf_file: str | None
    bus: str
    robot_name: str
    record: bool
    bridge: bool
    shm_group: int | None
    report: ValidationReport
    description: ResolvedDescription | None = None
    bridge_commands: bool = True

    @property
    def config(self) -> SerialArmConfig:
        """The robot's resolved configuration (the field sources are in `resolved`)."""
        return self.resolved.config

    @property
    def robot_id(self) -> str:
        """Instance id of this robot: namespace of its topics and prefix of its shared memory."""
        return self.config.robot_id

    def joint_state_rate(self) -> float:
        """Hz of joint_states: the launch argument, else controllers.yaml's update rate, at most 100 Hz."""
        if self.arguments.get("joint_states_rate"):
            return float(self.arguments["joint_states_rate"])
        rate = 1e6 / self.config.cycle_time
        controllers = self.report.files.controllers
        if controllers is not None:
            value: Any = yaml.safe_load(controllers.read_text(encoding="utf-8"))
            for key in ("controller_manager", "ros__parameters", "update_rate"):
                value = value.get(key) if isinstance(value, dict) else None
            if isinstance(value, (int, float)) and not isinstance(value, bool) and value > 0:
                rate = float(value)
        return min(rate, DEFAULT_JOINT_STATES_RATE_CAP)

    def recording(self) -> RecordingSettings:
        """Where and how the recorder writes this robot's bags: `bag_dir/{robot_id}/`."""
        def number(name: str) -> float:
            return float(self.arguments.get(name) or DEFAULTS[name])

        return RecordingSettings(bag_directory(self.arguments) / self.robot_id,
                                 self.arguments.get("bag_storage") or DEFAULTS["bag_storage"],
                                 number("bag_segment_seconds"), 60 * number("retention_minutes"),
                                 number("disk_threshold"), number("flight_recorder_seconds"))

    def poses(self, joint_names: tuple[str, ...]) -> dict[str, list[float]]:
        """Named poses of the SRDF; 'home' defaults to every joint at 0 rad when the SRDF names none."""
        poses = self.report.srdf.poses(joint_names) if self.report.srdf is not None else {}
        poses.setdefault("home", [0.0] * len(joint_names))
        return poses


def _problem(name: str, value: str, what: str, how: str) -> ConfigError:
    return ConfigError(f"invalid launch argument {name}:={value}", what=what, why=f"{name} is {value!r}", how=how)


def _boolean(arguments: Mapping[str, str], name: str, errors: list[PlemError]) -> bool:
    text = arguments.get(name, DEFAULTS[name]).lower()
    if text not in BOOLEANS:
        errors.append(_problem(name, text, "true or false", f"e.g. {name}:=false"))
        return False
    return BOOLEANS[text]


def _positive(text: str, high: float) -> bool:
    try:
        return 0.0 < float(text) <= high
    except ValueError:
        return False


def _integer(arguments: Mapping[str, str], name: str, low: int, high: int, errors: list[PlemError]) -> None:
    text = arguments.get(name) or DEFAULTS[name]
    if not text.strip().isdigit() or not low <= int(text) <= high:
        errors.append(_problem(name, text, f"a whole number from {low} to {high}", f"e.g. {name}:={DEFAULTS[name]}"))


def bag_directory(arguments: Mapping[str, str]) -> Path:
    """The directory of all robots' bags (`bag_dir`, `~` expanded); each robot records into its own subdirectory."""
    return Path(arguments.get("bag_dir") or DEFAULTS["bag_dir"]).expanduser()


def _check_bag_directory(arguments: Mapping[str, str], errors: list[PlemError]) -> None:
    """bag_dir must be a directory plem may write into, or one it may create (the recorder creates it)."""
    directory = bag_directory(arguments)
    existing = next(path for path in (directory, *directory.parents) if path.exists())
    if not existing.is_dir():
        why = f"{existing} is not a directory"
    elif not os.access(existing, os.W_OK | os.X_OK):
        why = f"plem may not write into {existing}"
    else:
        return
    errors.append(ConfigError(f"bag_dir {directory} cannot hold bags", what="a directory plem can write into",
                              why=why, how="pass bag_dir:=DIR with a writable DIR, or record:=false"))


def _group(text: str, errors: list[PlemError]) -> int | None:
    if not text:
        return None
    try:
        return int(text) if text.isdigit() else grp.getgrnam(text).gr_gid
    except KeyError:
        errors.append(_problem("shm_group", text, "an existing group name or id", "create the group or drop shm_group"))
        return None


def plan_robot(arguments: Mapping[str, str], *, generate: bool = True, temp_root: Path | None = None) -> RobotPlan:
    """Check the launch arguments of one robot and resolve its description and configuration.

    `generate` writes missing optional description files into a fresh temp directory (the supervisor);
    the RT driver plans without it. All argument problems are raised together.
    """
    arguments = {name: value for name, value in arguments.items() if value != ""}
    errors: list[PlemError] = []
    bus = arguments.get("bus", DEFAULTS["bus"])
    if bus not in BUSES:
        errors.append(_problem("bus", bus, f"one of {', '.join(BUSES)}",
                               "use bus:=mock for the simulated arm, bus:=ethercat_sim for the virtual EtherCAT "
                               "network"))
    record, bridge, bridge_commands = (_boolean(arguments, name, errors)
                                       for name in ("record", "bridge", "bridge_commands"))
    rate_text = arguments.get("joint_states_rate", "")
    if rate_text and not _positive(rate_text, MAX_JOINT_STATES_RATE):
        errors.append(_problem("joint_states_rate", rate_text, f"a rate in Hz above 0 and at most "
                               f"{MAX_JOINT_STATES_RATE:.0f}", "e.g. joint_states_rate:=50"))
    _integer(arguments, "retention_minutes", 1, 10_000_000, errors)
    _integer(arguments, "disk_threshold", 1, 99, errors)
    _integer(arguments, "bag_segment_seconds", 1, 86_400, errors)
    _integer(arguments, "flight_recorder_seconds", 1, 3_600, errors)
    storage = arguments.get("bag_storage", DEFAULTS["bag_storage"])
    if storage not in BAG_STORAGES:
        errors.append(_problem("bag_storage", storage, f"one of {', '.join(BAG_STORAGES)}", "e.g. bag_storage:=mcap"))
    if record:
        _check_bag_directory(arguments, errors)
    group = _group(arguments.get("shm_group", ""), errors)
    raise_collected(errors, "the launch arguments")

    package = Path(locate_package(package_for_launch(arguments.get("description_package"),
                                                     arguments.get("robot_type"))))
    urdf_file, srdf_file = arguments.get("urdf_file"), arguments.get("srdf_file")
    config_arguments = dict(arguments)
    builtin = _builtin_model(package)
    if builtin is None:
        config_arguments.pop("robot_type", None)  # a custom package: robot_type does not apply
    else:
        config_arguments["robot_type"] = builtin
    description = None
    if generate:
        cycle_us = int(arguments["cycle_time"]) if arguments.get("cycle_time", "").isdigit() else 1000
        description = resolve_description(package, urdf_file=urdf_file, srdf_file=srdf_file, cycle_time_us=cycle_us,
                                          stage=Stage.STARTUP, temp_root=temp_root)
        report = description.report
    else:
        report = require_valid(package, stage=Stage.STARTUP, urdf_file=urdf_file, srdf_file=srdf_file)
    resolved = resolve_arm_config(launch_args=config_arguments, launch_defaults=LAUNCH_DEFAULTS,
                                  dof=None if builtin else report.dof)
    if bus == "ethercat":
        _interface_from_etherlab(resolved)
    robot_name = arguments.get("robot_name") or package.name.removesuffix("_description")
    return RobotPlan(arguments, resolved, package, urdf_file, srdf_file, bus, robot_name, record, bridge,
                     group, report, description, bridge_commands)


def _interface_from_etherlab(resolved: ResolvedConfig) -> None:
    """No layer named the interface: an EtherLab installation's MASTER<index>_DEVICE serves as the default."""
    from plem.core.config.layers import LayerKind, Source
    from plem.fieldbus.ethercat.bringup import ETHERLAB_CONF, default_interface

    if resolved.sources["network_interface"].kind > LayerKind.LAUNCH_DEFAULT:
        return
    device = default_interface(resolved.config.master_index)
    if device:
        resolved.config.network_interface = device
        origin = f"MASTER{resolved.config.master_index}_DEVICE in {ETHERLAB_CONF}"
        resolved.sources["network_interface"] = Source(LayerKind.LAUNCH_DEFAULT, origin)


def check_shared_hardware(plans: list[RobotPlan]) -> None:
    """Robots of one launch on EtherCAT need their own interface and master index; all clashes raised together."""
    errors: list[PlemError] = []
    for key, argument in (("network_interface", "eth_interface"), ("master_index", "master_index")):
        seen: dict[object, str] = {}
        for plan in plans:
            if plan.bus not in ETHERCAT_BUSES or (plan.bus == "ethercat_sim" and key == "network_interface"):
                continue
            value = getattr(plan.config, key)
            if value in seen:
                errors.append(ConfigError(
                    f"robots {seen[value]} and {plan.robot_id} both use {argument} {value}",
                    what=f"a distinct {argument} for each EtherCAT robot of a launch",
                    why=f"{seen[value]} and {plan.robot_id} would drive one EtherCAT master",
                    how=f"give each robot its own {argument}:= (and its own wired port) in robots.yaml"))
            seen[value] = plan.robot_id
    raise_collected(errors, "the robots of the launch")


def _builtin_model(package: Path) -> str | None:
    """The robot_type whose built-in package this is, or None for a user's package."""
    if package.resolve().parent != BUILTIN_PACKAGES_DIR:
        return None
    return next((robot_type for robot_type, model in MODELS.items()
                 if model.MODEL.description_package == package.name), None)


def child_environment(plan: RobotPlan) -> dict[str, str]:
    """The environment of a robot's child processes: PLEM_ROBOT_ID, as the spec's launch passes it."""
    return {**os.environ, "PLEM_ROBOT_ID": plan.robot_id}
