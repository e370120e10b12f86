"""What the robots of a launch will be: their arguments checked, descriptions found, configurations resolved.

`plan_launch` (the supervisor) checks every robot of a launch, and what the host must provide for them,
before anything starts, reports all problems of all robots together, and only then generates missing
description files. Each child process (RT driver, bridge, recorder) makes the same `plan_robot` from the
same arguments to build its part; that has no side effects.
"""

from __future__ import annotations

import errno
import grp
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TypeVar

from plem.control.limits import ArmLimits
from plem.control.payload import Payload
from plem.core.config.launch_args import check_home, decimal_number, shown, whole_number
from plem.core.config.settings import parse_int
from plem.core.paths import BUILTIN_PACKAGES_DIR
from plem.description.controllers import ControllerSet, read_controllers
from plem.description.discover import locate_package, package_for_launch
from plem.description.generate import ResolvedDescription, complete_description
from plem.description.limits import derived_limits_note
from plem.description.validate import Stage, ValidationReport, require_valid
from plem.errors import ConfigError, MultipleErrors, PlemError, UsageError, raise_collected
from plem.launch.arguments import DEFAULTS, contact_share, export_dir, initial_positions, model_default, payload
from plem.planning.named_states import with_zero
from plem.planning.scene import read_scene_file
from plem.recording.access import FileAccess
from plem.recording.problems import refuse_unusable, write_problem
from plem.recording.robot_directory import make_directory
from plem.recording.settings import RecordingSettings
from plem.robot.config import ARM_SETTINGS, SerialArmConfig
from plem.robot.models import MODELS
from plem.robot.resolution import LAUNCH_DEFAULTS, ResolvedConfig, resolve_arm_config
from plem.robot.robot import arm_joint_names, startup_urdf

T = TypeVar("T")

BUSES = ("ethercat", "ethercat_sim", "mock")
ETHERCAT_BUSES = ("ethercat", "ethercat_sim")
#: joint_states rates: the most a user may ask for, and the most the default follows controllers.yaml.
MAX_JOINT_STATES_RATE = 1000.0
DEFAULT_JOINT_STATES_RATE_CAP = 100.0
BOOLEANS = {"true": True, "1": True, "yes": True, "false": False, "0": False, "no": False}
BAG_STORAGES = ("mcap", "sqlite3")
#: Whole-number launch arguments and their ranges (the configuration overrides are checked by the config rules).
WHOLE_ARGUMENTS = {"retention_minutes": (1, 10_000_000), "disk_threshold": (1, 99), "bag_segment_seconds": (1, 86_400),
                   "flight_recorder_seconds": (1, 3_600), "max_consecutive_overruns": (1, 1_000_000)}
