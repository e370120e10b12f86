"""SerialArmConfig: the runtime configuration of one serial arm, and its validation rules."""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

from plem.core.config.settings import Setting, parse_int, parse_optional_text, parse_text
from plem.errors import ConfigError, PlemError, raise_collected
from plem.robot.serial import serial_problem

if TYPE_CHECKING:
    from plem.fieldbus.bus import IBus
    from plem.robot.models import ArmModel

SUPPORTED_DOF = (6, 7)
RT_PRIORITY_RANGE = (1, 98)
CYCLE_TIME_RANGE_US = (250, 2000)
RT_KERNEL_MIN_CYCLE_US = 1000
INT32_RANGE = (-(2**31), 2**31 - 1)
IFNAMSIZ = 16
RT_KERNEL_FLAG = Path("/sys/kernel/realtime")
_ROS_NAME_TOKEN = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
#: Characters of a robot_id. Its longest use is the socket of its command service, /dev/shm/{robot_id}_commands,
#: whose path a Unix socket holds in 107 bytes: 64 leaves room, and is plenty for a name.
MAX_ROBOT_ID_CHARS = 64


def _parse_robot_id(text: str) -> str:
    return text.strip()


ARM_SETTINGS: tuple[Setting, ...] = (
    Setting("network_interface", parse_text, "an interface name such as eth0 or enp3s0",
            "EtherCAT network interface", env="PLEM_NETWORK_INTERFACE", launch="eth_interface"),
    Setting("master_index", parse_int, "a whole number of 0 or more",
            "EtherCAT master index", env="PLEM_MASTER_INDEX", launch="master_index"),
    Setting("cycle_time", parse_int, "microseconds from 250 to 2000, e.g. 1000",
            "control loop period in µs", env="PLEM_CYCLE_TIME_US", launch="cycle_time"),
    Setting("rt_priority", parse_int, "a whole number from 1 to 98",
            "SCHED_FIFO priority of the RT loop", env="PLEM_RT_PRIORITY", launch="rt_priority"),
    Setting("robot_serial", parse_optional_text, "a serial such as PE07I7E0E001",
            "serial used to load ~/.plem/profiles/<serial>.json", env="PLEM_ROBOT_SERIAL", launch="robot_serial"),
    Setting("robot_id", _parse_robot_id, "a ROS 2 name token such as arm_left",
            "instance id: namespace and shared-memory prefix", env="PLEM_ROBOT_ID", launch="robot_id"),
)


@dataclass
class SerialArmConfig:
    """Configuration of a serial arm with `dof` joints; field names and defaults follow the reference.

    Values are checked by `validate()` (the builder calls it), so a config can be built and edited freely.
    Interface checks that need the machine run when a bus opens (`plem.fieldbus.check_network_interface`).
    """

    MODEL: ClassVar[ArmModel | None] = None

    dof: int
    network_interface: str = "eth0"
    master_index: int = 0
    cycle_time: int = 1000
    rt_priority: int = 98
    robot_serial: str | None = None
    joint_offsets: list[int] = field(default_factory=list)
    robot_id: str = ""
    custom_bus: IBus | None = None

    def __post_init__(self) -> None:
        if not self.joint_offsets and isinstance(self.dof, int) and self.dof > 0:
            self.joint_offsets = [0] * self.dof

    @classmethod
    def model_name(cls) -> str:
        """The preset's name (e.g. 'Indy7V2'), or 'SerialArmConfig' for a custom arm."""
        return cls.MODEL.name if cls.MODEL else cls.__name__

    def field_values(self) -> dict[str, Any]:
        """Every field by name, for resolution and display."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def problems(self, sources: Mapping[str, Any] | None = None) -> list[PlemError]:
        """Every rule this config breaks, each naming the field's source when `sources` is given."""
        return [error for error in (check(self, sources or {}) for check in _CHECKS) if error]

    def validate(self, sources: Mapping[str, Any] | None = None, rt_kernel_flag: Path = RT_KERNEL_FLAG) -> list[str]:
        """Check every rule; raise all violations together, return warnings (e.g. a fast cycle without RT)."""
        raise_collected(self.problems(sources), "the arm configuration")
        return self.warnings(rt_kernel_flag)

    def warnings(self, rt_kernel_flag: Path = RT_KERNEL_FLAG) -> list[str]:
        """Legal but risky choices, such as a sub-millisecond cycle without a PREEMPT_RT kernel."""
        warnings: list[str] = []
        if self.cycle_time < RT_KERNEL_MIN_CYCLE_US and not rt_kernel_flag.exists():
            warnings.append(
                f"cycle_time {self.cycle_time} µs is below {RT_KERNEL_MIN_CYCLE_US} µs and needs a PREEMPT_RT kernel, "
                f"but {rt_kernel_flag} is absent (not an RT kernel): expect missed deadlines"
            )
        return warnings


