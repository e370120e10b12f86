"""Robot: one arm's runtime and loop behind a Python API, built by `Robot.builder(config)` or `RobotFactory`.

Each cycle is the compiled core's (`ArmRuntime`). The loop runs either in a background thread of the calling
process (`start()`, for scripts and tests) or in the calling thread (`run()`); the commands are the same.
Motions are validated and planned in the caller's thread, so the core only samples them.
"""

from __future__ import annotations

import logging
import math
import sys
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from plem.bridge.planning import LocalPlannerLink, PlanningCalls
from plem.bridge.reactions import ReactionCalls, settle_then_average
from plem.bridge.streaming import StreamingCalls
from plem.control.commands import (
    PLAN_ATTEMPTS,
    UNKNOWN_WAIT_S,
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
    preemption_lead,
    unknown_future,
)
from plem.control.core_thread import CoreThread
from plem.control.events import EventKind, EventLog
from plem.control.free_drive import FreeDriveController
from plem.control.kinematics import ArmDynamics
from plem.control.limits import ArmLimits
from plem.control.loop import CycleLoop, LoopSettings
from plem.control.modes import Mode
from plem.control.motion import StartState, plan_point_to_point
from plem.control.payload import Payload
from plem.control.polynomial import PolynomialMotion
from plem.control.reactions import Action, Condition
from plem.control.runtime import ArmRuntime, RuntimeSettings
from plem.control.state import JointState, StateBlock
from plem.control.streaming import StreamBlock, override_factor, stream_timeout
from plem.control.trajectory import JointTrajectory, TrajectoryTolerances
from plem.core import arguments
from plem.description.drives import drive_parameters
from plem.errors import CommandRejected, ConfigError, MoveItCode, PlanningError, PlemError, RobotFault
from plem.fieldbus.bus import BusSetup, IBus, SteppedBus
from plem.fieldbus.mock import MockBus
from plem.ipc.motion_slab import MotionSlab
from plem.ipc.request_bounds import point_count
from plem.ipc.ring import SlotRing
from plem.planning import fit_to_limits
from plem.planning.named_states import find_state
from plem.robot.config import SerialArmConfig
from plem.robot.models import LARGE_JOINT_GEAR, MOTOR_ENCODER_COUNTS

if TYPE_CHECKING:
    from plem.description.model import UrdfModel
    from plem.description.validate import ValidationReport
    from plem.planning.service import PlannerService

ACCEPT_TIMEOUT_S = 2.0
MAX_SWITCH_INTERVAL_S = 0.0002
SWITCH_INTERVALS_PER_CYCLE = 5  # another thread holds the interpreter for at most a fifth of a period
DEFAULT_COUNTS_PER_RADIAN = MOTOR_ENCODER_COUNTS * LARGE_JOINT_GEAR / (2 * math.pi)



_log = logging.getLogger("plem.robot")


def _warn(runtime: ArmRuntime, text: str) -> None:
    """A start-up warning goes to the log once and into the event log."""
    _log.warning(text)
    runtime.events.emit(EventKind.WARNING, "realtime_setup", text, runtime.mode, runtime.cycle_count)


def startup_urdf(report: ValidationReport) -> tuple[UrdfModel, str]:
    """The parsed URDF and its XML from a report of start-up validation, which produces both or raises."""
    if report.urdf is None or report.urdf_xml is None:
        raise ConfigError(f"description package '{report.files.name}' has no parsed URDF",
                          what="a report of start-up validation (require_valid with Stage.STARTUP or later)",
                          why=f"it was validated at stage {report.stage.name}",
                          how="validate the package with stage=Stage.STARTUP before building the arm")
    return report.urdf, report.urdf_xml


def home_position(report: ValidationReport, joint_names: Sequence[str]) -> tuple[float, ...] | None:
    """The SRDF's `home` pose in the order of `joint_names`, when the package has one naming every joint (found as
    `plem move --to home` finds it: exactly, else the one state named so in another case)."""
    poses = report.srdf.poses(joint_names) if report.srdf is not None else {}
    home = find_state("home", poses)
    return None if home is None else tuple(poses[home])


