"""One arm's cycle, run by the compiled core: read the bus, supervise, take requests, control, limits, write, publish.

`ArmRuntime` sets up the core's arm structure (settings, limits, dynamics, the bus), hands requests to it through
its command ring and turns what comes back on its outcome and event rings into finished command handles and
worded events. `cycle()` is everything that happens in one period: one call into the core (for a bus written in
Python, with its read and write around it), then the rings are drained. Timing belongs to the scheduler
(`control.loop`), planning to the callers.
"""

from __future__ import annotations

import itertools
import math
import threading
import time
from dataclasses import dataclass
from typing import cast

import numpy as np

from plem.control import compiled
from plem.control.commands import (
    ArmReaction,
    Command,
    CommandHandle,
    PlanBasis,
    ResetFault,
    SetMode,
    SetPayload,
    SetSpeedOverride,
    StartMotion,
    StartStream,
    StopMotion,
    motion_error,
)
from plem.control.compiled import CONSTANTS as C
from plem.control.events import EventKind, EventLog
from plem.control.free_drive import FreeDriveController
from plem.control.kinematics import compiled_model
from plem.control.limits import CONTACT_SHARE, ArmLimits
from plem.control.loop import OverrunWindow
from plem.control.modes import Mode
from plem.control.polynomial import ORDER, PolynomialMotion
from plem.control.reactions import ACTION_NAMES, Action, Condition, Stop, write_reaction
from plem.control.state import StateBlock
from plem.control.streaming import StreamBlock
from plem.control.trajectory import ErrorCode, TrajectoryOutcome, TrajectoryResult
from plem.control.wording import CAUSES, Reported, Wording
from plem.errors import CommandRejected
from plem.fieldbus.bus import BusSetup, DriveState, IBus, SteppedBus
from plem.ipc.motion_slab import MotionSlab, MotionSlabError
from plem.ipc.ring import SlotRing

#: Longest a request waits for room in the core's command ring, or for answers to make room for its own.
QUEUE_WAIT_S = 2.0
#: Requests other than stops the core may hold unanswered. Each gets at most two answers (accepted, finished) on
#: the outcome ring, which drops what finds it full: this bound keeps room for them, and for a ring of stops.
MAX_UNANSWERED = (C["PLEM_OUTCOME_SLOTS"] - C["PLEM_COMMAND_SLOTS"]) // 2
#: Tokens that never name a request: a stop aimed at a goal that already ended stops nothing.
NO_TOKEN = (1 << 64) - 1
#: Refusals the event log records (the others are a stale plan, retried, or are reported by the core itself).
_LOGGED_REFUSALS = frozenset({C["PLEM_ANSWER_NOT_HOLDING"], C["PLEM_ANSWER_MODE_PENDING"], C["PLEM_ANSWER_TRANSITION"],
                              C["PLEM_ANSWER_MOVING"], C["PLEM_ANSWER_RESET_NO_BUS"], C["PLEM_ANSWER_INVALID_SLOT"],
                              C["PLEM_ANSWER_UNKNOWN_OP"]})
_MOTION_ENDS = {C["PLEM_ANSWER_SUCCEEDED"], C["PLEM_ANSWER_GOAL_VIOLATED"], C["PLEM_ANSWER_PATH_VIOLATED"],
                C["PLEM_ANSWER_FAULT_ABORTED"], C["PLEM_ANSWER_PREEMPTED"], C["PLEM_ANSWER_CANCELED"],
                C["PLEM_ANSWER_STREAM_TIMED_OUT"], C["PLEM_ANSWER_REACTED"]}
