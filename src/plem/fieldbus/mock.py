"""The simulated arm: `MockBus`, an IBus whose drives, encoders and joints are simulated.

Each cycle `write()` hands the commands to simulated CiA402 drives and advances the arm by one cycle
time; `read()` reports encoder counts, joint torques, statuswords and 0x603F error codes.

Drives. One CiA402 state machine per drive, stepped by the controlwords the bus sends for the pending
enable()/disable()/fault_reset() request, one state per cycle (switch on disabled → ready to switch on →
switched on → operation enabled takes three cycles). The bus chooses each controlword from the
statusword it last read, like a real master, so power states progress when read() and write() alternate.
A drive that is not enabled holds its joint with the brake: velocity 0, position frozen, torque 0. A
drive seen in fault, and every drive after a communication loss, stays down until enable() is called
again; enable() is ignored while a drive is in fault.

Joints. With a URDF and `dynamics=True` the arm is a pinocchio rigid body, integrated by semi-implicit
Euler once per cycle. In cyclic-sync position each drive runs a stiff computed-torque servo: the
commanded acceleration kp·(q_d − q) + kd·(v_d − v) is evaluated at the end of the cycle (implicitly,
so the servo is stable at any cycle time), turned into torque by inverse dynamics plus the viscous
friction, and applied through forward dynamics together with external torques. The target written in a
cycle is where the joint should be at the end of that cycle, with the velocity offset as feed-forward;
the drive's own model covers gravity, so the torque offset is not needed (and not used) in this mode.
A large position error drives the joint at its URDF velocity limit, and when the torques would exceed
the effort limits the servoed accelerations are scaled down together, so a step command moves the arm
to the target without oscillating. Cyclic-sync velocity tracks the velocity offset the same way;
cyclic-sync torque applies the torque offset, clamped to the effort limit. Braked and jammed joints are
locked in the dynamics (the rest moves as the constrained arm would); positions stop at the URDF limits.
Without dynamics every joint follows its target with a first-order lag and velocity is the derivative;
torques read 0 and cyclic-sync torque holds the joint still.

Encoders. raw position = round(q · counts_per_radian) + raw_zero, raw velocity = round(v · counts_per_radian),
so a calibration offset (minus the raw reading at home) maps raw counts back to the joint angle; a negative
counts_per_radian is an encoder that counts against the joint's axis.

Fault injection (for tests and demos): inject_drive_fault, inject_communication_loss /
restore_communication (the drives then quick-stop on their own ramp and hold position),
inject_encoder_spike, stick_joint, apply_external_torque / clear_external_torque; set_positions places
the arm while its drives are disabled, true_positions / true_velocities report the simulated state.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from plem.core.files import read_regular_text
from plem.description.model import MAX_XML_BYTES
from plem.errors import CommandRejected, ConfigError, PlemError
from plem.fieldbus.bus import BusIO, BusSetup, BusStatus, DriveState, OperationMode
from plem.fieldbus.cia402 import STATUSWORD, Controlword, PowerSequencer, decode_statusword, drive_transition

if TYPE_CHECKING:
    from plem.control.kinematics import ArmDynamics

_RUNNING = (DriveState.OPERATION_ENABLED, DriveState.QUICK_STOP_ACTIVE)
_BOUNDS: dict[str, Callable[[np.ndarray], bool]] = {
    "finite": lambda a: True, "positive": lambda a: bool(np.all(a > 0)),
    "non-negative": lambda a: bool(np.all(a >= 0)), "nonzero": lambda a: bool(np.all(a != 0))}


def _joint_array(name: str, values: float | Sequence[float], dof: int, *, bound: str = "finite",
                 error: type[PlemError] = ConfigError) -> np.ndarray:
    """One number for every joint or one per joint, as a float array; a PlemError when it is not that."""
    try:
        array = np.array(values, dtype=float)
    except (TypeError, ValueError):
        array = None
    if array is not None and array.ndim == 0:
        array = np.full(dof, float(array))
    if array is None or array.shape != (dof,) or not np.all(np.isfinite(array)) or not _BOUNDS[bound](array):
        raise error(f"invalid {name} for the simulated arm",
                    what=f"{name}: one {bound} number, or {dof} of them (one per joint)",
                    why=f"got {values!r}",
                    how=f"pass {name} as a number or a list of {dof} {bound} numbers")
    return array


def _number(name: str, value: float, *, positive: bool = False, error: type[PlemError] = ConfigError) -> float:
    """One finite (or positive) number, or a PlemError saying what was expected."""
    if isinstance(value, (int, float, np.number)) and math.isfinite(value) and (value > 0 or not positive):
        return float(value)
    kind = "positive" if positive else "finite"
    raise error(f"invalid {name} for the simulated arm", what=f"{name}: a {kind} number",
                why=f"got {value!r}", how=f"pass {name} as a {kind} number")


class _Drives:
    """The simulated CiA402 drives (state, statusword, error code) and the master side that sequences them."""

    def __init__(self, dof: int) -> None:
        self.states = [DriveState.SWITCH_ON_DISABLED] * dof
        self.statusword = np.full(dof, STATUSWORD[DriveState.SWITCH_ON_DISABLED], dtype=np.uint16)
        self.error_code = np.zeros(dof, dtype=np.uint16)
        self.controlword = [int(Controlword.DISABLE_VOLTAGE)] * dof  # the last one each drive received
        self.latched = [False] * dof
        self.master = PowerSequencer(dof)
        self.settled = True

    def set_state(self, drive: int, state: DriveState) -> None:
        self.states[drive] = state
        self.statusword[drive] = STATUSWORD[state]

    def request(self, state: DriveState) -> None:
        """Ask every drive for `state`; it is reached over the next cycles."""
        self.master.request(state)
        self.settled = False

    def request_reset(self) -> None:
        self.master.request_reset()
        self.settled = False

    def fault(self, drive: int, error_code: int, latched: bool) -> None:
        self.set_state(drive, DriveState.FAULT)
        self.error_code[drive] = error_code
        self.latched[drive] = latched
        self.settled = False

    def power_off(self) -> None:
        for drive, state in enumerate(self.states):
            if state is not DriveState.FAULT:
                self.set_state(drive, DriveState.SWITCH_ON_DISABLED)
        self.request(DriveState.SWITCH_ON_DISABLED)

    def lose_communication(self) -> bool:
        """Drives that no longer hear the master quick-stop; True when a drive changed state."""
        running = [d for d, s in enumerate(self.states) if s is DriveState.OPERATION_ENABLED]
        for drive in running:
            self.set_state(drive, DriveState.QUICK_STOP_ACTIVE)
        return bool(running)

    def exchange(self, seen_statuswords: np.ndarray) -> bool:
        """One cycle of controlwords chosen from the statuswords the master last read; True when a state changed."""
        previous = list(self.controlword)
        seen = [decode_statusword(int(sw)) for sw in seen_statuswords]
        commands = self.master.commands(seen)
        changed = self.apply(commands)
        self.settled = not changed and commands == previous and seen == self.states
        return changed

    def apply(self, commands: Sequence[int] | np.ndarray) -> bool:
        """The drives' side of one cycle: each takes its controlword; True when a state changed."""
        changed = False
        for drive, (state, command) in enumerate(zip(self.states, commands, strict=True)):
            previous, self.controlword[drive] = self.controlword[drive], int(command)
            new = drive_transition(state, int(command), previous)
            if state is DriveState.FAULT and new is not state:
                if self.latched[drive]:
                    new = state
                else:
                    self.error_code[drive] = 0
            if new is not state:
                self.set_state(drive, new)
                changed = True
        return changed


