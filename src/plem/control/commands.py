"""Commands that travel from callers to the loop, and the handles callers wait on.

A caller validates and plans a command in its own thread, then hands it to the compiled core's command ring
(`ArmRuntime.submit`). The core accepts or rejects it at the start of a cycle and later finishes it; the handle
carries both answers.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from plem.control.modes import Mode
from plem.control.motion import StartState
from plem.control.polynomial import PolynomialMotion
from plem.control.reactions import Condition
from plem.control.trajectory import TrajectoryOutcome, TrajectoryResult, TrajectoryTolerances
from plem.errors import CommandRejected, PlemError, RobotFault


class CommandTimeout(PlemError):
    """A command did not finish within the time the caller allowed."""


Pump = Callable[[Callable[[], bool], "float | None"], None]


class CommandHandle:
    """Acceptance and completion of one command, set by the loop and awaited by the caller.

    `pump(condition, timeout)` runs cycles in the caller's thread when no loop thread is running
    (simulated time for scripts and tests), so waiting works the same in both cases.
    """

    def __init__(self, description: str, pump: Pump | None = None) -> None:
        self.description = description
        self._pump = pump
        self._accepted = threading.Event()
        self._finished = threading.Event()
        self.rejection: PlemError | None = None
        self.stale = False
        self.result: Any = None
        self.error: PlemError | None = None
        #: The core's token for the command once handed over (a stream's session).
        self.token = 0

    # -- loop side -------------------------------------------------------------------------------
    def accept(self) -> None:
        """Mark the command as taken by the loop; its completion comes later."""
        self._accepted.set()

    def reject(self, error: PlemError, *, stale: bool = False) -> None:
        """Refuse the command (`stale`: planned from an outdated state, worth planning again); ends the wait."""
        self.rejection = error
        self.stale = stale
        self._accepted.set()
        self._finished.set()

    def finish(self, result: Any = None, error: PlemError | None = None) -> None:
        """Complete the command with its result, or with the error its caller should see."""
        self.result = result
        self.error = error
        self._accepted.set()
        self._finished.set()

    # -- caller side -----------------------------------------------------------------------------
    @property
    def done(self) -> bool:
        """The loop finished or refused the command."""
        return self._finished.is_set()

    @property
    def is_accepted(self) -> bool:
        """The loop took the command (or already answered it)."""
        return self._accepted.is_set()

    def wait_accepted(self, timeout: float | None) -> None:
        """Block until the loop took or refused the command; raises the rejection, except a stale one, which the
        caller plans again (see `stale`)."""
        if self._pump is not None:
            self._pump(self._accepted.is_set, timeout)
        if not self._accepted.wait(timeout):
            raise CommandTimeout(f"{self.description} was not picked up by the loop",
                                 what=f"the loop to accept the command within {timeout} s",
                                 why="the loop is not running or is stalled",
                                 how="start the robot (robot.start()) and check its status")
        if self.rejection is not None and not self.stale:
            raise self.rejection

    def wait(self, timeout: float | None = None) -> Any:
        """Block until the command finished; returns its result, raises on rejection, abort or fault."""
        if self._pump is not None:
            self._pump(self._finished.is_set, timeout)
        if not self._finished.wait(timeout):
            raise CommandTimeout(f"{self.description} did not finish in {timeout} s",
                                 what=f"completion within {timeout} s", why="it is still running",
                                 how="wait longer, or stop() the robot")
        if self.rejection is not None:
            raise self.rejection
        if self.error is not None:
            raise self.error
        return self.result


#: A preemption starts this far ahead of the running motion on the first attempt.
PREEMPTION_LEAD_S = 0.02
#: Attempts at planning a preemption before the caller is told the state kept changing.
PLAN_ATTEMPTS = 5
#: Longest a plan waits for the running motion's future to be known (a speed override changing, a stream ending).
UNKNOWN_WAIT_S = 3.0


def unknown_future(reason: str) -> CommandRejected:
    """The refusal of a plan that waited UNKNOWN_WAIT_S for the running motion's future to be known."""
    return CommandRejected("cannot plan from the running motion now", what="its future known ahead",
                           why=f"{reason} (for {UNKNOWN_WAIT_S:g} s)",
                           how="stop the robot (stop()) and let it hold, then move; end a stream before a planned "
                               "motion")


