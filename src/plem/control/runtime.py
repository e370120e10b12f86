"""One arm's cycle: read the bus, run the active controller, enforce limits, write the bus, publish.

`ArmRuntime.cycle()` is everything that happens in one period and nothing else: timing belongs to the
scheduler (`control.loop`), device communication to the bus, planning to the callers. Steady-state
cycles work on preallocated numpy arrays only.
"""

from __future__ import annotations

import math
import time
from collections import deque
from dataclasses import dataclass

import numpy as np

from plem.control.commands import (
    ActiveMotion,
    Command,
    CommandHandle,
    PlanBasis,
    ResetFault,
    SetMode,
    StartMotion,
    StopMotion,
    motion_error,
)
from plem.control.events import EventKind, EventLog
from plem.control.free_drive import FreeDriveController
from plem.control.limits import ArmLimits
from plem.control.modes import Mode, check_transition
from plem.control.motion import plan_stop
from plem.control.state import StateBlock
from plem.control.trajectory import ErrorCode, TrajectoryOutcome, TrajectoryResult, TrajectoryTolerances
from plem.errors import CommandRejected, RobotFault
from plem.fieldbus.bus import BusIO, BusSetup, DriveState, IBus, OperationMode
from plem.fieldbus.cia402 import describe_drive_fault

STATUS_FAULT_BIT = 0x0008
ENABLED_MASK, ENABLED_VALUE = 0x006F, 0x0027
CSP = int(OperationMode.CYCLIC_SYNC_POSITION)
CST = int(OperationMode.CYCLIC_SYNC_TORQUE)
#: A goal time tolerance beyond this many cycles (or infinite) waits this long: about 3 years at 1 kHz.
MAX_SETTLE_CYCLES = 1 << 47

#: How to get a robot holding, in each interface a user may command it from.
HOLD_HOW = ("hold first: set_mode('hold') in Python, `plem mode hold`, or on ROS the wim_rt_driver/set_mode action "
            "or controller_manager/switch_controller activating the trajectory controller")
#: How to stop a motion before changing mode, in each interface.
STOP_HOW = ("stop the motion (stop() in Python, `plem mode hold`, or cancel the goal on ROS), wait until the arm is "
            "still, then retry")
#: How to clear a fault, in each interface.
RESET_HOW = ("clear the fault first: reset_fault() in Python, `plem reset`, or on ROS "
             "controller_manager/set_hardware_component_state with target state active")