#: Why a running motion's future is not known ahead, by the basis's slot: a plan cannot take it over yet.
_UNKNOWN_FUTURE = {C["PLEM_STREAM_SLOT"]: "a stream runs"}
_OUTSIDE_FAULTS = {"overrun": C["PLEM_CAUSE_OVERRUN"], "internal_error": C["PLEM_CAUSE_INTERNAL_ERROR"]}
_MODE_REASONS = {C["PLEM_CAUSE_SET_MODE_IDLE"]: "drives disabled on request",
                 C["PLEM_CAUSE_SET_MODE_FREE_DRIVE"]: "gravity compensation on",
                 C["PLEM_CAUSE_DRIVES_ENABLED"]: "all drives in operation enabled; command seeded from the measured "
                                                 "position"}
_BUS_INPUTS = ("position", "velocity", "torque", "statusword", "error_code")
_BUS_OUTPUTS = ("target_position", "velocity_offset", "torque_offset", "mode")


@dataclass(frozen=True)
class RuntimeSettings:
    """Supervision thresholds of the loop (SI units)."""

    tracking_tolerance: float = 0.05          # rad between command and measurement before a fault
    velocity_margin: float = 1.1              # measured |v| may exceed max_velocity by this factor
    position_margin: float = 0.02             # rad a measured position may pass a position limit
    enable_timeout_s: float = 1.0             # drives must reach operation enabled within this
    standstill_velocity: float = 0.05         # rad/s below which the arm counts as standing still
    command_tolerance: float = 1e-6           # relative slack for commanded derivatives (rounding)
    contact_share: float = CONTACT_SHARE      # estimated external torque, as a share of each joint's effort limit,
                                              # past which the arm stops (the contact stop); inf: off


@dataclass(frozen=True)
class ReactionRecord:
    """What Python keeps of an armed reaction, to word what it did."""

    slot: int
    text: str
    action: str
    motion: int


@dataclass
class _Request:
    """A request handed to the core: what was asked, and the private slab slot its motion occupies."""

    command: Command
    slot: int | None = None


def _record_value(value: float) -> float:
    """A tolerance for the command record: inf stands for unchecked."""
    return value if math.isfinite(value) else math.inf