#: Overruns in a row that fault the arm, by bus, when max_consecutive_overruns:= is not given (docs/runtime.md).
MAX_CONSECUTIVE_OVERRUNS = {"ethercat": 10, "ethercat_sim": 10, "mock": 1000}
#: Group ids chown accepts: 0 to 2³² − 2 (2³² − 1 means "no change").
MAX_GROUP_ID = 2**32 - 2
#: Arguments naming a package or a file, whose ~ the description expands.
PATH_ARGUMENTS = ("description_package", "urdf_file", "srdf_file")


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
    #: planner:= as given; the planner starts only when it is true, the package has an SRDF and its collision meshes.
    planner_wanted: bool = True

    @property
    def has_srdf(self) -> bool:
        """Whether the description package has an SRDF (the spec's condition for planning)."""
        return self.report.srdf is not None

    @property
    def planner(self) -> bool:
        """Whether the launch starts this robot's planner (never when `report.planning_disabled` says why not)."""
        return self.planner_wanted and self.has_srdf and self.report.planning_disabled is None

    @property
    def config(self) -> SerialArmConfig:
        """The robot's resolved configuration (the field sources are in `resolved`)."""
        return self.resolved.config

    @property
    def robot_id(self) -> str:
        """Instance id of this robot: namespace of its topics and prefix of its shared memory."""
        return self.config.robot_id

    @property
    def max_consecutive_overruns(self) -> int:
        """Overrun cycles in a row that fault the arm: the launch argument, else the bus's default."""
        text = self.arguments.get("max_consecutive_overruns")
        return int(text) if text else MAX_CONSECUTIVE_OVERRUNS[self.bus]

    @property
    def frame_prefix(self) -> str:
        """What the arm's /tf frame names start with: the launch argument ('none': nothing), else `{robot_id}/`."""
        given = self.arguments.get("frame_prefix", "")
        return "" if given == "none" else given or f"{self.robot_id}/"

    @property
    def start_enabled(self) -> bool:
        """Whether the driver enables the drives once started: the launch argument, else true on the simulated
        buses, false on EtherCAT (where enabling releases a real arm's brakes)."""
        given = _flag(self.arguments, "start_enabled") if self.arguments.get("start_enabled") else None
        return given if given is not None else self.bus != "ethercat"

    @property
    def joint_names(self) -> tuple[str, ...]:
        """The arm's joints in drive order."""
        urdf, _ = startup_urdf(self.report)
        return arm_joint_names(self.config, urdf)

    @property
    def initial_positions(self) -> tuple[float, ...] | None:
        """Where the simulated arm starts (initial_positions:=); None for its own start (zero, home or mid-range)."""
        text = self.arguments.get("initial_positions")
        return None if text is None else initial_positions(text, self.bus, self.limits())

    @property
    def payload(self) -> Payload | None:
        """What the flange carries by payload:= (mass, centre of mass in the flange frame); None when not given."""
        return payload(self.arguments.get("payload", ""))

    @property
    def contact_share(self) -> float:
        """The contact stop's threshold by contact_share:=, a share of each joint's effort limit (inf: off)."""
        return contact_share(self.arguments.get("contact_share", DEFAULTS["contact_share"]))

    def limits(self) -> ArmLimits:
        """The limits the driver enforces, in drive order."""
        return ArmLimits.from_joint_limits(self.report.limits, self.joint_names)

    @property
    def robot_description(self) -> str:
        """The URDF text the bridge publishes as robot_description and the recorder records with every segment."""
        return self.report.urdf_xml or ""

    @property
    def controllers(self) -> ControllerSet:
        """The controllers of the package's controllers.yaml, or the ones plem generates when it has none."""
        return read_controllers(self.report.files.controllers, self.joint_names, self.config.cycle_time)

    def joint_state_rate(self) -> float:
        """Hz of joint_states: the launch argument, else controllers.yaml's update rate, at most 100 Hz."""
        if self.arguments.get("joint_states_rate"):
            return float(self.arguments["joint_states_rate"])
        rate = self.controllers.update_rate if self.report.files.controllers is not None else None
        return min(rate or 1e6 / self.config.cycle_time, DEFAULT_JOINT_STATES_RATE_CAP)

    def recording(self) -> RecordingSettings:
        """Where and how the recorder writes this robot's bags: `bag_dir/{robot_id}/`."""
        def number(name: str) -> float:
            return float(self.arguments.get(name) or DEFAULTS[name])

        return RecordingSettings(bag_directory(self.arguments) / self.robot_id,
                                 self.arguments.get("bag_storage") or DEFAULTS["bag_storage"],
                                 number("bag_segment_seconds"), 60 * number("retention_minutes"),
                                 number("disk_threshold"), number("flight_recorder_seconds"))

    def poses(self, joint_names: tuple[str, ...]) -> dict[str, list[float]]:
        """The named states clients find by name: the SRDF's group_states, and `zero` unless the SRDF has its own."""
        return with_zero(self.report.srdf.poses(joint_names) if self.report.srdf is not None else {},
                         len(joint_names))

    def generate_files(self, temp_root: Path | None = None) -> None:
        """Generate the optional description files the package lacks (into `description`), as the launch does."""
        self.description = complete_description(self.report, cycle_time_us=self.config.cycle_time,
                                                temp_root=temp_root)


def _problem(name: str, value: str, what: str, how: str) -> ConfigError:
    return ConfigError(f"invalid launch argument {name}:={shown(value)}", what=what,
                       why=f"{name} is '{shown(value)}'", how=how)


def _flag(arguments: Mapping[str, str], name: str) -> bool | None:
    """A true/false argument (its default when not given), None when it is neither."""
    return BOOLEANS.get(arguments.get(name, DEFAULTS[name]).lower())


def _boolean(arguments: Mapping[str, str], name: str, errors: list[PlemError]) -> bool:
    value = _flag(arguments, name)
    if value is None:
        errors.append(_problem(name, arguments[name], "true or false", f"e.g. {name}:=false"))
    return bool(value)


