"""The emulated CiA402 drives of the virtual network, moving the simulated arm of `bus:=mock`.

The simulated arm's encoders count through the same encoder resolution, gear ratio and direction the
description package gives the master:

    motor counts = direction · q · encoder_resolution · gear_ratio / 2π + raw_zero
    torque (0x6077, 0x60B2) = thousandths of the rated motor torque 0x6076 (mN·m); joint torque = motor · gear

The arm is the simulated arm itself (`MockBus.serve`): its CiA402 state machines take the master's
controlwords, its dynamics integrate one cycle per process-data frame, so a motion on the virtual network
is the same motion as on `bus:=mock`. Between frames nothing moves; when frames stop, `idle_tick` keeps
the drives' own clock running so a quick stop ramps down as a real drive's does.

Fault injection: a drive fault with a chosen 0x603F code, a drive that refuses to enable (it stays
switched on, as one without motor power does).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from plem.description.drives import DriveParameters
from plem.fieldbus.bus import BusSetup, OperationMode
from plem.fieldbus.cia402 import Controlword
from plem.fieldbus.mock import MockBus

#: Rated motor torque reported (0x6076, mN·m) for a joint whose URDF gives no effort limit.
DEFAULT_RATED_TORQUE_MNM = 1000
_ENABLE_OPERATION_BIT = 0x0008


class EmulatedDrives:
    """CiA402 drives in cyclic synchronous position behind the virtual network (a `DriveApplication`)."""

    def __init__(self, joint_names: Sequence[str], urdf_xml: str | None, drives: Sequence[DriveParameters],
                 cycle_time_s: float, raw_zero: Sequence[int] | None = None,
                 initial_positions: Sequence[float] | None = None,
                 home_position: Sequence[float] | None = None,
                 position_limits: tuple[tuple[float, ...], tuple[float, ...]] | None = None) -> None:
        n = len(joint_names)
        self.count = n
        self.arm = MockBus(n, urdf_xml, raw_zero=raw_zero, initial_positions=initial_positions)
        self.arm.open(BusSetup(tuple(joint_names), tuple(d.signed_counts_per_radian for d in drives), cycle_time_s,
                               urdf_xml, home_position=None if home_position is None else tuple(home_position),
                               position_limits=position_limits))
        gear_ratio = np.array([d.gear_ratio for d in drives])
        effort = self.arm.effort_limits
        rated = np.where(np.isfinite(effort), np.round(effort / gear_ratio * 1000.0), DEFAULT_RATED_TORQUE_MNM)
        self.rated_torque = np.maximum(rated, 1).astype(np.uint32)
        direction = np.array([d.direction for d in drives])
        self._joint_torque_per_unit = self.rated_torque / 1e6 * gear_ratio * direction  # N·m per thousandth
        self.controlword = np.zeros(n, dtype=np.uint16)
        self.target_position = np.zeros(n, dtype=np.int32)
        self.velocity_offset = np.zeros(n, dtype=np.int32)
        self.torque_offset = np.zeros(n, dtype=np.int16)
        self.mode = np.full(n, OperationMode.CYCLIC_SYNC_POSITION, dtype=np.int8)
        self.statusword = np.zeros(n, dtype=np.uint16)
        self.position_actual = np.zeros(n, dtype=np.int32)
        self.velocity_actual = np.zeros(n, dtype=np.int32)
        self.torque_actual = np.zeros(n, dtype=np.int16)
        self.error_code = np.zeros(n, dtype=np.uint16)
        self.mode_display = np.zeros(n, dtype=np.int8)
        self.digital_inputs = np.zeros(n, dtype=np.uint32)
        self.refusing_enable = np.zeros(n, dtype=bool)
        self._commands = np.zeros(n, dtype=np.uint16)  # what each drive obeys: the last outputs it received in OP
        self._latch_inputs()
        self.target_position[:] = self.position_actual

    # ---- DriveApplication ---------------------------------------------------------------------------

    def step(self, operational: np.ndarray) -> None:
        """One cycle: the outputs of drives whose slave is in OP take effect, the arm moves, inputs latch."""
        io = self.arm.io
        np.copyto(self._commands, self.controlword, where=operational)
        self._commands[self.refusing_enable] &= ~np.uint16(_ENABLE_OPERATION_BIT)
        io.target_position[:] = self.target_position
        io.velocity_offset[:] = self.velocity_offset
        io.torque_offset[:] = self.torque_offset * self._joint_torque_per_unit
        io.mode[:] = self.mode
        self.arm.serve(self._commands)
        self._latch_inputs()

    def communication_lost(self, drive: int) -> None:
        """Process data stopped reaching `drive`: like every drive of the arm, it quick-stops and holds.

        Stale outputs are forgotten: until the master writes again, each drive's own command is quick stop.
        """
        self._commands[:] = Controlword.QUICK_STOP
        self.arm.quick_stop()
        self._latch_inputs()

    def idle_tick(self) -> None:
        """Advance one cycle with no frame from the master (the drives' own clock), keeping their states."""
        self.arm.serve(self._commands)
        self._latch_inputs()

    # ---- fault injection ------------------------------------------------------------------------------

    def inject_fault(self, drive: int, error_code: int, persistent: bool = False) -> None:
        """Drive `drive` faults with 0x603F = `error_code` (persistent: a reset does not clear it)."""
        self.arm.inject_drive_fault(drive, error_code, persistent=persistent)
        self._latch_inputs()

    def clear_fault(self, drive: int) -> None:
        """The cause of a persistent fault is gone: the next fault reset clears it."""
        self.arm.clear_drive_fault(drive)

    def refuse_enable(self, drive: int, refuse: bool = True) -> None:
        """Drive `drive` ignores enable operation (no motor power): it stays switched on."""
        self.refusing_enable[drive] = refuse

    # ---- internals ------------------------------------------------------------------------------------

    def _latch_inputs(self) -> None:
        arm = self.arm
        arm.read()
        io = arm.io
        self.statusword[:] = io.statusword
        self.error_code[:] = io.error_code
        self.position_actual[:] = io.position
        self.velocity_actual[:] = io.velocity
        torque = np.clip(np.rint(io.torque / self._joint_torque_per_unit), -32768, 32767)
        self.torque_actual[:] = torque.astype(np.int16)
        self.mode_display[:] = self.mode
        self.digital_inputs[:] = arm.digital_inputs