def _origin(name: str, sources: Mapping[str, Any]) -> str:
    source = sources.get(name)
    return f" (from {source})" if source else ""


def _check_dof(cfg: SerialArmConfig, sources: Mapping[str, Any]) -> PlemError | None:
    if isinstance(cfg.dof, int) and cfg.dof in SUPPORTED_DOF:
        return None
    return ConfigError(
        f"DOF {cfg.dof} is not supported",
        what=f"an arm with {' or '.join(map(str, SUPPORTED_DOF))} actuated joints",
        why=f"dof is {cfg.dof!r}",
        how="describe the arm with 6 or 7 actuated (revolute, prismatic or continuous) joints in its URDF",
    )


def _check_network_interface(cfg: SerialArmConfig, sources: Mapping[str, Any]) -> PlemError | None:
    name = cfg.network_interface
    if isinstance(name, str) and name and len(name) < IFNAMSIZ and not re.search(r"[\s/:]", name):
        return None
    return ConfigError(
        "network_interface is not a valid interface name",
        what=f"an interface name of 1-{IFNAMSIZ - 1} characters without spaces, '/' or ':' (e.g. eth0, enp3s0)",
        why=f"network_interface is {name!r}{_origin('network_interface', sources)}",
        how="list interfaces with `ip link show` and pass eth_interface:=<name>",
    )


def _check_master_index(cfg: SerialArmConfig, sources: Mapping[str, Any]) -> PlemError | None:
    if isinstance(cfg.master_index, int) and not isinstance(cfg.master_index, bool) and cfg.master_index >= 0:
        return None
    return ConfigError(
        "master_index out of range",
        what="an EtherCAT master index of 0 or more (0 for a single robot)",
        why=f"master_index is {cfg.master_index!r}{_origin('master_index', sources)}",
        how="set master_index:=0, or the index of the master for this robot (ls /dev/EtherCAT*)",
    )


def _check_cycle_time(cfg: SerialArmConfig, sources: Mapping[str, Any]) -> PlemError | None:
    low, high = CYCLE_TIME_RANGE_US
    if isinstance(cfg.cycle_time, int) and not isinstance(cfg.cycle_time, bool) and low <= cfg.cycle_time <= high:
        return None
    return ConfigError(
        "cycle_time out of range",
        what=f"a control period from {low} µs (4 kHz, experimental) to {high} µs (500 Hz); 1000 µs is typical",
        why=f"cycle_time is {cfg.cycle_time!r} µs{_origin('cycle_time', sources)}",
        how="set cycle_time:=1000 (it must also match the EtherCAT cycle of the drives)",
    )


def _check_rt_priority(cfg: SerialArmConfig, sources: Mapping[str, Any]) -> PlemError | None:
    low, high = RT_PRIORITY_RANGE
    value = cfg.rt_priority
    if isinstance(value, int) and not isinstance(value, bool) and low <= value <= high:
        return None
    if value == 99:
        why = (f"rt_priority is 99{_origin('rt_priority', sources)}; 99 is reserved for kernel watchdogs and "
               "interrupt threads, and a busy loop above them can deadlock or freeze the machine")
    else:
        why = f"rt_priority is {value!r}{_origin('rt_priority', sources)}"
    return ConfigError(
        "rt_priority out of range",
        what=f"a SCHED_FIFO priority from {low} to {high} (95-98 in production, 50-80 for development)",
        why=why,
        how="set rt_priority:=98 (or 80 while developing)",
    )


