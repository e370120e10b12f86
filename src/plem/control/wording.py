"""The words for what the compiled core reports as codes and numbers: fault reasons, refusals, motion results.

The core's cycle never formats text; each event and answer carries a code, a joint and a few numbers. Here
they become the reasons events carry, the PlemErrors callers see and the TrajectoryResults goals end with.
"""

from __future__ import annotations

from dataclasses import dataclass

from plem.control.compiled import CONSTANTS as C
from plem.control.modes import Mode, check_transition
from plem.control.trajectory import ErrorCode, TrajectoryOutcome, TrajectoryResult
from plem.errors import CommandRejected, PlemError, RobotFault
from plem.fieldbus.bus import DriveState
from plem.fieldbus.cia402 import describe_drive_fault

#: How to get a robot holding, in each interface a user may command it from.
HOLD_HOW = ("hold first: set_mode('hold') in Python, `plem mode hold`, or on ROS the wim_rt_driver/set_mode action "
            "or controller_manager/switch_controller activating the trajectory controller")
#: How to stop a motion before changing mode, in each interface.
STOP_HOW = ("stop the motion (stop() in Python, `plem mode hold`, or cancel the goal on ROS), wait until the arm is "
            "still, then retry")
#: How to clear a fault, in each interface.
RESET_HOW = ("clear the fault first: reset_fault() in Python, `plem reset`, or on ROS "
             "controller_manager/set_hardware_component_state with target state active")

#: The cause names events carry, by the core's cause code.
CAUSES: dict[int, str] = {
    C["PLEM_CAUSE_SET_MODE_IDLE"]: "set_mode", C["PLEM_CAUSE_SET_MODE_FREE_DRIVE"]: "set_mode",
    C["PLEM_CAUSE_SET_MODE_HOLD"]: "set_mode", C["PLEM_CAUSE_DRIVES_ENABLED"]: "drives_enabled",
    C["PLEM_CAUSE_MOTION_STARTED"]: "motion_started", C["PLEM_CAUSE_MOTION_FINISHED"]: "motion_finished",
    C["PLEM_CAUSE_DRIVE_FAULT"]: "drive_fault", C["PLEM_CAUSE_DRIVE_DISABLED"]: "drive_disabled",
    C["PLEM_CAUSE_ENCODER_JUMP"]: "encoder_jump", C["PLEM_CAUSE_POSITION_LIMIT"]: "position_limit",
    C["PLEM_CAUSE_VELOCITY_LIMIT"]: "velocity_limit", C["PLEM_CAUSE_TRACKING_ERROR"]: "tracking_error",
    C["PLEM_CAUSE_COMMUNICATION_LOST"]: "communication_lost", C["PLEM_CAUSE_INVALID_COMMAND"]: "invalid_command",
    C["PLEM_CAUSE_COMMAND_POSITION"]: "position_limit", C["PLEM_CAUSE_COMMAND_VELOCITY"]: "velocity_limit",
    C["PLEM_CAUSE_COMMAND_ACCELERATION"]: "acceleration_limit", C["PLEM_CAUSE_COMMAND_JERK"]: "jerk_limit",
    C["PLEM_CAUSE_OVERRUN"]: "overrun", C["PLEM_CAUSE_INTERNAL_ERROR"]: "internal_error",
    C["PLEM_CAUSE_RESET"]: "reset_fault", C["PLEM_CAUSE_BRAKES_ENGAGED"]: "brakes_engaged",
    C["PLEM_CAUSE_ENABLE_TIMEOUT"]: "enable_timeout", C["PLEM_CAUSE_CONTACT"]: "contact",
    C["PLEM_CAUSE_REACTION"]: "reaction",
}
_COMMAND_KINDS = {C["PLEM_CAUSE_COMMAND_POSITION"]: "position", C["PLEM_CAUSE_COMMAND_VELOCITY"]: "velocity",
                  C["PLEM_CAUSE_COMMAND_ACCELERATION"]: "acceleration", C["PLEM_CAUSE_COMMAND_JERK"]: "jerk"}