class ArmRuntime:
    """The per-cycle logic of one arm on one bus, in the compiled core."""

    def __init__(self, bus: IBus | SteppedBus, setup: BusSetup, limits: ArmLimits, joint_offsets: np.ndarray,
                 free_drive: FreeDriveController, settings: RuntimeSettings | None = None,
                 state_block: StateBlock | None = None, events: EventLog | None = None,
                 slab: MotionSlab | None = None, raw_ring: SlotRing | None = None,
                 max_consecutive_overruns: int = 10, stream: StreamBlock | None = None) -> None:
        dof = setup.dof
        self.bus = bus
        self.setup = setup
        self.limits = limits
        self.settings = settings or RuntimeSettings()
        self.dt = setup.cycle_time_s
        self.events = events or EventLog()
        self.state_block = state_block or StateBlock(dof)
        self.joint_names = setup.joint_names
        self.offsets = np.asarray(joint_offsets, dtype=np.int64)
        self.fault_reason = ""
        self._outside_reason = ""
        self.arm = compiled.new(compiled.ARM)
        arm = self.arm[0]
        self._write_settings(arm["settings"], free_drive)
        arm["model"] = compiled_model(free_drive.dynamics.model, self.joint_names)
        simulated = getattr(bus, "simulated_arm", None)
        master = getattr(bus, "core_master", None)
        arm["settings"]["bus"] = simulated is not None or master is not None
        compiled.core.arm_init(self.arm)
        self.slab = slab or MotionSlab.private(dof)
        #: Where streamed samples arrive, and where the core reports on streams and the speed override.
        self.stream = stream or StreamBlock.private(dof)
        #: The timing of the core's real-time thread, when it runs the cycles.
        self.stats = compiled.new(compiled.STATS)
        self._core = compiled.core.Core(self.arm, self.state_block.header, self.state_block.values, self.slab.buffer,
                                        simulated, None if raw_ring is None else raw_ring.buffer, self.stats, master,
                                        self.stream.buffer)
        #: The bus is written in Python: the core cannot step it from its own thread, a Python loop runs the cycles.
        self.python_bus = simulated is None and master is None
        self._handed_over = master is None   # an EtherCAT bus keeps its watchdogs fed until the core's first cycle
        self._applied_power = (0, 0)   # the core's power requests and resets passed on to a Python bus
        self._wording = Wording(self.joint_names, self.settings.enable_timeout_s, self.settings.standstill_velocity,
                                self.dt, max_consecutive_overruns)
        self._pending: dict[int, _Request] = {}
        self._tokens = itertools.count(1)
        self._submitting = threading.Lock()
        self._busy_slots: set[int] = set()
        #: Reactions by their token, and the core's slots written but not yet answered.
        self.reactions: dict[int, ReactionRecord] = {}
        self._arming: set[int] = set()
        self.work = arm["work"][:, :dof]   # position, velocity, effort, command position/velocity/acceleration
        self._io = {name: arm[f"io_{name}"][:dof] for name in _BUS_INPUTS + _BUS_OUTPUTS}
        self._basis = arm["basis"]
        self._rings = {name: (arm[f"{name}_index"], arm[name]) for name in ("commands", "outcomes", "events")}

    def _write_settings(self, settings: np.ndarray, free_drive: FreeDriveController) -> None:
        dof, limits, thresholds = self.setup.dof, self.limits, self.settings
        settings["dof"] = dof
        settings["dt"] = self.dt
        for name in ("tracking_tolerance", "velocity_margin", "position_margin", "standstill_velocity",
                     "command_tolerance"):
            settings[name] = getattr(thresholds, name)
        settings["enable_timeout_cycles"] = max(1, math.ceil(thresholds.enable_timeout_s / self.dt))
        settings["counts_per_radian"][:dof] = self.setup.counts_per_radian
        settings["offsets"][:dof] = self.offsets
        for name in ("min_position", "max_position"):
            settings[name][:dof] = getattr(limits, name)
        for kind in ("velocity", "acceleration", "jerk", "effort"):
            settings[f"max_{kind}"][:dof] = limits.maximum(kind)
        settings["damping"][:dof] = free_drive.damping
        settings["friction"][:dof], settings["contact_threshold"][:dof] = self._contact_model()

    def _contact_model(self) -> tuple[np.ndarray, np.ndarray]:
        """Viscous friction the model's effort includes, and the contact stop's threshold per joint: off (inf) where
        the measured effort is not a joint torque the model can explain (a simulated arm without dynamics, drives
        whose torque unit is unknown, joints without an effort limit)."""
        dof = self.setup.dof
        simulated = getattr(self.bus, "simulated_arm", None)
        if simulated is None:
            friction = np.zeros(dof)
            known = np.array(getattr(self.bus, "torque_in_newton_metres", None) or [False] * dof, dtype=bool)
        else:
            friction = np.array(simulated["friction"][0][:dof])
            known = np.full(dof, bool(simulated["dynamics"][0]))
        effort = self.limits.maximum("effort") * self.settings.contact_share
        return friction, np.where(np.isfinite(effort) & known, effort, math.inf)

    # -- state -------------------------------------------------------------------------------------
    @property
    def mode(self) -> Mode:
        """What the loop is doing with the drives now."""
        return Mode(int(self.arm["mode"][0]))

    @property
    def cycle_count(self) -> int:
        """Cycles run so far."""
        return int(self.arm["cycle"][0])

    @property
    def basis(self) -> PlanBasis:
        """Where a new motion starts now: the held position, or the running motion (read without tearing)."""
        basis, dof = self._basis, self.setup.dof
        while True:
            before = int(basis["sequence"])
            if before & 1:
                continue
            generation, slot, segments = int(basis["generation"]), int(basis["slot"]), int(basis["segments"])
            start, hold = int(basis["start_cycle"]), basis["hold_position"][:dof].copy()
            time_, rate, ramping = float(basis["time"]), float(basis["rate"]), bool(basis["ramping"])
            motion = self._motion_in(slot, segments) if slot >= 0 or slot == C["PLEM_STOP_SLOT"] else None
            if int(basis["sequence"]) == before:
                return PlanBasis(hold, motion, start, generation, time_, rate, self._unknown(slot, ramping))

    def _unknown(self, slot: int, ramping: bool) -> str:
        """Why the running motion's future is not known ahead (see PlanBasis.unknown): a stream, the speed override
        changing, or the core's own stop while the override is not 1 (a plan from it would run at another speed)."""
        if slot in _UNKNOWN_FUTURE:
            return _UNKNOWN_FUTURE[slot]
        if ramping:
            return "the speed override is changing"
        if slot == C["PLEM_STOP_SLOT"] and self.speed_override != 1.0:
            return "the arm is stopping while the speed override is below 1"
        return ""

    @property
    def speed_override(self) -> float:
        """The speed override in force (0..1)."""
        return float(self.arm[0]["override"]["factor"])

    def _motion_in(self, slot: int, segments: int) -> PolynomialMotion | None:
        """The motion in a slab slot, or a copy of the core's stop; None when the slot no longer holds it."""
        if slot != C["PLEM_STOP_SLOT"]:
            try:
                return self.slab.view(slot, segments)
            except MotionSlabError:
                return None
        arm, dof = self.arm[0], self.setup.dof
        coefficients = arm["stop_coefficients"][:segments * ORDER * dof].reshape(segments, ORDER, dof).copy()
        return PolynomialMotion(arm["stop_knots"][:segments + 1].copy(), coefficients,
                                arm["stop_final"][:3 * dof].reshape(3, dof))

    def drive_inputs(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Copies of what the drives last reported to the cycle: encoder counts, statuswords, error codes."""
        io = self._io
        return io["position"].copy(), io["statusword"].copy(), io["error_code"].copy()

    # -- one cycle ---------------------------------------------------------------------------------
    def cycle(self) -> None:
        """One period: the core's cycle (a Python bus read before and written after it), then its reports."""
        if self.python_bus:
            self._exchange_before()
        self._hand_over()
        self._core.cycle()
        if self.python_bus:
            self._exchange_after()
        self.drain()

    def _hand_over(self) -> None:
        """Before the core's first exchange on a bus that keeps itself alive until then: stop that."""
        if not self._handed_over:
            cast(SteppedBus, self.bus).hand_over()
            self._handed_over = True

    def service_bus(self) -> None:
        """Outside the cycle, often: what the bus does beside the core's exchanges (e.g. EtherCAT recovery)."""
        service = getattr(self.bus, "service", None)
        if service is not None:
            service()

    def _exchange_before(self) -> None:
        bus, io = cast(IBus, self.bus), self._io
        answered = bus.read()
        for name in _BUS_INPUTS:
            io[name][:] = getattr(bus.io, name)
        self.arm["io_answered"] = answered

    def _exchange_after(self) -> None:
        bus, io, arm = cast(IBus, self.bus), self._io, self.arm[0]
        for name in _BUS_OUTPUTS:
            getattr(bus.io, name)[:] = io[name]
        requests, resets = int(arm["power_requests"]), int(arm["power_resets"])
        if resets != self._applied_power[1]:
            bus.fault_reset()
        if requests != self._applied_power[0]:
            (bus.enable if int(arm["power_wanted"]) == DriveState.OPERATION_ENABLED else bus.disable)()
        self._applied_power = (requests, resets)
        bus.write()

    def record_raw(self, latency_ns: int, compute_ns: int) -> None:
        """The rt_raw record of the cycle just run, with its timing (a Python loop's; the core's thread writes its
        own)."""
        self._core.record_raw(latency_ns, compute_ns)

    def fault(self, cause: str, reason: str) -> None:
        """Fault the robot from outside the cycle logic (a Python loop, on an error in its cycle)."""
        self._outside_reason = reason
        self._core.fault(_OUTSIDE_FAULTS.get(cause, C["PLEM_CAUSE_INTERNAL_ERROR"]))
        self.drain()

    def fault_overrun(self, consecutive: int, limit: int) -> None:
        """Fault on `consecutive` overruns in a row (a Python loop's count; the core's thread counts its own)."""
        self._core.fault(C["PLEM_CAUSE_OVERRUN"], consecutive, limit)
        self.drain()

    def report_overruns(self, window: OverrunWindow) -> None:
        """A Python loop's summary of one window with overruns, worded as the core's thread words its own."""
        self.events.emit(EventKind.OVERRUN, "overrun",
                         self._wording.overruns((window.overruns, window.missed_periods, window.longest_run,
                                                 window.total_overruns), window.seconds), self.mode, self.cycle_count)

    def start_thread(self, period_ns: int, priority: int, cpus: int, max_consecutive_overruns: int,
                     window_ns: int) -> None:
        """The core's real-time thread runs the cycles from now on (priority 0: no real-time scheduling)."""
        self._hand_over()
        self._core.start(period_ns, priority, cpus, max_consecutive_overruns, window_ns)

    def stop_thread(self) -> None:
        """Stop the core's thread after its current cycle and wait for it."""
        self._core.stop()

    @property
    def thread_running(self) -> bool:
        """The core's real-time thread runs the cycles."""
        running: bool = self._core.running
        return running

    def close(self) -> None:
        """Stop the thread and let go of the memory the core works on (before shared memory is unmapped)."""
        self._core.close()

    # -- requests ----------------------------------------------------------------------------------
    def submit(self, command: Command) -> CommandHandle:
        """Hand a request to the core; its handle is answered from the cycles that take it."""
        if isinstance(command, SetMode) and command.mode is Mode.FREE_DRIVE:
            refusal: CommandRejected | None = getattr(self.bus, "free_drive_refusal", None)
            if refusal is not None:   # e.g. drives whose torque units are unknown: no gravity torque reaches them
                raise refusal
        with self._submitting:   # tokens rise in the order requests are queued: the core relies on it
            if isinstance(command, StartMotion) and command.until is not None:
                token = next(self._tokens)
                reaction = self._write_reaction(command.until, Stop(), token, once=True)
                self._enqueue(ArmReaction(self.reactions[reaction].slot,
                                          CommandHandle(f"{command.label}'s until condition")))
                self._enqueue(command, token)   # right behind its reaction: watched from its first cycle
            else:
                self._enqueue(command)
        return command.handle

    def _enqueue(self, command: Command, token: int | None = None) -> None:
        """Put one request into the core's ring (with `_submitting` held), waiting while the ring is full."""
        token = next(self._tokens) if token is None else token
        command.handle.token = token
        request = _Request(command)
        index, records = self._rings["commands"]
        head = int(index["head"])
        waited = threading.Event()
        deadline = time.monotonic() + QUEUE_WAIT_S
        # the loop takes a few each cycle; a stop never waits for answers to other requests
        while (head - int(index["tail"]) >= len(records)
               or (not isinstance(command, StopMotion) and len(self._pending) >= MAX_UNANSWERED)):
            if time.monotonic() > deadline:
                raise CommandRejected("the robot's request queue is full",
                                      what=f"at most {len(records)} requests waiting for the loop and "
                                           f"{MAX_UNANSWERED} waiting for its answer",
                                      why=f"no request was taken or answered for {QUEUE_WAIT_S:g} s: the loop "
                                          "is not running",
                                      how="start the robot (robot.start()), or step it, and send fewer requests")
            waited.wait(0.0005)
        record = records[head % len(records)]
        record.fill(0)
        record["token"] = token
        self._fill(record, command, request)
        self._pending[token] = request
        index["head"] = head + 1

    def _fill(self, record: np.ndarray, command: Command, request: _Request) -> None:
        if isinstance(command, SetMode):
            record["op"], record["mode"] = C["PLEM_OP_SET_MODE"], int(command.mode)
        elif isinstance(command, ResetFault):
            record["op"] = C["PLEM_OP_RESET"]
        elif isinstance(command, StopMotion):
            record["op"] = C["PLEM_OP_STOP"]
            record["goal"] = 0 if command.goal is None else self._token_of(command.goal)
        elif isinstance(command, StartStream):
            record["op"], record["cycles"] = C["PLEM_OP_STREAM"], command.timeout_cycles
        elif isinstance(command, SetSpeedOverride):
            record["op"], record["value"] = C["PLEM_OP_OVERRIDE"], command.factor
        elif isinstance(command, ArmReaction):
            record["op"] = C["PLEM_OP_UNREACT"] if command.remove else C["PLEM_OP_REACT"]
            record["slot"] = command.slot
        elif isinstance(command, SetPayload):
            record["op"], record["body"] = C["PLEM_OP_PAYLOAD"], command.body
        else:
            record["op"] = C["PLEM_OP_START"]
            slot, segments = command.slot, command.segments
            if slot is None:
                slot = request.slot = self._free_slot()
                segments = self.slab.write(slot, command.motion)
            record["slot"], record["segments"] = slot, segments
            record["basis"] = command.basis.generation
            record["peaks"][:, :self.setup.dof] = command.motion.peaks()
            record["activation"] = -1 if command.activation_cycle is None else command.activation_cycle
            tolerances = command.tolerances
            for name in ("path", "goal"):
                values = getattr(tolerances, name)
                record[f"has_{name}"] = values is not None
                if values is not None:
                    record["path" if name == "path" else "goal_tolerance"][:len(values)] = values
            record["goal_time"] = _record_value(tolerances.goal_time)
            record["stopped_velocity"] = tolerances.stopped_velocity_tolerance

    def _token_of(self, handle: CommandHandle) -> int:
        return next((token for token, request in list(self._pending.items()) if request.command.handle is handle),
                    NO_TOKEN)

    def _free_slot(self) -> int:
        """A slot of the slab's local ones (all of a private slab's) that no running or waiting motion holds."""
        free = sorted(set(self.slab.local_slots) - self._busy_slots)
        if not free:
            raise CommandRejected("too many motions are waiting to start",
                                  what=f"at most {len(self.slab.local_slots)} at once",
                                  why="every motion slot holds a running or waiting motion",
                                  how="wait for a motion to finish, or stop() first")
        self._busy_slots.add(free[0])
        return free[0]

    def write_reaction(self, condition: Condition, action: Action, once: bool = False) -> int:
        """Write a standing reaction into a free slot of the core (not yet armed: submit ArmReaction with the slot);
        its token."""
        with self._submitting:
            return self._write_reaction(condition, action, 0, once)

    def _write_reaction(self, condition: Condition, action: Action, motion: int, once: bool) -> int:
        """Write a reaction (bound to the motion whose token is `motion`, ending with it; 0: standing), with
        `_submitting` held; its token."""
        slots = self.arm[0]["reactions"]
        free = [k for k in range(len(slots)) if not slots[k]["armed"] and k not in self._arming]
        if not free:
            raise CommandRejected("too many reactions", what=f"at most {len(slots)} armed at once",
                                  why="every reaction slot of the core is in use",
                                  how="remove reactions that are no longer needed (their handle's remove())")
        token = next(self._tokens)
        write_reaction(slots[free[0]], token, condition, action, self.joint_names, motion, once)
        self._arming.add(free[0])
        for old in [t for t, r in self.reactions.items() if r.slot == free[0]]:   # the slot's last reaction
            del self.reactions[old]
        self.reactions[token] = ReactionRecord(free[0], condition.text, ACTION_NAMES[action.code], motion)
        return token

    # -- reports -----------------------------------------------------------------------------------
    def drain(self) -> None:
        """Word the core's events and answer the requests it took (events first: a fault's reason is known to
        the answers it aborts)."""
        for event in self._take("events"):
            self._on_event(event)
        for outcome in self._take("outcomes"):
            self._on_outcome(outcome)

    def _take(self, ring: str) -> list[np.void]:
        index, records = self._rings[ring]
        tail, head = int(index["tail"]), int(index["head"])
        taken = [records[n % len(records)].copy() for n in range(tail, head)]
        index["tail"] = head
        return taken

    def _reported(self, record: np.void, code: int) -> Reported:
        return Reported(code, Mode(int(record["mode"])), int(record["detail"]), int(record["joint"]),
                        tuple(float(v) for v in record["values"]))

    def _label(self, token: int, default: str = "motion ended") -> str:
        request = self._pending.get(token)
        command = request.command if request is not None else None
        return command.label if isinstance(command, StartMotion) else "stream" if isinstance(command, StartStream) \
            else default

    def _on_event(self, event: np.void) -> None:
        kind, cause, token = int(event["kind"]), int(event["cause"]), int(event["token"])
        mode, cycle, joint = Mode(int(event["mode"])), int(event["cycle"]), int(event["joint"])
        previous = None if int(event["previous_mode"]) < 0 else Mode(int(event["previous_mode"]))
        values = tuple(float(v) for v in event["values"])
        emit = self.events.emit
        if kind == C["PLEM_EVENT_MODE_CHANGED"]:
            if cause == C["PLEM_CAUSE_SET_MODE_HOLD"]:
                reason = f"holding (from {previous.name if previous else 'an unknown mode'})"
            elif cause in (C["PLEM_CAUSE_MOTION_STARTED"], C["PLEM_CAUSE_MOTION_FINISHED"]):
                reason = self._label(token)
            else:
                reason = _MODE_REASONS[cause]
            emit(EventKind.MODE_CHANGED, CAUSES[cause], reason, mode, cycle, previous)
        elif kind == C["PLEM_EVENT_FAULT"]:
            self.fault_reason = self._wording.fault_reason(cause, joint, int(event["detail"]), values,
                                                           self._outside_detail(cause))
            emit(EventKind.FAULT, CAUSES[cause], self.fault_reason, mode, cycle, previous)
        elif kind == C["PLEM_EVENT_FAULT_CLEARED"]:
            emit(EventKind.FAULT_CLEARED, CAUSES[cause], self.fault_reason, mode, cycle)
            self.fault_reason = ""
        elif kind == C["PLEM_EVENT_MOTION_STARTED"]:
            request = self._pending.get(token)
            note = request.command.note if request is not None and isinstance(request.command, StartMotion) else ""
            emit(EventKind.MOTION_STARTED, self._label(token, "motion"), f"{values[0]:.3f} s" + (f": {note}" if note
                                                                                               else ""), mode, cycle)
        elif kind == C["PLEM_EVENT_MOTION_FINISHED"]:
            if cause == C["PLEM_ANSWER_PREEMPTED"]:
                emit(EventKind.MOTION_FINISHED, "preempted", self._label(token, "motion"), mode, cycle)
            else:
                result = self._result(self._reported(event, cause), token)
                emit(EventKind.MOTION_FINISHED, result.outcome.name.lower(), result.message, mode, cycle)
        elif kind == C["PLEM_EVENT_COMMAND_REJECTED"]:
            emit(EventKind.COMMAND_REJECTED, CAUSES[cause], self._wording.enable_timeout(values).why, mode, cycle)
        elif kind == C["PLEM_EVENT_OVERRUN"]:
            emit(EventKind.OVERRUN, "overrun", self._wording.overruns(values, int(event["detail"]) / 1e3), mode, cycle)
        elif kind == C["PLEM_EVENT_REACTION"]:
            emit(EventKind.REACTION, "reaction", self._reacted(token, values), mode, cycle)
        elif kind == C["PLEM_EVENT_WARNING"]:
            emit(EventKind.WARNING, CAUSES[cause], self._wording.brakes_engaged(joint, int(event["detail"]), values),
                 mode, cycle)

    def _reacted(self, token: int, values: tuple[float, ...]) -> str:
        """What a reaction that fired saw and did, in words."""
        record = self.reactions.get(token)
        if record is None:
            return f"a reaction fired (measured {values[0]:g})"
        return f"{record.text} (measured {values[0]:.6g}): {record.action}"

    def _outside_detail(self, cause: int) -> str:
        """The words for a fault the core cannot word itself: the bus's own account, or an outside fault's text."""
        if cause == C["PLEM_CAUSE_COMMUNICATION_LOST"]:
            return self.bus.status.detail
        return self._outside_reason if cause in _OUTSIDE_FAULTS.values() else ""

    def _result(self, reported: Reported, token: int) -> TrajectoryResult:
        request = self._pending.get(token)
        command = request.command if request is not None else None
        label = self._label(token, "motion")
        goal_time = command.tolerances.goal_time if isinstance(command, StartMotion) else 0.0
        if reported.code == C["PLEM_ANSWER_REACTED"]:
            return self._reaction_result(reported, token, label)
        result = self._wording.result(reported, label, goal_time, self.fault_reason)
        note = command.note if isinstance(command, StartMotion) else ""
        if note and result.outcome in (TrajectoryOutcome.SUCCEEDED, TrajectoryOutcome.ABORTED):
            result = TrajectoryResult(result.outcome, f"{result.message}; {note}", result.error_code)
        return result

    def _reaction_result(self, reported: Reported, token: int, label: str) -> TrajectoryResult:
        """How a motion a reaction ended: succeeded when its own `until` condition came true, else replaced."""
        fired = next((r for r in self.reactions.values() if r.slot == reported.joint), None)
        text = fired.text if fired is not None else "a reaction's condition"
        if fired is not None and fired.motion == token:
            return TrajectoryResult(TrajectoryOutcome.SUCCEEDED, f"{label} stopped by its until condition: {text} "
                                                                 f"(measured {reported.values[0]:.6g})",
                                    ErrorCode.SUCCESSFUL)
        action = fired.action if fired is not None else "its action"
        return TrajectoryResult(TrajectoryOutcome.PREEMPTED, f"{label} ended by a reaction: {text} (measured "
                                                             f"{reported.values[0]:.6g}): {action}",
                                ErrorCode.SUCCESSFUL)

    def _on_outcome(self, outcome: np.void) -> None:
        token, stage, code = int(outcome["token"]), int(outcome["stage"]), int(outcome["answer"])
        request = self._pending.get(token)
        if request is None:
            return
        handle = request.command.handle
        reported = self._reported(outcome, code)
        if stage == C["PLEM_ACCEPTED"]:
            handle.accept()
            return
        if stage == C["PLEM_REJECTED"]:
            error = self._wording.refusal(reported, self.fault_reason)
            if code in _LOGGED_REFUSALS:
                self.events.emit(EventKind.COMMAND_REJECTED, type(request.command).__name__, error.summary,
                                 reported.mode, int(outcome["cycle"]))
            handle.reject(error, stale=code == C["PLEM_ANSWER_STALE"])
        elif code == C["PLEM_ANSWER_MODE"]:
            handle.finish(Mode(int(outcome["mode"])))
        elif code in _MOTION_ENDS:
            result = self._result(reported, token)
            handle.finish(result, motion_error(result))
        else:
            handle.finish()
        self._finished(token)

    def _finished(self, token: int) -> None:
        request = self._pending.pop(token, None)
        if request is not None and isinstance(request.command, ArmReaction):
            self._arming.discard(request.command.slot)
        if request is not None and request.slot is not None:
            self._busy_slots.discard(request.slot)