def _check_robot_serial(cfg: SerialArmConfig, sources: Mapping[str, Any]) -> PlemError | None:
    if cfg.robot_serial is None:
        return None
    problem = serial_problem(cfg.robot_serial)
    if problem is None:
        return None
    return ConfigError(
        "robot_serial is not a valid serial",
        what="a serial usable as a file name: letters, digits, '.', '_' or '-' (e.g. PE07I7E0E001)",
        why=f"robot_serial {cfg.robot_serial!r}{_origin('robot_serial', sources)}: {problem}",
        how="use the serial printed on the robot, e.g. robot_serial:=PE07I7E0E001",
    )


def offsets_problem(offsets: Any, dof: int) -> str | None:
    """Why `offsets` is not a list of exactly `dof` int32 encoder counts, or None when it is."""
    if not isinstance(offsets, (list, tuple)):
        return f"joint_offsets is {type(offsets).__name__}, not a list"
    if len(offsets) != dof:
        return f"joint_offsets must have exactly {dof} elements; found {len(offsets)}"
    low, high = INT32_RANGE
    for index, value in enumerate(offsets):
        if not isinstance(value, int) or isinstance(value, bool):
            return f"joint_offsets[{index}] is {value!r}, not a whole number of encoder counts"
        if not low <= value <= high:
            return f"joint_offsets[{index}] is {value}, outside the int32 range {low}..{high}"
    return None


def _check_joint_offsets(cfg: SerialArmConfig, sources: Mapping[str, Any]) -> PlemError | None:
    if not isinstance(cfg.dof, int):
        return None
    problem = offsets_problem(cfg.joint_offsets, cfg.dof)
    if problem is None:
        return None
    return ConfigError(
        problem.split(";")[0],
        what=f"{cfg.dof} int32 encoder offsets (raw counts), one per joint",
        why=problem + _origin("joint_offsets", sources),
        how="give one offset per joint (negated raw reading at home), e.g. "
            f"plem profile create --serial <serial> --offsets {','.join(['0'] * cfg.dof)}",
    )


def ros_token_problem(name: Any, max_chars: int) -> str | None:
    """Why `name` is not a ROS 2 name token (letters, digits and single underscores, not starting with a digit) of
    1 to `max_chars` characters, or None when it is one."""
    if not isinstance(name, str):
        return f"it is {type(name).__name__}, not text"
    if not 0 < len(name) <= max_chars:
        return f"it has {len(name)} characters; at most {max_chars} are allowed" if name else "it is empty"
    if not _ROS_NAME_TOKEN.fullmatch(name):
        return "only letters, digits and '_' are allowed, and it must not start with a digit"
    if "__" in name:
        return "repeated underscores are not allowed in ROS 2 names"
    return None


def robot_id_problem(robot_id: Any) -> str | None:
    """Why `robot_id` cannot be a ROS 2 namespace token of at most MAX_ROBOT_ID_CHARS characters, or None when it
    can (empty means no namespace)."""
    return None if robot_id == "" else ros_token_problem(robot_id, MAX_ROBOT_ID_CHARS)


def _check_robot_id(cfg: SerialArmConfig, sources: Mapping[str, Any]) -> PlemError | None:
    problem = robot_id_problem(cfg.robot_id)
    if problem is None:
        return None
    return ConfigError(
        "robot_id is not a valid ROS 2 namespace",
        what=f"a ROS 2 name token of at most {MAX_ROBOT_ID_CHARS} characters: letters, digits and single "
             "underscores, not starting with a digit",
        why=f"robot_id {cfg.robot_id!r}{_origin('robot_id', sources)}: {problem}",
        how="choose an id such as robot_id:=arm_left",
    )


_CHECKS = (
    _check_dof, _check_network_interface, _check_master_index, _check_cycle_time,
    _check_rt_priority, _check_robot_serial, _check_joint_offsets, _check_robot_id,
)