def _whole(arguments: Mapping[str, str], name: str, errors: list[PlemError]) -> None:
    text = arguments.get(name)
    low, high = WHOLE_ARGUMENTS[name]
    value = whole_number(text) if text is not None else low
    if value is None or not low <= value <= high:
        errors.append(_problem(name, text or "", f"a whole number from {low} to {high}, written with the digits 0-9",
                               f"e.g. {name}:={DEFAULTS[name] or MAX_CONSECUTIVE_OVERRUNS['mock']}"))


def _rate(arguments: Mapping[str, str], errors: list[PlemError]) -> None:
    text = arguments.get("joint_states_rate")
    value = decimal_number(text) if text is not None else 1.0
    if value is None or not 0.0 < value <= MAX_JOINT_STATES_RATE:
        errors.append(_problem("joint_states_rate", text or "", f"a rate in Hz above 0 and at most "
                               f"{MAX_JOINT_STATES_RATE:.0f}, written with the digits 0-9 and at most one '.'",
                               "e.g. joint_states_rate:=50"))


def _home_problems(arguments: Mapping[str, str]) -> list[PlemError]:
    """Path arguments starting with ~user of a user the system does not know."""
    problems: list[PlemError] = []
    for name in PATH_ARGUMENTS:
        try:
            check_home(arguments.get(name, ""), f"{name}:={arguments.get(name, '')}")
        except PlemError as error:
            problems.append(error)
    return problems


def _config_arguments(arguments: Mapping[str, str], errors: list[PlemError]) -> dict[str, str]:
    """The arguments for the configuration layers; a number there not written in plain digits is a problem and
    is left out (the configuration rules check the ranges)."""
    config_arguments = dict(arguments)
    for setting in ARM_SETTINGS:
        name = setting.launch or ""
        text = arguments.get(name)
        if setting.parse is parse_int and text is not None and whole_number(text) is None:
            errors.append(_problem(name, text, f"{setting.expected}, written with the digits 0-9",
                                   f"e.g. {name}:={model_default(setting)}"))
            del config_arguments[name]
    return config_arguments


def _your_groups() -> str:
    names = set()
    for gid in {os.getegid(), *os.getgroups()}:
        try:
            names.add(grp.getgrgid(gid).gr_name)
        except KeyError:
            names.add(str(gid))
    return ", ".join(sorted(names))


def _group(text: str, errors: list[PlemError]) -> int | None:
    """The group id of shm_group (a name or a number), None when not given or a problem."""
    if not text:
        return None
    gid = whole_number(text)
    why = ""
    if gid is None:
        try:
            gid = grp.getgrnam(text).gr_gid
        except (KeyError, ValueError):
            why = f"no group is named '{shown(text)}'"
    elif gid > MAX_GROUP_ID:
        why = f"{text} is above the largest group id, {MAX_GROUP_ID}"
    if not why and os.geteuid() != 0 and gid not in (os.getegid(), *os.getgroups()):
        why = f"you are not a member of group {shown(text)}, so plem may not give it your shared memory"
    if why:
        mine = _your_groups()
        errors.append(ConfigError(
            f"invalid launch argument shm_group:={shown(text)}",
            what="the name or id of an existing group you are a member of (root: any group)",
            why=f"{why}; your groups: {mine}",
            how=f"pass shm_group:= one of {mine}, or leave it out for owner-only shared memory; to make a group: "
                "sudo groupadd robots && sudo usermod -aG robots $USER (then log in again)"))
        return None
    return gid


def bag_directory(arguments: Mapping[str, str]) -> Path:
    """The directory of all robots' bags (`bag_dir`, `~` expanded); each robot records into its own subdirectory."""
    return Path(arguments.get("bag_dir") or DEFAULTS["bag_dir"]).expanduser()


def prepare_bag_directory(arguments: Mapping[str, str], robot_id: str | None, group: int | None) -> PlemError | None:
    """Create the bag directory (and `robot_id`'s below it, when known) as the recorder would; the problem if not.

    The directories get the recorder's access (owner-only, or readable by `group`), and a problem is worded as
    the recorder words it, naming `bag_dir:=`.
    """
    text = arguments.get("bag_dir") or DEFAULTS["bag_dir"]
    try:
        check_home(text, f"bag_dir:={text}")
        directory = bag_directory(arguments)
        target = directory / robot_id if robot_id else directory
        refuse_unusable(target)
    except PlemError as error:
        return error
    try:
        existing = next(path for path in (target, *target.parents) if os.path.lexists(path))
        if not existing.is_dir():
            raise NotADirectoryError(errno.ENOTDIR, os.strerror(errno.ENOTDIR), str(existing))
        make_directory(target, FileAccess(group), robot=robot_id is not None)
        if not os.access(target, os.W_OK | os.X_OK):
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(target))
    except OSError as error:
        return write_problem(target, error)
    return None