def arm_joint_names(config: SerialArmConfig, urdf: UrdfModel) -> tuple[str, ...]:
    """The arm's joints in drive order: the preset's names, else the URDF's actuated joints."""
    model = config.MODEL
    return tuple(model.joint_names) if model else tuple(j.name for j in urdf.actuated_joints)


class Robot(PlanningCalls, StreamingCalls, ReactionCalls):
    """A built arm: bus opened, limits and dynamics loaded, loop ready to run; with an SRDF, plans in this process."""

    def __init__(self, config: SerialArmConfig, bus: IBus | SteppedBus, runtime: ArmRuntime,
                 loop: CycleLoop | CoreThread, description_package: str, dynamics: ArmDynamics,
                 report: ValidationReport | None = None) -> None:
        self.report = report
        self.config = config
        self.bus = bus
        self.runtime = runtime
        self.loop = loop
        self.description_package = description_package
        self.dynamics = dynamics  # kinematics and dynamics for the caller's thread (the loop has its own)
        self._thread: threading.Thread | None = None
        self._previous_switch_interval: float | None = None
        self._closed = False

    @staticmethod
    def builder(config: SerialArmConfig) -> RobotBuilder:
        """Start building a robot from `config` (see RobotBuilder)."""
        return RobotBuilder(config)

    # -- identity --------------------------------------------------------------------------------
    @property
    def robot_id(self) -> str:
        """Instance id: namespace of topics and prefix of shared-memory names ('' for none)."""
        return self.config.robot_id

    @property
    def joint_names(self) -> tuple[str, ...]:
        """The arm's joints in drive order, the order of every joint vector."""
        return self.runtime.joint_names

    @property
    def limits(self) -> ArmLimits:
        """Position, velocity, acceleration and jerk limits every motion is checked against."""
        return self.runtime.limits

    @property
    def events(self) -> EventLog:
        """Faults, warnings and mode changes of the loop, for subscribers and the recorder."""
        return self.runtime.events

    @property
    def mode(self) -> Mode:
        """What the loop is doing with the drives now."""
        return self.runtime.mode

    @property
    def fault_reason(self) -> str:
        """Why the arm last faulted ('' when it has not)."""
        return self.runtime.fault_reason

    # -- running the loop ------------------------------------------------------------------------
    def start(self) -> None:
        """Run the loop in the background: the core's real-time thread, or for a bus written in Python a thread of
        this process (real-time priority when permitted)."""
        if self.running:
            return
        if isinstance(self.loop, CoreThread):
            self.loop.start()
        else:
            self._start_python_loop(self.loop)
        state = self.wait_for_state(2.0)
        if state is None:
            raise PlemError("the control loop did not start", what="a first cycle within 2 s",
                            why=repr(self.loop.error) if self.loop.error else "no cycle ran",
                            how="check the bus and the system load")

    def _start_python_loop(self, loop: CycleLoop) -> None:
        self._previous_switch_interval = sys.getswitchinterval()
        # the loop thread gets the interpreter back within a fraction of its period
        sys.setswitchinterval(min(MAX_SWITCH_INTERVAL_S, self.runtime.dt / SWITCH_INTERVALS_PER_CYCLE))
        self._thread = threading.Thread(target=loop.run, name=f"plem-loop-{self.robot_id or 'robot'}", daemon=True)
        self._thread.start()

    def step(self, cycles: int = 1) -> None:
        """Run `cycles` cycles now, in the calling thread, without waiting for deadlines (simulated time).

        Only while the loop is not running; waiting on a command handle steps the same way.
        """
        if self.running:
            raise PlemError("cannot step a running loop", what="step() only while the loop is stopped",
                            why="the loop runs in its own thread", how="call shutdown() first, or just wait")
        for _ in range(cycles):
            self.runtime.cycle()

    @property
    def running(self) -> bool:
        """True while the loop runs in the background (after start(), until shutdown())."""
        if isinstance(self.loop, CoreThread):
            return self.loop.running
        return self._thread is not None and self._thread.is_alive()

    def _pump(self, condition: Callable[[], bool], timeout: float | None) -> None:
        """Advance simulated time until `condition()` or `timeout` when no loop thread runs."""
        if self.running:
            return
        cycles = math.ceil((timeout if timeout is not None else 60.0) / self.runtime.dt)
        for _ in range(cycles):
            if condition():
                return
            self.runtime.cycle()

    def run(self, duration_s: float | None = None) -> None:
        """Run the loop until `shutdown()` from elsewhere (or for `duration_s`), returning when it has stopped."""
        if isinstance(self.loop, CoreThread):
            self.start()
            waited, pause = 0.0, threading.Event()
            while self.running and (duration_s is None or waited < duration_s):
                pause.wait(0.01)
                waited += 0.01
            self.loop.stop()
        else:
            self.loop.run(duration_s)

    def shutdown(self, timeout: float = 10.0) -> None:
        """Stop any motion smoothly, disable the drives, stop the loop and close the bus (idempotent)."""
        if self._closed:
            return
        if self.mode in (Mode.TRAJECTORY, Mode.HOLD, Mode.FREE_DRIVE):
            self._settle_and_disable(timeout)
        self.loop.stop()
        thread = self._thread
        if thread is not None and thread.is_alive():
            thread.join(timeout)
        self._thread = None
        if self._previous_switch_interval is not None:
            sys.setswitchinterval(self._previous_switch_interval)
            self._previous_switch_interval = None
        self.runtime.close()
        self.bus.close()
        self._closed = True

    def _settle_and_disable(self, timeout: float) -> None:
        try:
            if self.mode is not Mode.HOLD:
                self.set_mode(Mode.HOLD, timeout)
            self.wait_until_idle(timeout)
            self.set_mode(Mode.IDLE, timeout)
        except PlemError as error:
            self.events.emit(EventKind.WARNING, "shutdown", f"could not settle before disabling: {error.summary}",
                             self.mode, self.runtime.cycle_count)

    def __enter__(self) -> Robot:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.shutdown()

    # -- state -----------------------------------------------------------------------------------
    def state(self) -> JointState | None:
        """The latest published state (None before the first cycle)."""
        return self.runtime.state_block.read()

    def live_state(self) -> JointState:
        """The latest published state; RobotFault before the first cycle (as the client raises DriverGone)."""
        state = self.state()
        if state is None:
            raise RobotFault("the arm has no state yet", what="a running loop (robot.start())",
                             why="no cycle has run", how="call robot.start() (or use `with Robot...build()`) first")
        return state

    def _planning_joints(self) -> tuple[str, ...]:
        return self.joint_names

    def _new_planner_link(self) -> LocalPlannerLink:
        """The planner runs in this process, built from the robot's description package on first use."""
        def build() -> PlannerService:
            from plem.planning.planner import Planner
            from plem.planning.service import PlannerService

            if self.report is None:
                raise PlanningError("this robot has no description report to plan with",
                                    what="a robot built with Robot.builder(...).build()", why="it was built by hand",
                                    how="build the robot with Robot.builder(config).build()",
                                    code=MoveItCode.FAILURE)
            planner = Planner.for_package(self.report, self.joint_names, self.limits, self.runtime.dt)
            return PlannerService(planner, self)
        return LocalPlannerLink(build)

    def wait_for_state(self, timeout: float = 1.0, after_cycle: int = 0) -> JointState | None:
        """Block until a state newer than `after_cycle` is published."""
        timeout = arguments.seconds(timeout, "timeout")
        after_cycle = arguments.whole(after_cycle, "after_cycle")
        deadline = threading.Event()
        waited = 0.0
        while waited <= timeout:
            state = self.state()
            if state is not None and state.cycle > after_cycle:
                return state
            deadline.wait(0.001)
            waited += 0.001
        return None

    def timing(self) -> dict[str, Any]:
        """Loop timing: whole-run and recent latency and compute, overruns, missed periods."""
        return self.loop.stats.summary()

    # -- commands --------------------------------------------------------------------------------
    def _send(self, command: Command) -> CommandHandle:
        return self.runtime.submit(command)

    def set_mode(self, mode: str | Mode, timeout: float = 5.0) -> Mode:
        """Change mode (idle, hold, free_drive) and wait until it took effect."""
        timeout = arguments.seconds(timeout, "timeout")
        return Mode(self.request_mode(mode).wait(timeout))

    def request_mode(self, mode: str | Mode) -> CommandHandle:
        """Ask for a mode change without waiting; the handle finishes with the mode reached."""
        requested = Mode.parse(arguments.instance(mode, (str, Mode), "mode",
                                                  "a mode name (idle, hold, free_drive) or a Mode"))
        return self._send(SetMode(requested, CommandHandle(f"set_mode({requested.name})", self._pump)))

    def reset_fault(self, timeout: float = 5.0) -> Mode:
        """Clear a fault: fault-reset the drives, re-enable them, hold where the arm is."""
        timeout = arguments.seconds(timeout, "timeout")
        return Mode(self.request_reset().wait(timeout))

    def request_reset(self) -> CommandHandle:
        """Ask for a fault reset without waiting; the handle finishes once the arm holds again."""
        return self._send(ResetFault(CommandHandle("reset_fault()", self._pump)))

    def stop(self, goal: CommandHandle | None = None) -> CommandHandle:
        """Cancel the running motion with a jerk-limited stop; the arm then holds.

        With `goal`, only that motion is canceled: if another has replaced it meanwhile, nothing stops.
        """
        if goal is not None:
            arguments.instance(goal, CommandHandle, "goal", "the CommandHandle of a motion, or None")
        return self._send(StopMotion(CommandHandle("stop()", self._pump), goal))

    def move_joints(self, target: Sequence[float], speed_scale: float = 1.0,
                    tolerances: TrajectoryTolerances | None = None, until: Condition | None = None) -> CommandHandle:
        """Time-optimal jerk-limited motion to `target` (rad), within every joint limit.

        Returns once the loop accepted the motion; wait on the handle for the result. With `until` (a reaction
        condition, plem.control.reactions), the motion stops as soon as the condition holds, and succeeds.
        """
        goal = self.limits.check_vector(arguments.reals(target, "target"), "the target")
        speed_scale = arguments.real(speed_scale, "speed_scale")
        return self._submit(lambda start: (plan_point_to_point(self.limits, start, goal, speed_scale).polynomial(), ""),
                            tolerances, "move_joints", until)

    def execute_trajectory(self, trajectory: JointTrajectory, tolerances: TrajectoryTolerances | None = None,
                           until: Condition | None = None) -> CommandHandle:
        """Follow a JointTrajectory with ros2_control's spline semantics, re-timed where it would break a limit.

        Refused up front only for what no timing can fix (see `plem.planning.fit_to_limits`); the result's
        message says when and how the motion was re-timed. `until` as for `move_joints`.
        """
        arguments.instance(trajectory, JointTrajectory, "trajectory", "a JointTrajectory (plem.control.trajectory)")
        point_count(len(trajectory.points))
        trajectory.check_times()

        def plan(start: StartState) -> tuple[PolynomialMotion, str]:
            timed = fit_to_limits(trajectory, self.limits.reaching(start[0]), start, self.runtime.dt)
            return timed.motion, timed.note()

        return self._submit(plan, tolerances, "trajectory", until)

    def _submit(self, plan: Callable[[StartState], tuple[PolynomialMotion, str]],
                tolerances: TrajectoryTolerances | None, label: str, until: Condition | None = None) -> CommandHandle:
        """Plan from the loop's current basis and hand the motion over, armed with its `until` condition (a Stop
        reaction the core arms just before the motion starts); re-plan when the basis moved on."""
        if tolerances is not None:
            arguments.instance(tolerances, TrajectoryTolerances, "tolerances", "a TrajectoryTolerances or None")
        tolerances = tolerances or TrajectoryTolerances()
        planning_s = 0.0
        for attempt in range(PLAN_ATTEMPTS):
            lead_s = preemption_lead(attempt, planning_s)
            basis, activation, start = self._start_state(lead_s)
            began = time.monotonic()
            motion, note = plan(start)
            planning_s = time.monotonic() - began
            handle = CommandHandle(label, self._pump)
            self._send(StartMotion(motion, basis, activation, tolerances, handle, label, note, until=until))
            handle.wait_accepted(ACCEPT_TIMEOUT_S + (0 if activation is None else lead_s))
            if not handle.stale:
                return handle
        raise CommandRejected(f"{label} could not be started", what="the arm's state to settle long enough to plan",
                              why=f"the state changed during {PLAN_ATTEMPTS} planning attempts",
                              how="retry, or stop() first")

    def _start_state(self, lead_s: float) -> tuple[PlanBasis, int | None, StartState]:
        """The basis a plan starts from, waiting (at most UNKNOWN_WAIT_S) while the running motion's future is not
        known ahead."""
        runtime = self.runtime
        self._pump(lambda: not runtime.basis.unknown, UNKNOWN_WAIT_S)
        deadline = time.monotonic() + UNKNOWN_WAIT_S
        while True:
            basis = runtime.basis
            found = basis.start(runtime.cycle_count, lead_s, runtime.dt)
            if found is not None:
                return basis, *found
            if time.monotonic() > deadline or not self.running:
                raise unknown_future(basis.unknown)
            time.sleep(runtime.dt)

    # -- reactions and the payload ------------------------------------------------------------------------
    def request_reaction(self, condition: Condition, action: Action, once: bool = False) -> tuple[int, CommandHandle]:
        """Arm a standing reaction without waiting: its token, and the handle the core answers when it took it.
        (A motion's `until` travels with the motion: `move_joints(..., until=...)`.)"""
        token = self.runtime.write_reaction(condition, action, once)
        return token, self._send(ArmReaction(self.runtime.reactions[token].slot,
                                             CommandHandle("arm a reaction", self._pump)))

    def request_reaction_removal(self, token: int) -> CommandHandle | None:
        """Disarm reaction `token` without waiting; None when it is no longer armed."""
        record = self.runtime.reactions.get(token)
        if record is None:
            return None
        slot = self.runtime.arm[0]["reactions"][record.slot]
        if int(slot["token"]) != token or not slot["armed"]:
            return None
        return self._send(ArmReaction(record.slot, CommandHandle("remove a reaction", self._pump), remove=True))

    def request_payload(self, body: np.ndarray) -> CommandHandle:
        """Give the core's model its last body (13 numbers, see SetPayload) without waiting."""
        return self._send(SetPayload(body, CommandHandle("set_payload()", self._pump)))

    @property
    def simulator(self) -> MockBus:
        """The simulated arm's control interface (push a link, mount a payload); refused on a real bus."""
        if not isinstance(self.bus, MockBus):
            raise CommandRejected("this robot has no simulator", what="a simulated arm (bus:=mock)",
                                  why=f"its bus is {type(self.bus).__name__}",
                                  how="push and load a simulated arm only: plem launch bus:=mock")
        return self.bus

    def _arm_reaction(self, condition: Condition, action: Action, once: bool) -> int:
        token, handle = self.request_reaction(condition, action, once=once)
        handle.wait(ACCEPT_TIMEOUT_S)
        return token

    def _remove_reaction(self, token: int) -> None:
        handle = self.request_reaction_removal(token)
        if handle is not None:
            handle.wait(ACCEPT_TIMEOUT_S)

    def _send_payload(self, body: np.ndarray) -> None:
        self.request_payload(body).wait(ACCEPT_TIMEOUT_S)

    def _payload_dynamics(self) -> tuple[ArmDynamics, ArmLimits]:
        return self.dynamics, self.limits

    def _hold_at(self, pose: np.ndarray) -> None:
        self.move_joints(pose.tolist()).wait(60.0)

    def _mean_state(self, seconds: float) -> tuple[np.ndarray, np.ndarray]:
        return settle_then_average(self.live_state, self._let_time_pass, seconds, self.runtime.dt)

    def _let_time_pass(self, seconds: float) -> None:
        """Let `seconds` of the robot's time pass: cycles stepped here when no loop thread runs."""
        if self.running:
            time.sleep(seconds)
        else:
            self.step(max(1, round(seconds / self.runtime.dt)))

    # -- streaming and the speed override ----------------------------------------------------------------
    def _stream_arm(self) -> tuple[ArmLimits, tuple[str, ...]]:
        return self.limits, self.joint_names

    def _stream_block(self) -> StreamBlock:
        return self.runtime.stream

    def _stream_dynamics(self) -> ArmDynamics:
        return self.dynamics

    def _stream_cycle_time(self) -> float:
        return self.runtime.dt

    def request_stream(self, timeout_s: float) -> CommandHandle:
        """Ask the core to follow the stream block, without waiting; the handle's token is the stream's session."""
        return self._send(StartStream(max(1, round(stream_timeout(timeout_s) / self.runtime.dt)),
                                      CommandHandle("stream", self._pump)))

    def request_speed_override(self, factor: float) -> CommandHandle:
        """Ask for a speed override (see `set_speed_override`) without waiting."""
        return self._send(SetSpeedOverride(override_factor(factor),
                                           CommandHandle("set_speed_override()", self._pump)))

    def _open_stream(self, timeout_s: float) -> tuple[int, CommandHandle]:
        handle = self.request_stream(timeout_s)
        handle.wait_accepted(ACCEPT_TIMEOUT_S)
        return handle.token, handle

    def _request_speed_override(self, factor: float) -> CommandHandle:
        return self.request_speed_override(factor)

    def wait_until_idle(self, timeout: float = 30.0) -> None:
        """Block until no motion (user or internal stop) is running."""
        timeout = arguments.seconds(timeout, "timeout")
        waited = 0.0
        pause = threading.Event()
        def moving() -> bool:
            return self.runtime.basis.motion is not None or self.mode is Mode.TRAJECTORY

        self._pump(lambda: not moving(), timeout)
        while moving():
            if waited > timeout:
                raise PlemError("the robot is still moving", what=f"motion to end within {timeout} s",
                                why=f"mode {self.mode.name}", how="wait longer or call stop()")
            pause.wait(0.002)
            waited += 0.002


