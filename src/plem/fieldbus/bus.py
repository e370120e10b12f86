"""The bus interface every fieldbus implements (EtherCAT, the simulated MockBus, custom buses).

The loop talks to drives only through `IBus`: once per cycle it calls `read()` to receive the actual
values into the bus's `BusIO` buffers and `write()` to send the commands it put there. Buffers are
preallocated numpy arrays filled in place, so a cycle allocates nothing. Positions and velocities are
raw encoder counts (the bus boundary is the only place counts exist); torques are N·m at the joint.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np

if TYPE_CHECKING:
    from plem.description.drives import DriveParameters


class DriveState(IntEnum):
    """CiA402 power state of one drive, decoded from its statusword (0x6041)."""

    NOT_READY_TO_SWITCH_ON = 0
    SWITCH_ON_DISABLED = 1
    READY_TO_SWITCH_ON = 2
    SWITCHED_ON = 3
    OPERATION_ENABLED = 4
    QUICK_STOP_ACTIVE = 5
    FAULT_REACTION_ACTIVE = 6
    FAULT = 7


class OperationMode(IntEnum):
    """CiA402 modes of operation (0x6060) the loop uses."""

    CYCLIC_SYNC_POSITION = 8
    CYCLIC_SYNC_VELOCITY = 9
    CYCLIC_SYNC_TORQUE = 10


@dataclass(frozen=True)
class BusSetup:
    """What a bus needs to know about the arm when it opens.

    `counts_per_radian` is signed: negative where a drive counts against the joint's axis. `drives` are
    the description package's drive parameters (ids, gearing, direction), empty when it has none.
    `home_position` is the SRDF's `home` pose in joint order, when it names every joint. `position_limits` are
    the lowest and highest positions the driver allows each joint (joint_limits.yaml within the URDF's), for a
    simulated arm to start inside them.
    """

    joint_names: tuple[str, ...]
    counts_per_radian: tuple[float, ...]
    cycle_time_s: float
    urdf_xml: str | None = None
    network_interface: str = "eth0"
    master_index: int = 0
    drives: tuple[DriveParameters, ...] = ()
    home_position: tuple[float, ...] | None = None
    position_limits: tuple[tuple[float, ...], tuple[float, ...]] | None = None

    @property
    def dof(self) -> int:
        """Number of drives on the bus, one per joint."""
        return len(self.joint_names)


class BusIO:
    """Process data of one cycle, one slot per drive, in the order of the arm's joints.

    Inputs (filled by `read()`): position, velocity, torque, statusword, error_code.
    Outputs (read by `write()`): target_position, velocity_offset, torque_offset, mode.
    In cyclic-sync-position mode the drive tracks target_position with the offsets as feed-forward;
    in cyclic-sync-torque mode it applies torque_offset as the target torque.
    """

    __slots__ = ("dof", "position", "velocity", "torque", "statusword", "error_code",
                 "target_position", "velocity_offset", "torque_offset", "mode")

    def __init__(self, dof: int) -> None:
        self.dof = dof
        self.position = np.zeros(dof, dtype=np.int64)
        self.velocity = np.zeros(dof, dtype=np.int64)
        self.torque = np.zeros(dof)
        self.statusword = np.zeros(dof, dtype=np.uint16)
        self.error_code = np.zeros(dof, dtype=np.uint16)
        self.target_position = np.zeros(dof, dtype=np.int64)
        self.velocity_offset = np.zeros(dof, dtype=np.int64)
        self.torque_offset = np.zeros(dof)
        self.mode = np.full(dof, OperationMode.CYCLIC_SYNC_POSITION, dtype=np.int8)


@dataclass
class BusStatus:
    """Health of the bus after the last exchange, for the loop to act on."""

    communication_ok: bool = True
    working_counter: int = 0
    expected_working_counter: int = 0
    lost_frames: int = 0
    working_counter_errors: int = 0
    detail: str = ""


class SteppedBus(Protocol):
    """A bus whose cycle the compiled core steps itself (the EtherCAT master): Python opens and closes it, reads
    its status, hands it to the core (`core_master`) and serves it beside the cycle."""

    @property
    def status(self) -> BusStatus:
        """Working counter, lost frames, and who fell silent while communication is lost."""
        ...

    @property
    def core_master(self) -> Any:
        """What the core exchanges through."""
        ...

    def open(self, setup: BusSetup) -> None:
        """Bring the drives up, disabled; raises a PlemError when it cannot."""
        ...

    def close(self) -> None:
        """Release the bus once the core no longer cycles it; drives are left disabled."""
        ...

    def hand_over(self) -> None:
        """The core's cycle exchanges from now on."""
        ...

    def service(self) -> None:
        """Work beside the cycle (e.g. recovery), called often from a thread that is not real-time."""
        ...


@runtime_checkable
class IBus(Protocol):
    """A fieldbus with `dof` CiA402 drives. Power-state requests take effect over the next cycles."""

    io: BusIO
    status: BusStatus

    def open(self, setup: BusSetup) -> None:
        """Connect to the drives and size the process data; raises a PlemError when it cannot."""
        ...

    def close(self) -> None:
        """Release the bus; drives are left disabled."""
        ...

    def read(self) -> bool:
        """Receive this cycle's actual values into `io`; False when communication failed."""
        ...

    def write(self) -> None:
        """Send the commands in `io` (and the controlwords of pending power-state requests)."""
        ...

    def drive_state(self, drive: int) -> DriveState:
        """The CiA402 power state of one drive, from its last statusword."""
        ...

    def enable(self) -> None:
        """Request operation-enabled on every drive (shutdown → switch on → enable operation)."""
        ...

    def disable(self) -> None:
        """Request switch-on-disabled on every drive."""
        ...

    def fault_reset(self) -> None:
        """Request a fault reset (controlword bit 7 rising edge) on every drive in fault."""
        ...