def _center_and_half(low: np.ndarray, high: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Midpoint and half-width of each range; an unlimited joint gets centre 0 and half-width inf."""
    finite = np.isfinite(low) & np.isfinite(high)
    center = np.where(finite, (low + high) / 2, 0.0)
    half = np.where(finite, (high - low) / 2, np.inf)
    return center, half


class _Flags:
    """A preallocated boolean buffer, so the cycle's comparisons allocate nothing (and skip ndarray.any())."""

    def __init__(self, shape: int | tuple[int, ...]) -> None:
        self.buffer = np.zeros(shape, dtype=bool)

    def greater(self, values: np.ndarray, bound: np.ndarray | float) -> bool:
        return bool(np.count_nonzero(np.greater(values, bound, out=self.buffer)))

    def not_within(self, values: np.ndarray, bound: np.ndarray | float) -> np.bool:
        """True when some value is above its bound or NaN (`not value <= bound`); the buffer marks those within."""
        return np.count_nonzero(np.less_equal(values, bound, out=self.buffer)) < self.buffer.size

    def less(self, values: np.ndarray, bound: np.ndarray | float) -> bool:
        return bool(np.count_nonzero(np.less(values, bound, out=self.buffer)))

    def not_equal(self, values: np.ndarray, other: np.ndarray | int) -> bool:
        return bool(np.count_nonzero(np.not_equal(values, other, out=self.buffer)))


@dataclass(slots=True)
class _PendingMode:
    """A mode change waiting for the drives to reach operation enabled."""

    target: Mode
    deadline_cycle: int
    handle: CommandHandle | None
    enable_sent: bool


@dataclass(frozen=True)
class RuntimeSettings:
    """Supervision thresholds of the loop (SI units)."""

    tracking_tolerance: float = 0.05          # rad between command and measurement before a fault
    velocity_margin: float = 1.1              # measured |v| may exceed max_velocity by this factor
    position_margin: float = 0.02             # rad a measured position may pass a position limit
    enable_timeout_s: float = 1.0             # drives must reach operation enabled within this
    standstill_velocity: float = 0.05         # rad/s below which the arm counts as standing still
    command_tolerance: float = 1e-6           # relative slack for commanded derivatives (rounding)


class ArmRuntime:
    """The per-cycle logic of one arm on one bus."""

    def __init__(self, bus: IBus, setup: BusSetup, limits: ArmLimits, joint_offsets: np.ndarray,
                 free_drive: FreeDriveController, settings: RuntimeSettings | None = None,
                 state_block: StateBlock | None = None, events: EventLog | None = None) -> None:
        dof = setup.dof
        self.bus = bus
        self.setup = setup
        self.limits = limits
        self.settings = settings or RuntimeSettings()
        self.dt = setup.cycle_time_s
        self.free_drive = free_drive
        self.events = events or EventLog()
        self.state_block = state_block or StateBlock(dof)
        self.joint_names = setup.joint_names
        self.counts_per_radian = np.asarray(setup.counts_per_radian, dtype=float)
        self.radians_per_count = 1.0 / self.counts_per_radian
        self.offsets = np.asarray(joint_offsets, dtype=np.int64)
        self.inbox: deque[Command] = deque()
        self.mode = Mode.IDLE
        self.cycle_count = 0
        self.fault_reason = ""
        self.communication_ok = True
        # Working arrays: rows are position, velocity, effort, command position/velocity/acceleration.
        self._work = np.zeros((6, dof))
        self.position, self.velocity, self.effort = self._work[0], self._work[1], self._work[2]
        self.command = self._work[3:6]
        self.command_position, self.command_velocity, self.command_acceleration = self._work[3:6]
        self._previous_position = np.zeros(dof)
        self._previous_acceleration = np.zeros(dof)
        self._torque = np.zeros(dof)
        self._scratch = np.zeros(dof)
        self._counts = np.zeros(dof, dtype=np.int64)
        self._status = np.zeros(dof, dtype=np.uint16)
        self._flags = _Flags(dof)
        settings = self.settings
        center, half = _center_and_half(limits.min_position, limits.max_position)
        # Measured checks, one row each: encoder jump, position, velocity, tracking error.
        self._measure = np.zeros((4, dof))
        self._measure_flags = _Flags((4, dof))
        self._measure_center = center
        measure_bounds = np.vstack([2.0 * limits.max_velocity * self.dt + 1e-3, half + settings.position_margin,
                                    limits.max_velocity * settings.velocity_margin + 0.01,
                                    np.full(dof, settings.tracking_tolerance)])
        idle = measure_bounds.copy()
        idle[1:] = np.inf  # drives off: only encoder plausibility
        free = measure_bounds.copy()
        free[3] = np.inf   # free drive: the command follows the arm
        self._measure_bounds = {Mode.IDLE: idle, Mode.FREE_DRIVE: free, Mode.HOLD: measure_bounds,
                                Mode.TRAJECTORY: measure_bounds}
        # Command checks: |command - center| per row (position, velocity, acceleration) and |Δa| per cycle.
        self._command_center = np.vstack([center, np.zeros(dof), np.zeros(dof)])
        slack = 1 + settings.command_tolerance
        self._command_bounds = np.vstack([half * slack, limits.max_velocity * slack, limits.max_acceleration * slack,
                                          limits.max_jerk * self.dt * slack]) + 1e-9
        self._command_check = np.zeros((4, dof))
        self._command_flags = _Flags((4, dof))
        self._have_previous = False
        self._active: ActiveMotion | None = None
        self._pending_mode: _PendingMode | None = None
        self._braking = False   # FAULT: the drives could not hold the arm and were disabled onto the brakes
        self.basis = PlanBasis(self.command_position.copy())

    # -- one cycle -------------------------------------------------------------------------------
    def cycle(self) -> None:
        """Read → supervise → control → limits → write → publish."""
        bus = self.bus
        io = bus.io
        if bus.read():
            if not self.communication_ok:
                self.communication_ok = True
                self._have_previous = False
            np.add(io.position, self.offsets, out=self._counts)
            np.multiply(self._counts, self.radians_per_count, out=self.position)
            np.multiply(io.velocity, self.radians_per_count, out=self.velocity)
            self.effort[:] = io.torque
            if self.mode is not Mode.FAULT:
                self._supervise_measurement(io)
            elif not self._braking and self._can_command():
                self._supervise_fault_hold()
        elif self.communication_ok:
            self.communication_ok = False
            self._fault("communication_lost", f"bus communication lost: {bus.status.detail or 'no response'}")
        if self.inbox:
            self._process_inbox()
        self._control()
        self._write()
        self.cycle_count += 1
        self.state_block.publish(self._work, self.cycle_count, time.monotonic_ns(), int(self.mode),
                                 self.mode is Mode.FAULT, self.mode in (Mode.HOLD, Mode.TRAJECTORY, Mode.FREE_DRIVE))

    def _supervise_measurement(self, io: BusIO) -> None:
        """Fault on drive faults, implausible encoder jumps, limit breaches and tracking errors."""
        mode = self.mode
        enabled = mode is not Mode.IDLE
        if enabled and self._flags.not_equal(np.bitwise_and(io.statusword, ENABLED_MASK, out=self._status),
                                             ENABLED_VALUE):
            i = int(np.flatnonzero(self._flags.buffer)[0])
            cause = "drive_fault" if io.statusword[i] & STATUS_FAULT_BIT else "drive_disabled"
            self._fault(cause, describe_drive_fault(self.joint_names[i], int(io.statusword[i]),
                                                    int(io.error_code[i])))
            return
        if not self._have_previous:
            self._previous_position[:] = self.position
            self._have_previous = True
        measure = self._measure
        np.subtract(self.position, self._previous_position, out=measure[0])
        np.subtract(self.position, self._measure_center, out=measure[1])
        np.copyto(measure[2], self.velocity)
        np.subtract(self.command_position, self.position, out=measure[3])
        np.abs(measure, out=measure)
        self._previous_position[:] = self.position
        bounds = self._measure_bounds[mode]
        if self._measure_flags.greater(measure, bounds):
            self._measurement_fault(measure, bounds)

    def _supervise_fault_hold(self) -> None:
        """In FAULT with drives enabled, the drives hold the arm where the stop leaves it. When they cannot (it runs
        away from its command or past its velocity limit: short of torque, a heavy load), disable them so the brakes
        hold it, and say so."""
        measure, bounds = self._measure, self._measure_bounds[Mode.HOLD]
        measure[:2] = 0.0
        np.copyto(measure[2], self.velocity)
        np.subtract(self.command_position, self.position, out=measure[3])
        np.abs(measure, out=measure)
        self._flags.not_equal(np.bitwise_and(self.bus.io.statusword, ENABLED_MASK, out=self._status), ENABLED_VALUE)
        np.copyto(measure, 0.0, where=self._flags.buffer)   # a disabled drive's joint is on its brake
        if not self._measure_flags.greater(measure, bounds):
            return
        row, i = (int(x) for x in np.argwhere(self._measure_flags.buffer)[0])
        found = (f"moves at {self.velocity[i]:.4g} rad/s (limit {self.limits.max_velocity[i]:.4g} rad/s)" if row == 2
                 else f"is {measure[3, i]:.4g} rad from where it is held (tolerance {bounds[3, i]:g} rad)")
        self.bus.disable()
        self._braking = True
        self.events.emit(EventKind.WARNING, "brakes_engaged",
                         f"in FAULT the drives could not hold the arm: {self.joint_names[i]} {found}; drives "
                         "disabled, the brakes hold the joints", Mode.FAULT, self.cycle_count)

    def _measurement_fault(self, measure: np.ndarray, bounds: np.ndarray) -> None:
        """Name the first breached check (rows in order of how basic they are) and fault."""
        row, i = (int(x) for x in np.argwhere(self._measure_flags.buffer)[0])
        joint, value, bound = self.joint_names[i], measure[row, i], bounds[row, i]
        limits = self.limits
        if row == 0:
            self._fault("encoder_jump", f"{joint} encoder jumped {value:.4g} rad in one cycle (at most {bound:.4g} "
                        "rad is physically possible)")
        elif row == 1:
            self._fault("position_limit", f"{joint} at {self.position[i]:.4g} rad is outside "
                        f"[{limits.min_position[i]:.4g}, {limits.max_position[i]:.4g}] rad")
        elif row == 2:
            self._fault("velocity_limit", f"{joint} moves at {self.velocity[i]:.4g} rad/s, above its limit "
                        f"{limits.max_velocity[i]:.4g} rad/s")
        else:
            self._fault("tracking_error", f"{joint} is {value:.4g} rad from its command (tolerance {bound:g} rad)")

    def _control(self) -> None:
        mode = self.mode
        if mode is Mode.IDLE or (mode is Mode.FAULT and not self._can_command()):
            self._seed_from_measurement()
            pending = self._pending_mode
            if pending is not None:
                self._advance_enable(pending)
            return
        if mode is Mode.FREE_DRIVE:
            self._follow_measurement()
            self.free_drive.update(self.position, self.velocity, self._torque)
            return
        active = self._active
        if active is not None:
            t = (self.cycle_count - active.start_cycle) * self.dt
            if not active.ended:
                active.ended = active.motion.sample(t, self.command)
                path = active.tolerances.path
                if path is not None:
                    self._check_path(path)
            if active.ended and self._active is active:
                self._settle(active)
        self._check_command()
        pending = self._pending_mode
        if pending is not None:
            self._advance_enable(pending)

    def _check_command(self) -> None:
        """Fault when the command leaves the position, velocity or acceleration limits or jerks too hard."""
        check = self._command_check
        np.subtract(self.command, self._command_center, out=check[:3])
        np.subtract(self.command_acceleration, self._previous_acceleration, out=check[3])
        np.abs(check, out=check)
        self._previous_acceleration[:] = self.command_acceleration
        if self._command_flags.not_within(check, self._command_bounds):
            row, i = (int(x) for x in np.argwhere(~self._command_flags.buffer)[0])
            if not np.isfinite(self.command[:, i]).all():
                self._follow_measurement()  # a stop is planned from where the arm really is, never from NaN
                self._fault("invalid_command", f"command for {self.joint_names[i]} is not a finite number")
                return
            kind = ("position", "velocity", "acceleration", "jerk")[row]
            value = check[row, i] / self.dt if row == 3 else self.command[row, i]
            limit = self.limits.maximum(kind)[i] if row else None
            detail = (f"{kind} {value:.6g}, beyond its limit {limit:.6g}" if limit is not None
                      else f"position {value:.6g} rad, outside [{self.limits.min_position[i]:.6g}, "
                           f"{self.limits.max_position[i]:.6g}]")
            self._fault(f"{kind}_limit", f"command for {self.joint_names[i]} has {detail}")

    def _write(self) -> None:
        io = self.bus.io
        np.multiply(self.command_position, self.counts_per_radian, out=self._scratch)
        np.rint(self._scratch, out=self._scratch)
        np.subtract(self._scratch, self.offsets, out=self._scratch)
        np.copyto(io.target_position, self._scratch, casting="unsafe")
        np.multiply(self.command_velocity, self.counts_per_radian, out=self._scratch)
        np.rint(self._scratch, out=self._scratch)
        np.copyto(io.velocity_offset, self._scratch, casting="unsafe")
        if self.mode is Mode.FREE_DRIVE:
            io.torque_offset[:] = self._torque
        else:
            io.torque_offset[:] = 0.0
        self.bus.write()

    # -- motions ---------------------------------------------------------------------------------
    def _check_path(self, path: np.ndarray) -> None:
        np.subtract(self.command_position, self.position, out=self._scratch)
        np.abs(self._scratch, out=self._scratch)
        if self._flags.greater(self._scratch, path):
            i = int(np.argmax(self._scratch - path))
            message = (f"path tolerance violated: {self.joint_names[i]} is {self._scratch[i]:.4g} rad from the "
                       f"trajectory (tolerance {path[i]:.4g} rad)")
            self._end_motion(TrajectoryResult(TrajectoryOutcome.ABORTED, message, ErrorCode.PATH_TOLERANCE_VIOLATED))
            self._start_stop("path tolerance violated")

    def _settle(self, active: ActiveMotion) -> None:
        """After the last point: succeed once inside the goal tolerance and stopped, abort after goal_time."""
        if active.handle is None:  # an internal stop: done as soon as it ends
            self._end_motion(None)
            return
        tolerances = active.tolerances
        if active.settle_deadline_cycle is None:
            cycles = tolerances.goal_time / self.dt
            active.settle_deadline_cycle = (self.cycle_count + max(1, math.ceil(cycles)) if cycles < MAX_SETTLE_CYCLES
                                            else self.cycle_count + MAX_SETTLE_CYCLES)
        np.subtract(active.motion.final_positions, self.position, out=self._scratch)
        np.abs(self._scratch, out=self._scratch)
        inside = tolerances.goal is None or not (self._scratch > tolerances.goal).any()
        stopped = not (np.abs(self.velocity) > tolerances.stopped_velocity_tolerance).any()
        if inside and stopped:
            self._end_motion(TrajectoryResult(TrajectoryOutcome.SUCCEEDED, f"{active.label} reached its goal",
                                               ErrorCode.SUCCESSFUL))
        elif self.cycle_count >= active.settle_deadline_cycle:
            i = int(np.argmax(self._scratch))
            self._end_motion(TrajectoryResult(
                TrajectoryOutcome.ABORTED,
                f"goal tolerance violated: {self.joint_names[i]} is {self._scratch[i]:.4g} rad from the goal "
                f"{tolerances.goal_time:g} s after the end", ErrorCode.GOAL_TOLERANCE_VIOLATED))

    def _end_motion(self, result: TrajectoryResult | None) -> None:
        active = self._active
        self._active = None
        self._rebase()
        if self.mode is Mode.TRAJECTORY:
            self._set_mode(Mode.HOLD, "motion_finished", active.label if active else "motion ended")
        if active is not None and active.handle is not None and result is not None:
            if active.note and result.outcome in (TrajectoryOutcome.SUCCEEDED, TrajectoryOutcome.ABORTED):
                result = TrajectoryResult(result.outcome, f"{result.message}; {active.note}", result.error_code)
            self.events.emit(EventKind.MOTION_FINISHED, result.outcome.name.lower(), result.message, self.mode,
                             self.cycle_count)
            active.handle.finish(result, motion_error(result))

    def _start_stop(self, reason: str) -> None:
        """Replace whatever runs by the quickest jerk-limited stop from the current command."""
        start = (self.command_position.copy(), self.command_velocity.copy(), self.command_acceleration.copy())
        if not (np.any(start[1]) or np.any(start[2])):
            self._rebase()
            return
        stop = plan_stop(self.limits, start)
        self._active = ActiveMotion(stop, self.cycle_count, TrajectoryTolerances(), None, f"stop ({reason})")
        self._active.ended = stop.sample(0.0, self.command)
        self._rebase()

    def _rebase(self) -> None:
        active = self._active
        self.basis = PlanBasis(self.command_position.copy(), active.motion if active else None,
                               active.start_cycle if active else 0)

    # -- commands --------------------------------------------------------------------------------
    def _process_inbox(self) -> None:
        while self.inbox:
            command = self.inbox[0]
            if isinstance(command, StartMotion) and command.activation_cycle is not None \
                    and command.basis is self.basis and self.cycle_count < command.activation_cycle:
                return  # a preemption waits for the cycle it was planned for
            self.inbox.popleft()
            try:
                self._execute(command)
            except (CommandRejected, RobotFault) as error:
                self.events.emit(EventKind.COMMAND_REJECTED, type(command).__name__, error.summary, self.mode,
                                 self.cycle_count)
                command.handle.reject(error)

    def _execute(self, command: Command) -> None:
        if isinstance(command, StartMotion):
            self._activate(command)
        elif isinstance(command, SetMode):
            self._request_mode(command.mode, command.handle)
        elif isinstance(command, StopMotion):
            active = self._active
            if active is not None and active.handle is not None and command.goal in (None, active.handle):
                self._end_motion(TrajectoryResult.canceled())
                self._start_stop("stop requested")
            command.handle.finish()
        elif isinstance(command, ResetFault):
            self._reset(command.handle)

    def _activate(self, command: StartMotion) -> None:
        if self.mode not in (Mode.HOLD, Mode.TRAJECTORY) or self._pending_mode is not None:
            raise CommandRejected(f"cannot start a motion in {self.mode.name}",
                                  what="the robot holding (HOLD) or moving (TRAJECTORY)",
                                  why=f"the robot is in {self.mode.name}" + (f": {self.fault_reason}"
                                                                             if self.mode is Mode.FAULT else ""),
                                  how=HOLD_HOW if self.mode is not Mode.FAULT else RESET_HOW)
        if command.basis is not self.basis or (command.activation_cycle is not None
                                               and self.cycle_count != command.activation_cycle):
            stale = CommandRejected("the motion was planned from an outdated state",
                                    what="a plan starting from the arm's current command",
                                    why="the command changed while the motion was being planned",
                                    how="plan again (the robot's methods retry automatically)")
            command.handle.reject(stale, stale=True)
            return
        previous = self._active
        if previous is not None and previous.handle is not None:
            previous.handle.finish(TrajectoryResult.preempted())
            self.events.emit(EventKind.MOTION_FINISHED, "preempted", previous.label, self.mode, self.cycle_count)
        self._active = ActiveMotion(command.motion, self.cycle_count, command.tolerances, command.handle,
                                    command.label, command.note)
        self._rebase()
        command.handle.accept()
        self._set_mode(Mode.TRAJECTORY, "motion_started", command.label)
        self.events.emit(EventKind.MOTION_STARTED, command.label,
                         f"{command.motion.duration:.3f} s" + (f": {command.note}" if command.note else ""), self.mode,
                         self.cycle_count)

    def _request_mode(self, requested: Mode, handle: CommandHandle) -> None:
        if self._pending_mode is not None:
            raise CommandRejected("a mode change is already in progress",
                                  what="one mode change at a time",
                                  why=f"waiting for the drives to enable for {self._pending_mode.target.name}",
                                  how="wait for the previous set_mode to finish")
        check_transition(self.mode, requested)
        current = self.mode
        if requested is current:
            handle.finish(current)
            return
        if requested is Mode.IDLE:
            self._require_standstill("disable the drives")
            self.bus.disable()
            self._active = None
            self._set_mode(Mode.IDLE, "set_mode", "drives disabled on request")
            self._seed_from_measurement()
            handle.finish(Mode.IDLE)
        elif current is Mode.IDLE:
            self._start_enable(requested, handle)
        elif requested is Mode.FREE_DRIVE:
            self._require_standstill("enter free drive")
            self.bus.io.mode[:] = CST
            self._active = None
            self._set_mode(Mode.FREE_DRIVE, "set_mode", "gravity compensation on")
            handle.finish(Mode.FREE_DRIVE)
        else:  # HOLD from FREE_DRIVE or TRAJECTORY: stop smoothly from where the arm is
            if current is Mode.FREE_DRIVE:
                self._leave_free_drive()
            elif self._active is not None and self._active.handle is not None:
                self._end_motion(TrajectoryResult.canceled())
            self._set_mode(Mode.HOLD, "set_mode", f"holding (from {current.name})")
            self._start_stop("hold requested")
            handle.finish(Mode.HOLD)

    def _require_standstill(self, action: str) -> None:
        moving = np.abs(self.velocity) > self.settings.standstill_velocity
        if self._active is not None or moving.any():
            joint = self.joint_names[int(np.argmax(np.abs(self.velocity)))]
            raise CommandRejected(f"cannot {action} while the arm moves",
                                  what=f"the arm standing still (|v| < {self.settings.standstill_velocity} rad/s)",
                                  why=f"{joint} moves at {np.max(np.abs(self.velocity)):.3g} rad/s"
                                  if moving.any() else "a motion is still running",
                                  how=STOP_HOW)

    def _start_enable(self, target: Mode, handle: CommandHandle | None, *, after_reset: bool = False) -> None:
        """Ask the drives for operation enabled; after a fault reset, only once no drive is in FAULT any more."""
        self.bus.io.mode[:] = CST if target is Mode.FREE_DRIVE else CSP
        if not after_reset:
            self.bus.enable()
        self._pending_mode = _PendingMode(
            target, self.cycle_count + max(1, math.ceil(self.settings.enable_timeout_s / self.dt)), handle,
            not after_reset)

    def _advance_enable(self, pending: _PendingMode) -> None:
        target, deadline, handle = pending.target, pending.deadline_cycle, pending.handle
        states = [self.bus.drive_state(i) for i in range(self.setup.dof)]
        if not pending.enable_sent and DriveState.FAULT not in states:
            self.bus.enable()
            pending.enable_sent = True
        if all(state is DriveState.OPERATION_ENABLED for state in states):
            self._pending_mode = None
            self._seed_from_measurement()
            self._previous_acceleration[:] = 0.0
            self._rebase()
            previous = self.mode
            if previous is Mode.FAULT:
                self.events.emit(EventKind.FAULT_CLEARED, "reset_fault", self.fault_reason, target, self.cycle_count)
                self.fault_reason = ""
            self._set_mode(target, "drives_enabled", "all drives in operation enabled; command seeded from the "
                           "measured position")
            if handle is not None:
                handle.finish(target)
        elif self.cycle_count >= deadline:
            self._pending_mode = None
            stuck = ", ".join(f"{self.joint_names[i]} {state.name}" for i, state in enumerate(states)
                              if state is not DriveState.OPERATION_ENABLED)
            self.bus.disable()
            error = RobotFault("the drives did not enable", what="every drive in OPERATION_ENABLED",
                               why=f"after {self.settings.enable_timeout_s:g} s: {stuck}",
                               how="check the drives (power, safety circuit, faults) and retry")
            if handle is not None:
                handle.reject(error)
            self.events.emit(EventKind.COMMAND_REJECTED, "enable_timeout", error.why, self.mode, self.cycle_count)

    def _reset(self, handle: CommandHandle) -> None:
        if self.mode is not Mode.FAULT:
            handle.finish(self.mode)
            return
        if not self.communication_ok:
            raise RobotFault("the fault cannot be reset", what="working bus communication",
                             why=self.fault_reason, how="restore the EtherCAT connection, then reset again")
        self._require_standstill("reset the fault")
        self._active = None
        self.bus.fault_reset()
        self._start_enable(Mode.HOLD, handle, after_reset=True)

    # -- modes and faults ------------------------------------------------------------------------
    def _set_mode(self, mode: Mode, cause: str, reason: str) -> None:
        if mode is self.mode:
            return
        previous, self.mode = self.mode, mode
        self.events.emit(EventKind.MODE_CHANGED, cause, reason, mode, self.cycle_count, previous)

    def _fault(self, cause: str, reason: str) -> None:
        """Enter FAULT, abort the running motion, stop smoothly from the current command, then hold."""
        if self.mode is Mode.FAULT:
            return
        previous = self.mode
        self.fault_reason = reason
        self.mode = Mode.FAULT
        self.events.emit(EventKind.FAULT, cause, reason, Mode.FAULT, self.cycle_count, previous)
        self._have_previous = False
        self._braking = False
        active, self._active = self._active, None
        if active is not None and active.handle is not None:
            result = TrajectoryResult(TrajectoryOutcome.ABORTED, f"robot fault: {reason}",
                                      ErrorCode.PATH_TOLERANCE_VIOLATED)
            active.handle.finish(result, motion_error(result))
        if self._pending_mode is not None and self._pending_mode.handle is not None:
            self._pending_mode.handle.reject(RobotFault("the robot faulted", what="the mode change to complete",
                                                        why=reason, how="reset_fault() once the cause is gone"))
        self._pending_mode = None
        if previous is Mode.FREE_DRIVE:
            self._leave_free_drive()
        if previous is not Mode.IDLE and self._can_command():
            self._start_stop(cause)
        else:
            self._rebase()

    def _can_command(self) -> bool:
        """Whether commands reach any drive (a faulted drive ignores its share and holds on its brake)."""
        io = self.bus.io
        return self.communication_ok and bool(((io.statusword & ENABLED_MASK) == ENABLED_VALUE).any())

    def _follow_measurement(self) -> None:
        """Command where the arm is and how it moves (free drive: the arm leads, the command follows)."""
        self.command_position[:] = self.position
        self.command_velocity[:] = self.velocity
        self.command_acceleration[:] = 0.0

    def _leave_free_drive(self) -> None:
        """Back to position control, starting from the arm's measured motion so a stop can be planned."""
        self.bus.io.mode[:] = CSP
        self._follow_measurement()
        self._previous_acceleration[:] = 0.0

    def _seed_from_measurement(self) -> None:
        self.command_position[:] = self.position
        self.command_velocity[:] = 0.0
        self.command_acceleration[:] = 0.0

    def fault(self, cause: str, reason: str) -> None:
        """Fault the robot from outside the cycle logic (the scheduler, on consecutive overruns)."""
        self._fault(cause, reason)
