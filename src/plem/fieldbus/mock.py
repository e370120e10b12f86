"""The simulated arm: `MockBus`, an IBus whose drives, encoders and joints are simulated.

Each cycle `write()` hands the commands to simulated CiA402 drives and advances the arm by one cycle
time; `read()` reports encoder counts, joint torques, statuswords and 0x603F error codes. Drives, servos and
physics are the compiled core's simulated arm (`plem_sim` in plem.control.csrc): this class sets it up,
validates what a user gives it and injects faults; each read and write is one call into the core, whose
structure the bus's `io` arrays view.

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
locked in the dynamics (the rest moves as the constrained arm would); positions stop at the URDF limits
(continuous joints have none: their angle goes on turning, unwrapped).
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
from typing import TYPE_CHECKING, Any

import numpy as np

from plem.control import compiled
from plem.core.files import read_regular_text
from plem.description.model import MAX_XML_BYTES
from plem.errors import CommandRejected, ConfigError, PlemError
from plem.fieldbus.bus import BusIO, BusSetup, BusStatus, DriveState, OperationMode
from plem.fieldbus.cia402 import STATUSWORD, decode_statusword

if TYPE_CHECKING:
    from plem.control.kinematics import ArmDynamics
    from plem.control.payload import Payload

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


def _vector(name: str, values: Sequence[float]) -> np.ndarray:
    """Three finite numbers, or a CommandRejected saying so."""
    try:
        array = np.array(values, dtype=float)
    except (TypeError, ValueError):
        array = None
    if array is None or array.shape != (3,) or not np.all(np.isfinite(array)):
        raise CommandRejected(f"invalid {name} for a push", what=f"{name} as three finite numbers (x, y, z)",
                              why=f"got {values!r}", how=f"pass e.g. {name}=(0, 0, -20)")
    return array


def _number(name: str, value: float, *, positive: bool = False, error: type[PlemError] = ConfigError) -> float:
    """One finite (or positive) number, or a PlemError saying what was expected."""
    if isinstance(value, (int, float, np.number)) and math.isfinite(value) and (value > 0 or not positive):
        return float(value)
    kind = "positive" if positive else "finite"
    raise error(f"invalid {name} for the simulated arm", what=f"{name}: a {kind} number",
                why=f"got {value!r}", how=f"pass {name} as a {kind} number")


def start_position(lower: np.ndarray, upper: np.ndarray, home: Sequence[float] | None) -> np.ndarray:
    """Where a simulated arm starts, inside every joint's range: at zero where zero is inside every range, else at
    `home` (the SRDF's) when it is, else at the middle of each range (zero where a range is unbounded)."""
    zero = np.zeros(len(lower))

    def inside(q: np.ndarray) -> bool:
        return bool(np.all((lower <= q) & (q <= upper)))

    if inside(zero):
        return zero
    if home is not None and inside(np.asarray(home, dtype=float)):
        return np.asarray(home, dtype=float)
    bounded = np.isfinite(lower) & np.isfinite(upper)
    return np.where(bounded, (np.where(bounded, lower, 0) + np.where(bounded, upper, 0)) / 2,
                    np.clip(zero, lower, upper))


class MockBus:
    """A simulated arm behind the IBus interface: CiA402 drives, encoders, and rigid-body or first-order joints."""

    def __init__(self, dof: int, urdf: str | os.PathLike[str] | None = None, *, dynamics: bool = True,
                 raw_zero: Sequence[int] | None = None, initial_positions: Sequence[float] | None = None,
                 viscous_friction: float | Sequence[float] = 0.05, effort_limits: Sequence[float] | None = None,
                 servo_bandwidth_hz: float = 50.0, follower_time_constant_s: float = 0.005,
                 quick_stop_deceleration: float = 10.0) -> None:
        if not isinstance(dof, int) or not 1 <= dof <= compiled.MAX_JOINTS:
            raise ConfigError("invalid joint count for the simulated arm",
                              what=f"MockBus(dof) with 1 ≤ dof ≤ {compiled.MAX_JOINTS}",
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
        self._open = False
        self._dynamics = False
        self._rigid_body: ArmDynamics | None = None   # the model the simulated arm moves by, once open
        self._start_given = initial_positions is not None
        self._sim = self._new_sim(_joint_array("initial_positions", 0.0 if initial_positions is None
                                               else initial_positions, dof))
        self.io = BusIO(dof)
        self._status = BusStatus()

    @property
    def status(self) -> BusStatus:
        """Health of the exchange, from the simulated arm (whoever stepped it: this bus or the compiled core)."""
        status, sim = self._status, self._sim[0]
        answered = bool(sim["answered"])
        status.communication_ok = answered
        status.working_counter = status.expected_working_counter if answered else 0
        status.lost_frames = int(sim["lost_frames"])
        status.detail = "" if answered else "simulated communication loss: no drive answered"
        return status

    @status.setter
    def status(self, status: BusStatus) -> None:
        self._status = status

    @property
    def simulated_arm(self) -> np.ndarray | None:
        """The compiled core's structure of this simulated arm once open, for a core that steps it itself."""
        return self._sim if self._open else None

    def _new_sim(self, positions: np.ndarray) -> np.ndarray:
        """A simulated arm at rest at `positions` with every drive switched off, its master asking for nothing."""
        sim = compiled.new(compiled.SIM)
        n = self.dof
        sim["dof"] = n
        self._view = {name: compiled.joints(sim, name, n)
                      for name, (field, *_) in compiled.field_types(compiled.SIM).items()
                      if field.shape == (compiled.MAX_JOINTS,)}
        self._view["q"][:] = positions
        self._view["state"][:] = DriveState.SWITCH_ON_DISABLED
        self._view["statusword"][:] = STATUSWORD[DriveState.SWITCH_ON_DISABLED]
        self._view["io_mode"][:] = OperationMode.CYCLIC_SYNC_POSITION
        sim["lost_reads"] = -1
        sim["answered"] = 1
        sim["push_body"] = -1
        self._power = sim["power"]
        compiled.core.power_init(self._power, n)
        return sim

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
        self._rigid_body = arm
        sim = self._new_sim(self._view["q"].copy())
        self._sim = sim
        view = self._view
        sim["dynamics"] = arm is not None
        sim["dt"] = dt
        sim["omega"] = 2.0 * math.pi * self._bandwidth
        sim["follow"] = math.exp(-dt / self._lag)
        sim["deceleration"] = self._deceleration
        view["counts"][:] = counts
        view["raw_zero"][:] = self._raw_zero
        view["friction"][:] = self._friction
        self._set_limits(arm, setup.joint_names)
        if self._start_given:
            self._check_inside_hard_stops(setup.joint_names)
        else:
            lower, upper = view["lower"], view["upper"]
            if setup.position_limits is not None:   # inside the limits the driver enforces, not only the URDF's
                lower, upper = np.maximum(lower, setup.position_limits[0]), np.minimum(upper, setup.position_limits[1])
            view["q"][:] = start_position(lower, upper, setup.home_position)
        if arm is not None:
            from plem.control.kinematics import compiled_model

            sim["model"] = compiled_model(arm.model, setup.joint_names)
        self._dynamics = arm is not None
        n = self.dof
        io = BusIO(n)
        for name in ("position", "velocity", "torque", "statusword", "error_code", "target_position",
                     "velocity_offset", "torque_offset", "mode"):
            setattr(io, name, view[f"io_{name}"])
        self.io = io
        self.status = BusStatus(expected_working_counter=3 * n)
        self._open = True

    def close(self) -> None:
        """Power the drives down (brakes hold the joints) and release the bus."""
        if self._open:
            compiled.core.sim_power_off(self._sim)
            self._open = False

    def read(self) -> bool:
        """Encoder counts, torques, statuswords and error codes into `io`; False while communication is lost."""
        if not self._open:
            raise self._not_open("read")
        answered: bool = compiled.core.sim_read(self._sim)
        return answered

    def write(self) -> None:
        """Deliver this cycle's controlwords and commands, then advance the arm by one cycle time."""
        if not self._open:
            raise self._not_open("write")
        compiled.core.sim_write(self._sim)

    def serve(self, controlwords: Sequence[int] | np.ndarray) -> None:
        """Be the drives of a real master: take its controlwords (not enable()/disable()) and advance one cycle.

        The virtual EtherCAT network runs its emulated drives this way; targets and modes come in `io`.
        """
        self._require_open("serve")
        compiled.core.sim_serve(self._sim, np.ascontiguousarray(controlwords, dtype=np.uint16))

    def quick_stop(self) -> None:
        """The drives no longer hear their master: running ones quick-stop on their own ramp and hold."""
        compiled.core.sim_quick_stop(self._sim)

    def drive_state(self, drive: int) -> DriveState:
        """The power state of one drive as its last statusword read reports it."""
        return decode_statusword(int(self.io.statusword[drive]))

    def enable(self) -> None:
        """Request operation enabled on every drive (three cycles from switch on disabled)."""
        self._require_open("enable")
        compiled.core.power_request(self._power, DriveState.OPERATION_ENABLED)

    def disable(self) -> None:
        """Request switch on disabled on every drive; brakes then hold the joints."""
        self._require_open("disable")
        compiled.core.power_request(self._power, DriveState.SWITCH_ON_DISABLED)

    def fault_reset(self) -> None:
        """Send one fault-reset edge to every drive seen in fault; it clears unless the fault persists."""
        self._require_open("fault_reset")
        compiled.core.power_request_reset(self._power)

    # ---- simulated state and fault injection ------------------------------------------------------

    @property
    def simulates_dynamics(self) -> bool:
        """True when the open bus integrates rigid-body dynamics, False for the first-order follower."""
        return self._dynamics

    @property
    def true_positions(self) -> np.ndarray:
        """Simulated joint angles (rad), a copy."""
        return self._view["q"].copy()

    @property
    def true_velocities(self) -> np.ndarray:
        """Simulated joint velocities (rad/s), a copy."""
        return self._view["v"].copy()

    @property
    def effort_limits(self) -> np.ndarray:
        """The torque each drive can apply (N·m, inf when unlimited), a copy; known once open."""
        return self._view["effort"].copy()

    def set_positions(self, positions: Sequence[float]) -> None:
        """Place the simulated arm at `positions` (rad), at rest; only while no drive is enabled."""
        running = [d for d, s in enumerate(self._view["state"]) if s in _RUNNING]
        if running:
            raise CommandRejected("the simulated arm cannot be moved by hand while drives are enabled",
                                  what="every drive out of operation enabled before set_positions()",
                                  why=f"drives {running} are enabled",
                                  how="call disable() and run a few read()/write() cycles first")
        self._view["q"][:] = _joint_array("positions", positions, self.dof, error=CommandRejected)
        self._view["v"][:] = 0.0

    def inject_drive_fault(self, joint: int, error_code: int = 0x7121, *, persistent: bool = False) -> None:
        """Put one drive in FAULT with `error_code` in 0x603F; a persistent one survives resets until cleared."""
        self._require_open("inject_drive_fault")
        drive = self._joint(joint)
        if not isinstance(error_code, int) or not 0 < error_code <= 0xFFFF:
            raise CommandRejected("invalid error code for an injected drive fault",
                                  what="a 0x603F error code between 0x0001 and 0xFFFF",
                                  why=f"got {error_code!r}", how="pass e.g. 0x7121 (motor blocked)")
        compiled.core.sim_fault(self._sim, drive, error_code, persistent)

    def clear_drive_fault(self, joint: int) -> None:
        """The cause of a persistent injected fault is gone: the next fault reset clears it."""
        self._view["latched"][self._joint(joint)] = 0

    def inject_communication_loss(self, cycles: int | None = None) -> None:
        """Drop the exchange for `cycles` reads (None: until restore_communication()); drives quick-stop."""
        self._require_open("inject_communication_loss")
        if cycles is not None and (not isinstance(cycles, int) or cycles < 1):
            raise CommandRejected("invalid length for a communication loss",
                                  what="a number of cycles ≥ 1, or None for a loss until restored",
                                  why=f"got {cycles!r}", how="pass e.g. cycles=10")
        self._sim["lost_reads"] = -1 if cycles is None else cycles
        self._sim["lost"] = 1

    def restore_communication(self) -> None:
        """End a communication loss: the next read() succeeds and controlwords reach the drives again."""
        self._sim["lost"] = 0
        self._sim["lost_reads"] = -1

    def inject_encoder_spike(self, joint: int, counts: int) -> None:
        """The next successful read reports this joint's position off by `counts`, once."""
        self._view["spike"][self._joint(joint)] += int(counts)

    def set_digital_inputs(self, joint: int, value: int) -> None:
        """What a joint's drive reports as its digital inputs (0x60FD: bit 0 negative limit switch, 1 positive limit
        switch, 2 home switch, 3 interlock, 16-31 the manufacturer's inputs)."""
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 0 <= value < 2**32:
            raise CommandRejected("invalid digital inputs", what="an unsigned 32-bit number, one bit per input",
                                  why=f"got {value!r}", how="e.g. set_digital_inputs(5, 1 << 16) for input 16 of "
                                                            "joint 5's drive")
        self._view["digital_inputs"][self._joint(joint)] = int(value)

    @property
    def digital_inputs(self) -> np.ndarray:
        """What each drive reports as its digital inputs (0x60FD), a copy."""
        return self._view["digital_inputs"][:self.dof].copy()

    def stick_joint(self, joint: int, stuck: bool = True) -> None:
        """Jam a joint (it stays where it is whatever the command) or free it again."""
        drive = self._joint(joint)
        self._view["stuck"][drive] = stuck
        self._view["v"][drive] = 0.0

    def apply_external_torque(self, joint_or_torques: int | Sequence[float], torque: float | None = None) -> None:
        """Push the arm: `apply_external_torque(joint, torque)` or one torque per joint (N·m); needs dynamics."""
        external = self._view["external"]
        if isinstance(joint_or_torques, (int, np.integer)) and torque is not None:
            external[self._joint(joint_or_torques)] = _number("torque", torque, error=CommandRejected)
        elif torque is None:
            external[:] = _joint_array("external torques", joint_or_torques, self.dof, error=CommandRejected)
        else:
            raise CommandRejected("invalid external torque", what="(joint, torque) or one torque per joint",
                                  why=f"got {joint_or_torques!r} with torque={torque!r}",
                                  how="call apply_external_torque(1, 20.0) or apply_external_torque([0, 20.0, ...])")

    def clear_external_torque(self) -> None:
        """Remove every external push."""
        self._view["external"][:] = 0.0

    def push(self, link: str, force: Sequence[float] = (0.0, 0.0, 0.0), torque: Sequence[float] = (0.0, 0.0, 0.0),
             point: Sequence[float] = (0.0, 0.0, 0.0)) -> None:
        """Push a link of the URDF: a force (N) at `point` (m, in the link's frame) and a torque (N·m), both in the
        base frame's axes, applied every cycle through the arm's Jacobian until `release()`; needs dynamics."""
        frame, placement = self._link(link, "push")
        wrench = np.array([*_vector("force", force), *_vector("torque", torque)])
        at = np.asarray(placement.rotation) @ _vector("point", point) + np.asarray(placement.translation)
        sim = self._sim
        sim["push"][0][:] = wrench
        sim["push_point"][0][:] = at
        sim["push_body"] = frame

    def release(self) -> None:
        """End a `push`."""
        self._sim["push_body"] = -1
        self._sim["push"][0][:] = 0.0

    def mount_payload(self, payload: Payload) -> None:
        """Add a payload at the flange of the simulated arm (its last body), from its next cycle on; needs
        dynamics. Payload(0) takes it off."""
        from plem.control.payload_estimation import last_body_with

        self._link(None, "mount a payload")
        assert self._rigid_body is not None
        self._sim["payload_body"][0][:] = last_body_with(self._rigid_body.model, payload)
        self._sim["payload_pending"] = 1

    def _link(self, link: str | None, action: str) -> tuple[int, Any]:
        """The compiled model's index of the joint that moves `link`, and the link's placement in its frame."""
        if self._rigid_body is None or not self._open:
            raise CommandRejected(f"the simulated arm cannot {action}", what="a simulated arm with dynamics, open",
                                  why="it has no rigid-body model (no URDF) or is not open",
                                  how="simulate the arm from its description (plem launch bus:=mock)")
        model = self._rigid_body.model
        if link is None:
            return model.njoints - 2, None
        import pinocchio as pin

        if not isinstance(link, str) or not model.existFrame(link):
            links = [f.name for f in model.frames if f.type == pin.FrameType.BODY]
            raise CommandRejected("no such link on the simulated arm", what=f"one of {', '.join(links)}",
                                  why=f"got {link!r}", how="name a link of the URDF")
        frame = model.frames[model.getFrameId(link)]
        return int(frame.parentJoint) - 1, frame.placement

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

    def _check_inside_hard_stops(self, joint_names: Sequence[str]) -> None:
        """A ConfigError when initial_positions put a joint beyond the URDF's range, where no arm can be (the
        simulation would stop it there at once, a jump its encoder reports)."""
        view = self._view
        outside = [f"{name} = {q:g} is outside [{low:g}, {high:g}]" for name, q, low, high in
                   zip(joint_names, view["q"], view["lower"], view["upper"], strict=True) if not low <= q <= high]
        if outside:
            raise ConfigError("initial_positions of the simulated arm are beyond the URDF's joint range",
                              what="every initial position within its joint's <limit lower upper> in the URDF",
                              why="; ".join(outside),
                              how="pass initial_positions inside the ranges (initial_positions:= on the command line)")

    def _set_limits(self, arm: ArmDynamics | None, joint_names: Sequence[str]) -> None:
        """Effort limits, hard stops and the servo's error cap in joint order, from the URDF (or effort_limits)."""
        n = self.dof
        effort, speed = np.full(n, math.inf), np.full(n, math.inf)
        lower, upper = np.full(n, -math.inf), np.full(n, math.inf)
        if arm is not None:
            model = arm.model
            for drive, name in enumerate(joint_names):
                joint = model.joints[model.getJointId(name)]
                effort[drive], speed[drive] = model.effortLimit[joint.idx_v], model.velocityLimit[joint.idx_v]
            lower, upper = arm.position_bounds()
            effort[~(effort > 0)] = math.inf
            speed[~(speed > 0)] = math.inf
        if self._effort_override is not None:
            effort = self._effort_override.copy()
        view = self._view
        view["effort"][:], view["lower"][:], view["upper"][:] = effort, lower, upper
        view["max_error"][:] = speed / (math.pi * self._bandwidth)  # error at which kp/kd·error = speed limit