class MockBus:
    """A simulated arm behind the IBus interface: CiA402 drives, encoders, and rigid-body or first-order joints."""

    #: The rigid-body arm, set by open() when it builds one; only the dynamics step (chosen then) reads it.
    _dynamics: ArmDynamics

    def __init__(self, dof: int, urdf: str | os.PathLike[str] | None = None, *, dynamics: bool = True,
                 raw_zero: Sequence[int] | None = None, initial_positions: Sequence[float] | None = None,
                 viscous_friction: float | Sequence[float] = 0.05, effort_limits: Sequence[float] | None = None,
                 servo_bandwidth_hz: float = 50.0, follower_time_constant_s: float = 0.005,
                 quick_stop_deceleration: float = 10.0) -> None:
        if not isinstance(dof, int) or dof < 1:
            raise ConfigError("invalid joint count for the simulated arm", what="MockBus(dof) with dof ≥ 1",
                              why=f"got dof={dof!r}", how="pass the number of joints of the arm, e.g. MockBus(6)")
        self.dof = dof
        self._urdf = urdf
        self._want_dynamics = dynamics
        self._raw_zero = _joint_array("raw_zero", 0 if raw_zero is None else raw_zero, dof)
        if not np.all(self._raw_zero == np.round(self._raw_zero)):
            raise ConfigError("invalid raw_zero for the simulated arm", what="raw_zero: whole encoder counts",
                              why=f"got {raw_zero!r}", how="pass integers, e.g. raw_zero=[-535768, 0, ...]")
        self._friction = _joint_array("viscous_friction", viscous_friction, dof, bound="non-negative")
        self._effort_override = (None if effort_limits is None
                                 else _joint_array("effort_limits", effort_limits, dof, bound="positive"))
        self._bandwidth = _number("servo_bandwidth_hz", servo_bandwidth_hz, positive=True)
        self._lag = _number("follower_time_constant_s", follower_time_constant_s, positive=True)
        self._deceleration = _number("quick_stop_deceleration", quick_stop_deceleration, positive=True)
        self._q = _joint_array("initial_positions", 0.0 if initial_positions is None else initial_positions, dof)
        self._v = np.zeros(dof)
        self._tau = np.zeros(dof)
        self._external = np.zeros(dof)
        self._pushed = False
        self._stuck = np.zeros(dof, dtype=bool)
        self._spike = np.zeros(dof, dtype=np.int64)
        self._spiked = False
        self._lost = False
        self._lost_reads: int | None = None
        self._open = False
        self._arm: ArmDynamics | None = None
        self._drives = _Drives(dof)
        self.io = BusIO(dof)
        self.status = BusStatus()
        self._set_limits(None, ())

    # ---- IBus -------------------------------------------------------------------------------------

    def open(self, setup: BusSetup) -> None:
        """Size the process data for `setup` and build the simulated arm (rigid body when a URDF is given)."""
        if setup.dof != self.dof:
            raise ConfigError("the bus setup does not match the simulated arm",
                              what=f"a BusSetup naming {self.dof} joints, as the MockBus was created for {self.dof}",
                              why=f"the setup names {setup.dof}: {', '.join(setup.joint_names) or 'none'}",
                              how=f"create MockBus({setup.dof}) or open it with the arm's {self.dof} joint names")
        counts = _joint_array("counts_per_radian", setup.counts_per_radian, self.dof, bound="nonzero")
        dt = _number("cycle_time_s", setup.cycle_time_s, positive=True)
        urdf_xml = self._urdf_xml(setup)
        arm = None
        if self._want_dynamics and urdf_xml is not None:
            from plem.control.kinematics import ArmDynamics
            arm = ArmDynamics(urdf_xml, setup.joint_names)
        self._arm = arm
        if arm is not None:
            self._dynamics = arm
        self._counts = counts
        self._inv_counts = 1.0 / counts
        self._dt = dt
        self._dt_vec = np.full(self.dof, dt)
        self._follow = math.exp(-dt / self._lag)
        self._set_limits(arm, setup.joint_names)
        n = self.dof
        (self._qd, self._vd, self._a, self._work, self._friction_torque, self._probe, self._bias,
         self._no_acceleration) = np.zeros((8, n))
        self._stop_q, self._stop_v = np.zeros((2, n))
        self._outside, self._below, self._saturated = np.zeros((3, n), dtype=bool)
        self._stopping = np.zeros(n, dtype=bool)
        self._v[:] = 0.0
        self._tau[:] = 0.0
        self._drives = _Drives(n)
        self._lost = False
        self._lost_reads = None
        self.io = BusIO(n)
        self.status = BusStatus(expected_working_counter=3 * n)
        self._step = self._step_dynamics if arm is not None else self._step_follower
        self._configure()
        self._open = True

    def close(self) -> None:
        """Power the drives down (brakes hold the joints) and release the bus."""
        if self._open:
            self._drives.power_off()
            self._configure()
            self._open = False

    def read(self) -> bool:
        """Encoder counts, torques, statuswords and error codes into `io`; False while communication is lost."""
        if not self._open:
            raise self._not_open("read")
        status = self.status
        if self._lost and self._lost_reads != 0:
            if self._lost_reads is not None:
                self._lost_reads -= 1
            status.communication_ok = False
            status.working_counter = 0
            status.lost_frames += 1
            status.detail = "simulated communication loss: no drive answered"
            self._drives.master.master_lost()
            return False
        if self._lost:
            self.restore_communication()
        io = self.io
        work = self._work
        np.multiply(self._q, self._counts, out=work)
        work += self._raw_zero
        np.rint(work, out=work)
        io.position[:] = work
        if self._spiked:
            io.position += self._spike
            self._spike[:] = 0
            self._spiked = False
        np.multiply(self._v, self._counts, out=work)
        np.rint(work, out=work)
        io.velocity[:] = work
        io.torque[:] = self._tau
        io.statusword[:] = self._drives.statusword
        io.error_code[:] = self._drives.error_code
        if not status.communication_ok:
            status.communication_ok = True
            status.detail = ""
        status.working_counter = status.expected_working_counter
        return True

    def write(self) -> None:
        """Deliver this cycle's controlwords and commands, then advance the arm by one cycle time."""
        if not self._open:
            raise self._not_open("write")
        drives = self._drives
        if self._lost:
            self.quick_stop()
        elif not drives.settled and drives.exchange(self.io.statusword):
            self._dirty = True
        self._advance()

    def serve(self, controlwords: Sequence[int] | np.ndarray) -> None:
        """Be the drives of a real master: take its controlwords (not enable()/disable()) and advance one cycle.

        The virtual EtherCAT network runs its emulated drives this way; targets and modes come in `io`.
        """
        self._require_open("serve")
        if self._drives.apply(controlwords):
            self._dirty = True
        self._advance()

    def quick_stop(self) -> None:
        """The drives no longer hear their master: running ones quick-stop on their own ramp and hold."""
        if self._drives.lose_communication():
            self._dirty = True

    def _advance(self) -> None:
        """Advance the arm by one cycle under the drives' current states and modes."""
        if self._dirty or self.io.mode.tobytes() != self._modes:
            self._configure()
        if self._any_running:
            self._step()

    def drive_state(self, drive: int) -> DriveState:
        """The power state of one drive as its last statusword read reports it."""
        return decode_statusword(int(self.io.statusword[drive]))

    def enable(self) -> None:
        """Request operation enabled on every drive (three cycles from switch on disabled)."""
        self._require_open("enable")
        self._drives.request(DriveState.OPERATION_ENABLED)

    def disable(self) -> None:
        """Request switch on disabled on every drive; brakes then hold the joints."""
        self._require_open("disable")
        self._drives.request(DriveState.SWITCH_ON_DISABLED)

    def fault_reset(self) -> None:
        """Send one fault-reset edge to every drive seen in fault; it clears unless the fault persists."""
        self._require_open("fault_reset")
        self._drives.request_reset()

    # ---- simulated state and fault injection ------------------------------------------------------

    @property
    def simulates_dynamics(self) -> bool:
        """True when the open bus integrates rigid-body dynamics, False for the first-order follower."""
        return self._arm is not None

    @property
    def true_positions(self) -> np.ndarray:
        """Simulated joint angles (rad), a copy."""
        return self._q.copy()

    @property
    def true_velocities(self) -> np.ndarray:
        """Simulated joint velocities (rad/s), a copy."""
        return self._v.copy()

    @property
    def effort_limits(self) -> np.ndarray:
        """The torque each drive can apply (N·m, inf when unlimited), a copy; known once open."""
        return self._effort.copy()

    def set_positions(self, positions: Sequence[float]) -> None:
        """Place the simulated arm at `positions` (rad), at rest; only while no drive is enabled."""
        running = [d for d, s in enumerate(self._drives.states) if s in _RUNNING]
        if running:
            raise CommandRejected("the simulated arm cannot be moved by hand while drives are enabled",
                                  what="every drive out of operation enabled before set_positions()",
                                  why=f"drives {running} are enabled",
                                  how="call disable() and run a few read()/write() cycles first")
        self._q[:] = _joint_array("positions", positions, self.dof, error=CommandRejected)
        self._v[:] = 0.0

    def inject_drive_fault(self, joint: int, error_code: int = 0x7121, *, persistent: bool = False) -> None:
        """Put one drive in FAULT with `error_code` in 0x603F; a persistent one survives resets until cleared."""
        self._require_open("inject_drive_fault")
        drive = self._joint(joint)
        if not isinstance(error_code, int) or not 0 < error_code <= 0xFFFF:
            raise CommandRejected("invalid error code for an injected drive fault",
                                  what="a 0x603F error code between 0x0001 and 0xFFFF",
                                  why=f"got {error_code!r}", how="pass e.g. 0x7121 (motor blocked)")
        self._drives.fault(drive, error_code, persistent)
        self._dirty = True

    def clear_drive_fault(self, joint: int) -> None:
        """The cause of a persistent injected fault is gone: the next fault reset clears it."""
        self._drives.latched[self._joint(joint)] = False

    def inject_communication_loss(self, cycles: int | None = None) -> None:
        """Drop the exchange for `cycles` reads (None: until restore_communication()); drives quick-stop."""
        self._require_open("inject_communication_loss")
        if cycles is not None and (not isinstance(cycles, int) or cycles < 1):
            raise CommandRejected("invalid length for a communication loss",
                                  what="a number of cycles ≥ 1, or None for a loss until restored",
                                  why=f"got {cycles!r}", how="pass e.g. cycles=10")
        self._lost = True
        self._lost_reads = cycles

    def restore_communication(self) -> None:
        """End a communication loss: the next read() succeeds and controlwords reach the drives again."""
        self._lost = False
        self._lost_reads = None
        self._drives.settled = False

    def inject_encoder_spike(self, joint: int, counts: int) -> None:
        """The next successful read reports this joint's position off by `counts`, once."""
        self._spike[self._joint(joint)] += int(counts)
        self._spiked = True

    def stick_joint(self, joint: int, stuck: bool = True) -> None:
        """Jam a joint (it stays where it is whatever the command) or free it again."""
        drive = self._joint(joint)
        self._stuck[drive] = stuck
        self._v[drive] = 0.0
        self._dirty = True

    def apply_external_torque(self, joint_or_torques: int | Sequence[float], torque: float | None = None) -> None:
        """Push the arm: `apply_external_torque(joint, torque)` or one torque per joint (N·m); needs dynamics."""
        if isinstance(joint_or_torques, (int, np.integer)) and torque is not None:
            self._external[self._joint(joint_or_torques)] = _number("torque", torque, error=CommandRejected)
        elif torque is None:
            self._external[:] = _joint_array("external torques", joint_or_torques, self.dof, error=CommandRejected)
        else:
            raise CommandRejected("invalid external torque", what="(joint, torque) or one torque per joint",
                                  why=f"got {joint_or_torques!r} with torque={torque!r}",
                                  how="call apply_external_torque(1, 20.0) or apply_external_torque([0, 20.0, ...])")
        self._pushed = bool(np.any(self._external))

    def clear_external_torque(self) -> None:
        """Remove every external push."""
        self._external[:] = 0.0
        self._pushed = False

    # ---- internals --------------------------------------------------------------------------------

    def _joint(self, joint: int) -> int:
        if isinstance(joint, (int, np.integer)) and 0 <= joint < self.dof:
            return int(joint)
        raise CommandRejected("no such joint on the simulated arm", what=f"a joint index from 0 to {self.dof - 1}",
                              why=f"got {joint!r}", how="pass the joint's position in the arm's joint order")

    def _not_open(self, operation: str) -> PlemError:
        return PlemError("the simulated bus is not open",
                         what=f"open(setup) before {operation}()",
                         why=f"{operation}() was called on a MockBus that is not open",
                         how="call bus.open(BusSetup(joint_names, counts_per_radian, cycle_time_s)) first")

    def _require_open(self, operation: str) -> None:
        if not self._open:
            raise self._not_open(operation)

    def _urdf_xml(self, setup: BusSetup) -> str | None:
        """The URDF as text: given as XML, or read from the path given (a regular UTF-8 file of at most
        MAX_XML_BYTES, else a ConfigError saying what it is)."""
        source = self._urdf if self._urdf is not None else setup.urdf_xml
        if source is None or isinstance(source, str) and source.lstrip().startswith("<"):
            return source
        return read_regular_text(Path(source), MAX_XML_BYTES, "URDF")

    def _set_limits(self, arm: ArmDynamics | None, joint_names: Sequence[str]) -> None:
        """Effort and position limits in joint order, from the URDF (or the effort_limits argument)."""
        n = self.dof
        effort, speed = np.full(n, math.inf), np.full(n, math.inf)
        lower, upper = np.full(n, -math.inf), np.full(n, math.inf)
        if arm is not None:
            model = arm.model
            for drive, name in enumerate(joint_names):
                joint = model.joints[model.getJointId(name)]
                effort[drive], speed[drive] = model.effortLimit[joint.idx_v], model.velocityLimit[joint.idx_v]
                low, high = model.lowerPositionLimit[joint.idx_q], model.upperPositionLimit[joint.idx_q]
                if low < high:
                    lower[drive], upper[drive] = low, high
            effort[~(effort > 0)] = math.inf
            speed[~(speed > 0)] = math.inf
        if self._effort_override is not None:
            effort = self._effort_override.copy()
        self._effort, self._neg_effort = effort, -effort
        self._lower, self._upper = lower, upper
        self._max_error = speed / (math.pi * self._bandwidth)  # error at which kp/kd·error = speed limit
        self._min_error = -self._max_error
        self._limited = bool(np.any(np.isfinite(lower)) or np.any(np.isfinite(upper)))

    def _configure(self) -> None:
        """Per-joint servo gains and masks for the current drive states, modes and jams (not per cycle)."""
        io = self.io
        self._modes = io.mode.tobytes()
        states = self._drives.states
        running = np.array([s in _RUNNING for s in states])
        stopping = np.array([s is DriveState.QUICK_STOP_ACTIVE for s in states])
        commanded = running & ~stopping
        position = stopping | commanded & (io.mode == OperationMode.CYCLIC_SYNC_POSITION)
        velocity = commanded & (io.mode == OperationMode.CYCLIC_SYNC_VELOCITY)
        torque = commanded & (io.mode == OperationMode.CYCLIC_SYNC_TORQUE)
        held = ~(position | velocity | torque) | self._stuck
        if self._arm is None:
            held |= torque
        self._v[held] = 0.0
        started = stopping & ~self._stopping
        self._stop_q[started] = self._q[started]
        self._stop_v[started] = self._v[started]
        omega = 2.0 * math.pi * self._bandwidth
        kp = np.where(position, omega * omega, 0.0)
        kd = np.where(position | velocity, 2.0 * omega, 0.0)
        implicit = 1.0 + kd * self._dt + kp * self._dt ** 2
        self._position_gain, self._velocity_gain = kp / implicit, kd / implicit
        self._stopping, self._held, self._torque_mode, self._velocity_mode = stopping, held, torque, velocity
        self._commanded = (position | velocity) & ~held
        self._brake = ~running
        self._tau[self._brake] = 0.0
        self._any_running = bool(running.any())
        self._any_stopping = bool(stopping.any())
        self._any_held = bool(held.any())
        self._held_joints = np.flatnonzero(held)
        self._unit_response = np.zeros((len(self._held_joints), self.dof))
        self._any_brake = bool(self._brake.any())
        self._any_torque = bool(torque.any())
        self._any_velocity = bool(velocity.any())
        self._servoed = bool(self._commanded.any() or self._any_held)
        self._dirty = False

    def _targets(self) -> None:
        """Commanded positions and velocities in SI; quick-stopping drives follow their own stop ramp."""
        io = self.io
        qd, vd = self._qd, self._vd
        qd[:] = io.target_position
        qd -= self._raw_zero
        qd *= self._inv_counts
        vd[:] = io.velocity_offset
        vd *= self._inv_counts
        if self._any_stopping:
            speed = np.maximum(np.abs(self._stop_v) - self._deceleration * self._dt, 0.0)
            np.copysign(speed, self._stop_v, out=self._stop_v)
            self._stop_q += self._stop_v * self._dt
            np.copyto(self._qd, self._stop_q, where=self._stopping)
            np.copyto(self._vd, self._stop_v, where=self._stopping)

    def _step_dynamics(self) -> None:
        """One cycle of the rigid-body arm under its drives' servos, brakes, jams and pushes."""
        q, v, a, work, tau = self._q, self._v, self._a, self._work, self._tau
        arm = self._dynamics
        self._targets()
        friction = np.multiply(v, self._friction, out=self._friction_torque)
        clamp = self._any_torque
        if self._servoed:
            self._servo_acceleration(a)
            arm.inverse_dynamics(q, v, a, tau)
            tau += friction
            np.abs(tau, out=work)
            if np.count_nonzero(np.greater(work, self._effort, out=self._saturated)):
                self._fit_effort(tau)
                clamp = True
        if self._any_torque:
            np.copyto(tau, self.io.torque_offset, where=self._torque_mode)
        if clamp:
            np.minimum(tau, self._effort, out=tau)
            np.maximum(tau, self._neg_effort, out=tau)
        if self._any_brake:
            np.copyto(tau, 0.0, where=self._brake)
        np.subtract(tau, friction, out=work)
        if self._pushed:
            work += self._external
        arm.forward_dynamics(q, v, work, a)
        if self._any_held:
            self._lock_held(work, a)
        a *= self._dt_vec
        v += a
        np.multiply(v, self._dt_vec, out=work)
        q += work
        if self._limited:
            self._hard_stop()

    def _servo_acceleration(self, a: np.ndarray) -> None:
        """The drives' PD law evaluated at the cycle's end, into `a`:
        (kp·(q_d − q − dt·v) + kd·(v_d − v)) / (1 + kd·dt + kp·dt²), zero for held joints.

        The position error is capped so that a large one drives the joint at its URDF velocity limit
        instead of winding up the torque.
        """
        work = self._work
        np.multiply(self._v, self._dt_vec, out=work)
        np.subtract(self._qd, self._q, out=a)
        a -= work
        np.minimum(a, self._max_error, out=a)
        np.maximum(a, self._min_error, out=a)
        a *= self._position_gain
        np.subtract(self._vd, self._v, out=work)
        work *= self._velocity_gain
        a += work
        if self._any_held:
            np.copyto(a, 0.0, where=self._held)

    def _fit_effort(self, tau: np.ndarray) -> None:
        """Scale the servoed joints' accelerations down together until their torques fit the effort limits.

        Torque is affine in the acceleration (τ = M·a + bias), so one scale keeps the motion's direction
        and the joints' coupling consistent; joints whose bias alone exceeds the limit are clamped later.
        """
        bias = self._dynamics.inverse_dynamics(self._q, self._v, self._no_acceleration, self._bias)
        bias += self._friction_torque
        inertial = tau - bias
        fits = self._commanded & (np.abs(bias) < self._effort) & (inertial != 0)
        if fits.any():
            bounds = (np.copysign(self._effort[fits], inertial[fits]) - bias[fits]) / inertial[fits]
            tau[:] = bias + min(1.0, float(bounds.min())) * inertial

    def _lock_held(self, torque: np.ndarray, a: np.ndarray) -> None:
        """Turn free-arm accelerations into those with the braked or jammed joints locked.

        The locks add torques λ on the held joints so that their accelerations vanish; the accelerations
        are affine in λ with the columns of M⁻¹, one more forward-dynamics call per held joint.
        """
        held, columns, probe = self._held_joints, self._unit_response, self._probe
        for row, joint in enumerate(held):
            probe[:] = torque
            probe[joint] += 1.0
            self._dynamics.forward_dynamics(self._q, self._v, probe, columns[row])
            columns[row] -= a
        a += columns.T @ np.linalg.solve(columns[:, held].T, -a[held])
        a[held] = 0.0

    def _hard_stop(self) -> None:
        """Joints past a URDF position limit stop at it."""
        outside, below = self._outside, self._below
        np.greater(self._q, self._upper, out=outside)
        np.less(self._q, self._lower, out=below)
        outside |= below
        if np.count_nonzero(outside):
            np.minimum(self._q, self._upper, out=self._q)
            np.maximum(self._q, self._lower, out=self._q)
            np.copyto(self._v, 0.0, where=outside)

    def _step_follower(self) -> None:
        """One cycle without dynamics: positions lag their targets by a first-order time constant."""
        q, v, nxt = self._q, self._v, self._work
        self._targets()
        np.subtract(q, self._qd, out=nxt)
        nxt *= self._follow
        nxt += self._qd
        if self._any_velocity:
            np.multiply(self._vd, self._dt_vec, out=self._a)
            self._a += q
            np.copyto(nxt, self._a, where=self._velocity_mode)
        if self._any_held:
            np.copyto(nxt, q, where=self._held)
        np.subtract(nxt, q, out=v)
        v /= self._dt_vec
        q[:] = nxt