def _each(error: PlemError) -> list[PlemError]:
    return list(error.errors) if isinstance(error, MultipleErrors) else [error]


def _collected(errors: list[PlemError], step: Callable[[], T]) -> T | None:
    """What `step` returns; None when it raises a PlemError, whose problems go to `errors`."""
    try:
        return step()
    except PlemError as error:
        errors.extend(_each(error))
        return None


def plan_robot(arguments: Mapping[str, str], *, generate: bool = False, temp_root: Path | None = None) -> RobotPlan:
    """Check the launch arguments of one robot and resolve its description and configuration.

    Every problem (arguments, description package, configuration) is raised together. `generate` also writes
    the optional description files the package lacks (see `RobotPlan.generate_files`, under `temp_root`).
    """
    arguments = {name: value for name, value in arguments.items() if value != ""}
    errors: list[PlemError] = []
    bus = arguments.get("bus", DEFAULTS["bus"])
    if bus not in BUSES:
        errors.append(_problem("bus", bus, f"one of {', '.join(BUSES)}",
                               "use bus:=mock for the simulated arm, bus:=ethercat_sim for the virtual EtherCAT "
                               "network"))
    record, bridge, bridge_commands, planner = (_boolean(arguments, name, errors)
                                                for name in ("record", "bridge", "bridge_commands", "planner"))
    if arguments.get("scene"):
        _collected(errors, lambda: read_scene_file(Path(arguments["scene"])))
    if "start_enabled" in arguments:
        _boolean(arguments, "start_enabled", errors)
    prefix = arguments.get("frame_prefix", "")
    if prefix.startswith("/") or not all(c.isprintable() and not c.isspace() for c in prefix):
        errors.append(_problem("frame_prefix", prefix, "a tf frame name prefix: no leading '/', no spaces",
                               "e.g. frame_prefix:=arm_left/ (or frame_prefix:=none)"))
    _rate(arguments, errors)
    for name in WHOLE_ARGUMENTS:
        _whole(arguments, name, errors)
    storage = arguments.get("bag_storage", DEFAULTS["bag_storage"])
    if storage not in BAG_STORAGES:
        errors.append(_problem("bag_storage", storage, f"one of {', '.join(BAG_STORAGES)}", "e.g. bag_storage:=mcap"))
    group = _group(arguments.get("shm_group", ""), errors)
    config_arguments = _config_arguments(arguments, errors)
    homeless = _home_problems(arguments)
    errors.extend(homeless)

    package = None if homeless else _collected(errors, lambda: Path(locate_package(package_for_launch(
        arguments.get("description_package"), arguments.get("robot_type")))))
    builtin = _builtin_model(package) if package is not None else None
    report = None if package is None else _collected(errors, lambda: require_valid(
        package, stage=Stage.STARTUP, urdf_file=arguments.get("urdf_file"), srdf_file=arguments.get("srdf_file")))
    if builtin is None:
        config_arguments.pop("robot_type", None)  # a custom package: robot_type does not apply
    else:
        config_arguments["robot_type"] = builtin
    dof = None if builtin or report is None else report.dof
    resolved = _collected(errors, lambda: resolve_arm_config(launch_args=config_arguments,
                                                            launch_defaults=LAUNCH_DEFAULTS, dof=dof))
    if report is not None and resolved is not None:
        _collected(errors, lambda: read_controllers(report.files.controllers, arm_joint_names(
            resolved.config, startup_urdf(report)[0]), resolved.config.cycle_time))
        if "initial_positions" in arguments:
            _collected(errors, lambda: initial_positions(arguments["initial_positions"], bus,
                                                         ArmLimits.from_joint_limits(report.limits, arm_joint_names(
                                                             resolved.config, startup_urdf(report)[0]))))
    _collected(errors, lambda: payload(arguments.get("payload", "")))
    _collected(errors, lambda: export_dir(arguments.get("export_dir", ""), bool(_flag(arguments, "record"))))
    _collected(errors, lambda: contact_share(arguments.get("contact_share", DEFAULTS["contact_share"])))
    raise_collected(errors, "the launch arguments")
    assert package is not None and report is not None and resolved is not None  # each failure added an error

    if bus == "ethercat":
        _interface_from_etherlab(resolved)
    robot_name = arguments.get("robot_name") or report.files.name.removesuffix("_description")
    derived = derived_limits_note(report.limits)
    if derived:
        resolved.warnings.append(derived)
    plan = RobotPlan(arguments, resolved, package, arguments.get("urdf_file"), arguments.get("srdf_file"), bus,
                     robot_name, record, bridge, group, report, None, bridge_commands, planner)
    if generate:
        plan.generate_files(temp_root)
    return plan