@dataclass
class RobotBuilder:
    """Collects the choices for one robot; `build()` validates everything and opens the bus."""

    config: SerialArmConfig
    robot_id: str | None = None
    bus: IBus | None = None
    description_package: str | None = None
    urdf_file: str | None = None
    counts_per_radian: tuple[float, ...] | None = None
    state_block: Callable[[ArmLimits], StateBlock] | None = None
    motion_slab: Callable[[], MotionSlab] | None = None
    raw_ring: Callable[[], SlotRing] | None = None
    stream_block: Callable[[], StreamBlock] | None = None
    payload: Payload | None = None
    runtime_settings: RuntimeSettings = field(default_factory=RuntimeSettings)
    loop_settings: dict[str, Any] = field(default_factory=dict)

    def with_robot_id(self, robot_id: str) -> RobotBuilder:
        """Instance id: namespace of topics and prefix of shared-memory names (e.g. 'arm_left')."""
        self.robot_id = robot_id
        return self

    def with_bus(self, bus: IBus | None) -> RobotBuilder:
        """Use this bus (same as config.custom_bus)."""
        self.bus = bus
        return self

    def with_description(self, package: str, urdf_file: str | None = None) -> RobotBuilder:
        """Description package (name or path), optionally with a URDF override; presets default to their own."""
        self.description_package = package
        self.urdf_file = urdf_file or None
        return self

    def with_state_block(self, make: Callable[[ArmLimits], StateBlock]) -> RobotBuilder:
        """Publish into the block `make(limits)` returns (the RT driver's shared memory) instead of private memory."""
        self.state_block = make
        return self

    def with_motion_slab(self, make: Callable[[], MotionSlab]) -> RobotBuilder:
        """Take started motions from the slab `make()` returns (the RT driver's shared one) instead of a private one;
        called after the state block is made."""
        self.motion_slab = make
        return self

    def with_raw_ring(self, make: Callable[[], SlotRing]) -> RobotBuilder:
        """Write every cycle's rt_raw record into the ring `make()` returns (the RT driver's shared memory); called
        after the state block is made."""
        self.raw_ring = make
        return self

    def with_payload(self, payload: Payload | None) -> RobotBuilder:
        """What the flange carries from the first cycle (None: the profile's, when robot_serial names one with a
        payload, else nothing)."""
        self.payload = payload
        return self

    def with_stream_block(self, make: Callable[[], StreamBlock]) -> RobotBuilder:
        """Take streamed samples from the block `make()` returns (the RT driver's shared one) instead of a private
        one; called after the state block is made."""
        self.stream_block = make
        return self

    def with_counts_per_radian(self, counts: Sequence[float]) -> RobotBuilder:
        """Encoder counts per joint radian, for arms that are not presets."""
        self.counts_per_radian = tuple(float(c) for c in counts)
        return self

    def with_runtime_settings(self, **values: Any) -> RobotBuilder:
        """Override supervision thresholds (see RuntimeSettings)."""
        self.runtime_settings = replace(self.runtime_settings, **values)
        return self

    def with_loop_settings(self, **values: Any) -> RobotBuilder:
        """Override loop settings: cpus, max_consecutive_overruns, realtime."""
        self.loop_settings.update(values)
        return self

    def build(self) -> Robot:
        """Validate the config, load profile, description and limits, open the bus, make the runtime."""
        from plem.description.validate import Stage, require_valid

        config = replace(self.config, robot_id=self.robot_id) if self.robot_id is not None else self.config
        config.validate()
        offsets = self._joint_offsets(config)
        model = config.MODEL
        package = self.description_package or (model.description_package if model else None)
        if package is None:
            raise ConfigError("no description package for this arm",
                              what="a description package with the arm's URDF and joint_limits.yaml",
                              why=f"{config.model_name()} is not a preset and none was given",
                              how="call .with_description('my_robot_description') on the builder")
        report = require_valid(package, stage=Stage.STARTUP, urdf_file=self.urdf_file)
        urdf, urdf_xml = startup_urdf(report)
        joint_names = arm_joint_names(config, urdf)
        if len(joint_names) != config.dof:
            raise ConfigError("the URDF's DOF does not match the configuration",
                              what=f"{config.dof} actuated joints", why=f"{package} has {len(joint_names)}",
                              how="use the description package that belongs to this arm")
        drives = drive_parameters(urdf, joint_names) or ()
        counts = self.counts_per_radian or (tuple(d.signed_counts_per_radian for d in drives) if drives else
                                            model.counts_per_radian() if model else
                                            (DEFAULT_COUNTS_PER_RADIAN,) * config.dof)
        bus = self._bus(config)
        limits = ArmLimits.from_joint_limits(report.limits, joint_names)
        setup = BusSetup(joint_names, tuple(counts), config.cycle_time * 1e-6, urdf_xml,
                         config.network_interface, config.master_index, drives, home_position(report, joint_names),
                         (tuple(limits.min_position), tuple(limits.max_position)))
        dynamics = ArmDynamics(urdf_xml, joint_names)
        state_block = self.state_block(limits) if self.state_block else StateBlock(config.dof)
        bus.open(setup)
        loop_settings = LoopSettings(cycle_time_ns=config.cycle_time * 1000, priority=config.rt_priority,
                                     **self.loop_settings)
        limit = loop_settings.max_consecutive_overruns
        runtime = ArmRuntime(bus, setup, limits, np.array(offsets, dtype=np.int64),
                             FreeDriveController(dynamics, limits, setup.cycle_time_s), self.runtime_settings,
                             state_block, slab=self.motion_slab() if self.motion_slab else None,
                             raw_ring=self.raw_ring() if self.raw_ring else None, max_consecutive_overruns=limit,
                             stream=self.stream_block() if self.stream_block else None)
        payload = self.payload or self._profile_payload(config)
        if payload is not None:   # before the first cycle, the core's model takes it directly
            from plem.control.payload_estimation import last_body_with

            body = last_body_with(dynamics.model, payload)
            model, last = runtime.arm[0]["model"], config.dof - 1
            model["mass"][last], model["com"][last], model["inertia"][last] = body[0], body[1:4], body[4:]
        loop: CycleLoop | CoreThread
        if runtime.python_bus:   # served at its own pace by a thread of this process
            loop = CycleLoop(runtime.cycle, loop_settings,
                             on_overruns=lambda n: runtime.fault_overrun(n, limit),
                             on_error=lambda error: runtime.fault("internal_error", f"cycle raised {error!r}"),
                             on_overrun_report=runtime.report_overruns,
                             on_warning=lambda text: _warn(runtime, text), after_cycle=runtime.record_raw)
        else:
            loop = CoreThread(runtime, loop_settings, on_warning=lambda text: _warn(runtime, text))
        return Robot(config, bus, runtime, loop, str(package), dynamics, report)

    def _bus(self, config: SerialArmConfig) -> IBus | SteppedBus:
        bus = self.bus or config.custom_bus
        if bus is None:
            from plem.fieldbus.ethercat.master import EtherCATBus

            return EtherCATBus()
        if not isinstance(bus, IBus):
            raise ConfigError("custom_bus does not implement IBus", what="an object with the IBus methods",
                              why=f"got {type(bus).__name__}", how="pass a MockBus or an IBus implementation")
        return bus

    @staticmethod
    def _profile_payload(config: SerialArmConfig) -> Payload | None:
        """The payload of the unit's profile when robot_serial names one that has it."""
        if not config.robot_serial:
            return None
        from plem.robot.profile import RobotProfile

        payload = RobotProfile.load_from_serial(config.robot_serial).payload
        return None if payload is None else payload.to_payload()

    @staticmethod
    def _joint_offsets(config: SerialArmConfig) -> list[int]:
        """Offsets from the profile when robot_serial is set (the reference's rule), else from the config."""
        if not config.robot_serial:
            return list(config.joint_offsets)
        from plem.robot.profile import RobotProfile

        profile = RobotProfile.load_from_serial(config.robot_serial)
        if len(profile.joint_offsets) != config.dof:
            raise ConfigError(f"profile {config.robot_serial} has {len(profile.joint_offsets)} joint offsets",
                              what=f"{config.dof} offsets, one per joint",
                              why=f"{RobotProfile.default_path(config.robot_serial)} has "
                                  f"{len(profile.joint_offsets)}",
                              how=f"recreate it: plem profile create {config.robot_serial} --offsets ...")
        return list(profile.joint_offsets)


class RobotFactory:
    """Builds a robot from a config and an optional bus, like the reference's RobotFactory<Model>::create."""

    @staticmethod
    def create(config: SerialArmConfig, bus: IBus | None = None) -> Robot:
        """Build the robot `config` describes on `bus` (when None: config.custom_bus, else the EtherCAT master)."""
        return Robot.builder(config).with_bus(bus).build()