#: What needs the arm still, by the core's action number of a MOVING refusal.
_STANDSTILL_ACTIONS = ("disable the drives", "enter free drive", "reset the fault")


@dataclass(frozen=True)
class Reported:
    """One event or answer as the core wrote it: its code, the mode, the joint and the numbers."""

    code: int
    mode: Mode
    detail: int
    joint: int
    values: tuple[float, ...]


class Wording:
    """Words one arm's reports, knowing its joints, limits and the texts Python keeps beside the core."""

    def __init__(self, joint_names: tuple[str, ...], enable_timeout_s: float, standstill_velocity: float,
                 cycle_time_s: float, overrun_limit: int) -> None:
        self.joint_names = joint_names
        self.enable_timeout_s = enable_timeout_s
        self.standstill_velocity = standstill_velocity
        self.cycle_time_s = cycle_time_s
        self.overrun_limit = overrun_limit

    def _joint(self, joint: int) -> str:
        return self.joint_names[joint] if 0 <= joint < len(self.joint_names) else "a joint"

    def fault_reason(self, cause: int, joint: int, detail: int, values: tuple[float, ...],
                     outside: str = "") -> str:
        """Why the arm faulted; `outside` is the text of a fault raised from outside the cycle (overrun, error)."""
        name, v = self._joint(joint), values
        if cause in (C["PLEM_CAUSE_DRIVE_FAULT"], C["PLEM_CAUSE_DRIVE_DISABLED"]):
            return describe_drive_fault(name, detail, int(v[0]))
        if cause == C["PLEM_CAUSE_ENCODER_JUMP"]:
            return (f"{name} encoder jumped {v[0]:.4g} rad in one cycle (at most {v[1]:.4g} rad is physically "
                    "possible)")
        if cause == C["PLEM_CAUSE_POSITION_LIMIT"]:
            return f"{name} at {v[0]:.4g} rad is outside [{v[1]:.4g}, {v[2]:.4g}] rad"
        if cause == C["PLEM_CAUSE_VELOCITY_LIMIT"]:
            return f"{name} moves at {v[0]:.4g} rad/s, above its limit {v[1]:.4g} rad/s"
        if cause == C["PLEM_CAUSE_CONTACT"]:
            return (f"contact: the external torque on {name} is {v[0]:.4g} N·m, past its contact threshold "
                    f"{v[1]:.4g} N·m; the arm stopped (reset_fault() holds it where it is). A load on the flange "
                    "that the model does not know pushes too: set it (robot.set_payload(), payload:=)")
        if cause == C["PLEM_CAUSE_TRACKING_ERROR"]:
            return f"{name} is {v[0]:.4g} rad from its command (tolerance {v[1]:g} rad)"
        if cause == C["PLEM_CAUSE_INVALID_COMMAND"]:
            return f"command for {name} is not a finite number"
        if cause == C["PLEM_CAUSE_COMMAND_POSITION"]:
            return f"command for {name} has position {v[0]:.6g} rad, outside [{v[1]:.6g}, {v[2]:.6g}]"
        if cause in _COMMAND_KINDS:
            return f"command for {name} has {_COMMAND_KINDS[cause]} {v[0]:.6g}, beyond its limit {v[1]:.6g}"
        if cause == C["PLEM_CAUSE_COMMUNICATION_LOST"]:
            return f"bus communication lost: {outside or 'no response'}"
        if cause == C["PLEM_CAUSE_OVERRUN"]:
            return (f"{v[0]:.0f} consecutive cycles overran their {self.cycle_time_s * 1e6:.0f} µs period "
                    f"(max_consecutive_overruns {v[1]:.0f})")
        if outside:
            return outside
        return f"fault {CAUSES.get(cause, cause)} on {name}" if joint >= 0 else f"fault {CAUSES.get(cause, cause)}"

    def overruns(self, values: tuple[float, ...], seconds: float) -> str:
        """The summary of one window of overruns: how many, the periods skipped, the longest run, the total."""
        overruns, missed, longest, total = (int(v) for v in values[:4])
        return (f"{overruns} overrun{'' if overruns == 1 else 's'} in the last {seconds:.0f} s ({missed} periods "
                f"skipped, at most {longest} in a row; {self.overrun_limit} in a row fault the arm), {total} in all")

    def brakes_engaged(self, joint: int, row: int, values: tuple[float, ...]) -> str:
        """The warning when drives in FAULT could not hold the arm and were switched off onto the brakes."""
        found = (f"moves at {values[0]:.4g} rad/s (limit {values[1]:.4g} rad/s)" if row == 2
                 else f"is {values[0]:.4g} rad from where it is held (tolerance {values[1]:g} rad)")
        return (f"in FAULT the drives could not hold the arm: {self._joint(joint)} {found}; drives disabled, "
                "the brakes hold the joints")

    def stuck_drives(self, values: tuple[float, ...]) -> str:
        """The drives that did not reach operation enabled, from the states the core packed four bits each."""
        packed = int(values[0]) | int(values[1]) << 32
        states = [DriveState(packed >> 4 * i & 0xF) for i in range(len(self.joint_names))]
        return ", ".join(f"{name} {state.name}" for name, state in zip(self.joint_names, states, strict=True)
                         if state is not DriveState.OPERATION_ENABLED)

    def enable_timeout(self, values: tuple[float, ...]) -> RobotFault:
        """The error of drives that did not enable in time."""
        return RobotFault("the drives did not enable", what="every drive in OPERATION_ENABLED",
                          why=f"after {self.enable_timeout_s:g} s: {self.stuck_drives(values)}",
                          how="check the drives (power, safety circuit, faults) and retry")

    def refusal(self, answer: Reported, fault_reason: str) -> PlemError:
        """The error a refused request raises."""
        code, mode = answer.code, answer.mode
        if code == C["PLEM_ANSWER_NOT_HOLDING"]:
            return CommandRejected(f"cannot start a motion in {mode.name}",
                                   what="the robot holding (HOLD) or moving (TRAJECTORY)",
                                   why=f"the robot is in {mode.name}" + (f": {fault_reason}" if mode is Mode.FAULT
                                                                        else ""),
                                   how=HOLD_HOW if mode is not Mode.FAULT else RESET_HOW)
        if code == C["PLEM_ANSWER_STALE"]:
            return CommandRejected("the motion was planned from an outdated state",
                                   what="a plan starting from the arm's current command",
                                   why="the command changed while the motion was being planned",
                                   how="plan again (the robot's methods retry automatically)")
        if code == C["PLEM_ANSWER_MODE_PENDING"]:
            return CommandRejected("a mode change is already in progress", what="one mode change at a time",
                                   why=f"waiting for the drives to enable for {Mode(answer.detail).name}",
                                   how="wait for the previous set_mode to finish")
        if code == C["PLEM_ANSWER_TRANSITION"]:
            try:
                check_transition(mode, Mode(answer.detail))
            except CommandRejected as error:
                return error
        if code == C["PLEM_ANSWER_MOVING"]:
            action = _STANDSTILL_ACTIONS[answer.detail] if 0 <= answer.detail < len(_STANDSTILL_ACTIONS) else "do that"
            moving = answer.joint >= 0
            return CommandRejected(f"cannot {action} while the arm moves",
                                   what="the arm standing still (|v| < "
                                        f"{self.standstill_velocity:g} rad/s)",
                                   why=f"{self._joint(answer.joint)} moves at {answer.values[0]:.3g} rad/s" if moving
                                   else "a motion is still running",
                                   how=STOP_HOW)
        if code == C["PLEM_ANSWER_ENABLE_TIMEOUT"]:
            return self.enable_timeout(answer.values)
        if code == C["PLEM_ANSWER_RESET_NO_BUS"]:
            return RobotFault("the fault cannot be reset", what="working bus communication", why=fault_reason,
                              how="restore the EtherCAT connection, then reset again")
        if code == C["PLEM_ANSWER_FAULTED"]:
            return RobotFault("the robot faulted", what="the mode change to complete", why=fault_reason,
                              how="reset_fault() once the cause is gone")
        if code == C["PLEM_ANSWER_INVALID_SLOT"]:
            return CommandRejected("the motion slot does not hold the announced motion",
                                   what=f"{answer.values[0]:.0f} segments in slot {answer.detail}",
                                   why=f"it holds {answer.values[1]:.0f}",
                                   how="restart the robot (its command service is out of step)")
        if code == C["PLEM_ANSWER_STREAMING"]:
            return CommandRejected("cannot start a planned motion while a stream runs",
                                   what="the stream to end first",
                                   why="the arm follows streamed samples, whose future is not known to plan from",
                                   how="stop the stream (robot.stop(), or stop sending samples: it ends after its "
                                       "timeout), then move")
        if code == C["PLEM_ANSWER_MALFORMED_REACTION"]:
            return CommandRejected("the reaction's condition cannot be evaluated",
                                   what="comparisons of this arm's measures, combined with &, | and ~",
                                   why=f"reaction slot {answer.detail} holds a term the core does not know, an index "
                                       "beyond the arm or an incomplete combination",
                                   how="build conditions from plem.control.reactions.Measure")
        if code == C["PLEM_ANSWER_INVALID_VALUE"]:
            return CommandRejected("a value of the request is out of range", what="a value the core accepts",
                                   why=f"got {answer.values[0]:.6g}", how="check the request against its documentation")
        return CommandRejected("the request could not be handled", what="a request the core knows",
                               why=f"request code {answer.detail}", how="use the same plem version throughout")

    def result(self, answer: Reported, label: str, goal_time: float, fault_reason: str) -> TrajectoryResult:
        """How a motion ended."""
        code, v = answer.code, answer.values
        if code == C["PLEM_ANSWER_SUCCEEDED"]:
            return TrajectoryResult(TrajectoryOutcome.SUCCEEDED, f"{label} reached its goal", ErrorCode.SUCCESSFUL)
        if code == C["PLEM_ANSWER_GOAL_VIOLATED"]:
            return TrajectoryResult(TrajectoryOutcome.ABORTED,
                                    f"goal tolerance violated: {self._joint(answer.joint)} is {v[0]:.4g} rad from the "
                                    f"goal {goal_time:g} s after the end", ErrorCode.GOAL_TOLERANCE_VIOLATED)
        if code == C["PLEM_ANSWER_PATH_VIOLATED"]:
            return TrajectoryResult(TrajectoryOutcome.ABORTED,
                                    f"path tolerance violated: {self._joint(answer.joint)} is {v[0]:.4g} rad from the "
                                    f"trajectory (tolerance {v[1]:.4g} rad)", ErrorCode.PATH_TOLERANCE_VIOLATED)
        if code == C["PLEM_ANSWER_FAULT_ABORTED"]:
            return TrajectoryResult(TrajectoryOutcome.ABORTED, f"robot fault: {fault_reason}",
                                    ErrorCode.PATH_TOLERANCE_VIOLATED)
        if code == C["PLEM_ANSWER_PREEMPTED"]:
            return TrajectoryResult.preempted()
        if code == C["PLEM_ANSWER_STREAM_TIMED_OUT"]:
            gap = v[0] * self.cycle_time_s
            return TrajectoryResult(TrajectoryOutcome.SUCCEEDED,
                                    f"{label} ended: no sample for {gap:g} s, the arm came to rest",
                                    ErrorCode.SUCCESSFUL)
        return TrajectoryResult.canceled()