def _host_problems(arguments: Mapping[str, str], plan: RobotPlan | None) -> list[PlemError]:
    """What the host must provide for one robot: its bag directory (created here) and its EtherCAT interface.

    With the robot's own problems (`plan` None) both are still checked as far as the arguments tell: the bag
    directory without the robot's subdirectory (its robot_id may be the problem), the interface when named.
    """
    problems: list[PlemError] = []
    if _flag(arguments, "record"):  # a wrong shm_group is the plan's problem; the directories stay owner-only then
        problem = prepare_bag_directory(arguments, plan.robot_id if plan else None,
                                        _group(arguments.get("shm_group", ""), []))
        problems.extend([problem] if problem else [])
    interface = plan.config.network_interface if plan is not None else arguments.get("eth_interface")
    if arguments.get("bus", DEFAULTS["bus"]) == "ethercat" and interface:
        from plem.fieldbus.ethercat.bringup import check_access

        try:
            check_access(interface)
        except PlemError as error:
            problems.append(error)
    return problems


def _of_robot(error: PlemError, robot_id: str) -> PlemError:
    """`error` with the robot it belongs to in its summary (for launches of several robots)."""
    kind = UsageError if error.exit_code == UsageError.exit_code else ConfigError
    return kind(f"robot {robot_id}: {error.summary}", what=error.what, why=error.why, how=error.how)


def plan_launch(robots: Sequence[Mapping[str, str]], *, bridge: bool = True,
                temp_root: Path | None = None) -> list[RobotPlan]:
    """Plan every robot of a launch and check what the host must provide; all problems of all robots together.

    Checked besides each robot's `plan_robot`: its bag directory (created as the recorder would create it),
    its EtherCAT interface, EtherCAT hardware shared between robots and, when any robot has a bridge
    (`bridge` False: the launch file disabled bridges), the DDS configuration. Nothing is generated or started
    when anything is wrong; then the description files the packages lack are generated and the plans returned.
    """
    from plem.middleware.discovery import DiscoverySettings
    from plem.middleware.node import check_configuration

    errors: list[PlemError] = []
    plans: list[RobotPlan] = []
    for arguments in robots:
        problems: list[PlemError] = []
        plan = None
        try:
            plan = plan_robot(arguments)
            plans.append(plan)
        except PlemError as error:
            problems.extend(_each(error))
        problems.extend(_host_problems(arguments, plan))
        robot_id = shown(arguments.get("robot_id") or DEFAULTS["robot_id"])
        errors.extend(_of_robot(problem, robot_id) if len(robots) > 1 else problem for problem in problems)
    errors.extend(shared_hardware_problems(plans))
    if bridge and any(_flag(arguments, "bridge") is not False for arguments in robots):
        try:
            check_configuration(DiscoverySettings.from_environment())
        except PlemError as error:
            errors.append(error)
    raise_collected(errors, "the launch")
    for plan in plans:
        plan.generate_files(temp_root)
    return plans


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


def shared_hardware_problems(plans: Sequence[RobotPlan]) -> list[PlemError]:
    """Robots of one launch on EtherCAT need their own interface and master index: every clash."""
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
    return errors


def _builtin_model(package: Path) -> str | None:
    """The robot_type whose built-in package this is, or None for a user's package."""
    if package.resolve().parent != BUILTIN_PACKAGES_DIR:
        return None
    return next((robot_type for robot_type, model in MODELS.items()
                 if model.MODEL.description_package == package.name), None)


def child_environment(plan: RobotPlan) -> dict[str, str]:
    """The environment of a robot's child processes: PLEM_ROBOT_ID, as the spec's launch passes it."""
    return {**os.environ, "PLEM_ROBOT_ID": plan.robot_id}