def preemption_lead(attempt: int, planning_s: float) -> float:
    """How far ahead (s) attempt `attempt` starts a preempting motion: doubled on each retry, and after a plan that
    took `planning_s` (0 on the first attempt) at least one and a half times that, so a slow fit catches up."""
    return max(PREEMPTION_LEAD_S * 2.0 ** attempt, 1.5 * planning_s)


@dataclass(frozen=True)
class PlanBasis:
    """The loop's motion state a plan starts from, as the core published it.

    A plan is valid only while the core's basis still has this `generation` (it changes whenever the basis
    does), so a stale plan is refused. Holding: the plan starts at `hold_position` at rest. Moving: it starts
    at `motion`'s state at the activation cycle the caller picked.
    """

    hold_position: np.ndarray
    motion: PolynomialMotion | None = None
    motion_start_cycle: int = 0
    generation: int = 0
    motion_time: float = 0.0        # the running motion's own time at motion_start_cycle
    rate: float = 1.0               # how fast that time advances: the speed override in force for it
    unknown: str = ""               # why the running motion's future is not known ahead ("" when it is)

    def start(self, cycle: int, lead_s: float, dt: float) -> tuple[int | None, StartState] | None:
        """Where a motion planned now starts: at rest at the hold position (activation None), or in the running
        motion's state in its own time (the speed override scales the new motion as it does the running one) at an
        activation cycle `lead_s` after `cycle`; None while that state is not known ahead (see `unknown`)."""
        if self.unknown:
            return None
        dof = len(self.hold_position)
        if self.motion is None:
            return None, (self.hold_position.copy(), np.zeros(dof), np.zeros(dof))
        activation = cycle + max(2, math.ceil(lead_s / dt))
        return activation, self.motion.state_at(self.motion_time + self.rate * (activation - self.motion_start_cycle)
                                                * dt)


@dataclass
class SetMode:
    """Change the robot's mode; the handle finishes with the mode reached."""

    mode: Mode
    handle: CommandHandle


@dataclass
class StartMotion:
    """Run a planned motion from `basis`, at `activation_cycle` when it preempts a running one.

    The motion goes into a free slot of the robot's own motion slab, unless `slot` names the slab slot it was
    already written to (with its `segments`), as the RT driver's command service does.
    """

    motion: PolynomialMotion
    basis: PlanBasis
    activation_cycle: int | None
    tolerances: TrajectoryTolerances
    handle: CommandHandle
    label: str = "motion"
    note: str = ""  # how the motion differs from what was asked (re-timed to the limits), for the result
    slot: int | None = None
    segments: int = 0
    until: Condition | None = None   # stops the motion once it holds (armed in the core just before it starts)


@dataclass
class StopMotion:
    """Cancel the running motion; with `goal`, only if that very command is the one running."""

    handle: CommandHandle
    goal: CommandHandle | None = None


@dataclass
class ResetFault:
    """Clear a fault and re-enable the drives into HOLD."""

    handle: CommandHandle


@dataclass
class StartStream:
    """Follow the stream block's samples from now on; a stream without samples for `timeout_cycles` comes to rest
    and ends. The handle is accepted with the stream's session, and finishes when the stream ends."""

    timeout_cycles: int
    handle: CommandHandle


@dataclass
class SetSpeedOverride:
    """Scale the speed of every motion from now on, 0 (stopped on its path) to 1 (as planned)."""

    factor: float
    handle: CommandHandle


@dataclass
class ArmReaction:
    """Arm (or, with `remove`, remove) the reaction written into the core's reaction slot `slot`."""

    slot: int
    handle: CommandHandle
    remove: bool = False


@dataclass
class SetPayload:
    """The core's last body becomes `body` (mass, centre of mass, inertia about it: 13 numbers)."""

    body: np.ndarray
    handle: CommandHandle


#: Everything the loop's inbox carries.
Command = SetMode | StartMotion | StopMotion | ResetFault | StartStream | SetSpeedOverride | ArmReaction | SetPayload


def motion_error(result: TrajectoryResult) -> PlemError | None:
    """The PlemError a caller sees for a finished motion, or None when it succeeded, was preempted or canceled."""
    if result.outcome is TrajectoryOutcome.ABORTED:
        return RobotFault("the motion was aborted", what="the motion to reach its goal",
                          why=result.message, how="check the cause; the arm stopped smoothly and holds")
    if result.outcome is TrajectoryOutcome.REJECTED:
        return CommandRejected("the motion was rejected", what="a motion the robot can execute",
                               why=result.message, how="fix the command and send it again")
    return None
