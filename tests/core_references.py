"""Plain-Python references of what the compiled core computes, for property tests against the core.

These are the implementations plem ran before its cycle was compiled; they live only here, where they check
the core's results on inputs hypothesis chooses.
"""

from __future__ import annotations

import numpy as np

from plem.fieldbus.bus import DriveState
from plem.fieldbus.cia402 import Controlword

FAULT_BIT = 0x0008
RESET_BIT = 0x0080

# (mask, value, state) in the order of the CiA402 statusword table.
_PATTERNS = (
    (0x4F, 0x00, DriveState.NOT_READY_TO_SWITCH_ON),
    (0x4F, 0x40, DriveState.SWITCH_ON_DISABLED),
    (0x6F, 0x21, DriveState.READY_TO_SWITCH_ON),
    (0x6F, 0x23, DriveState.SWITCHED_ON),
    (0x6F, 0x27, DriveState.OPERATION_ENABLED),
    (0x6F, 0x07, DriveState.QUICK_STOP_ACTIVE),
    (0x4F, 0x0F, DriveState.FAULT_REACTION_ACTIVE),
    (0x4F, 0x08, DriveState.FAULT),
)


def _match(bits: int) -> DriveState:
    for mask, value, state in _PATTERNS:
        if bits & mask == value:
            return state
    return DriveState.FAULT if bits & FAULT_BIT else DriveState.NOT_READY_TO_SWITCH_ON


_STATE_OF_BITS = tuple(_match(bits) for bits in range(0x80))


def decode_statusword(sw: int) -> DriveState:
    """The power state a statusword reports (the CiA402 table; outside it, FAULT or NOT_READY)."""
    return _STATE_OF_BITS[sw & 0x6F]


_ENABLE_CHAIN = (DriveState.SWITCH_ON_DISABLED, DriveState.READY_TO_SWITCH_ON, DriveState.SWITCHED_ON,
                 DriveState.OPERATION_ENABLED)
_ENTERS: dict[DriveState, int] = {
    DriveState.SWITCH_ON_DISABLED: Controlword.DISABLE_VOLTAGE,
    DriveState.READY_TO_SWITCH_ON: Controlword.SHUTDOWN,
    DriveState.SWITCHED_ON: Controlword.SWITCH_ON,
    DriveState.OPERATION_ENABLED: Controlword.ENABLE_OPERATION,
}


def next_controlword(state: DriveState, target: DriveState, previous: int = 0) -> int:
    """The reference of plem.fieldbus.cia402.next_controlword."""
    if target not in _ENTERS:
        raise ValueError(f"{target.name} is not a state a controlword can hold a drive in")
    if state is DriveState.FAULT:
        return Controlword.DISABLE_VOLTAGE if previous & RESET_BIT else Controlword.FAULT_RESET
    if state not in _ENTERS:
        return Controlword.DISABLE_VOLTAGE
    here, there = _ENABLE_CHAIN.index(state), _ENABLE_CHAIN.index(target)
    return _ENTERS[_ENABLE_CHAIN[here + 1] if here < there else target]


def drive_transition(state: DriveState, controlword: int, previous: int) -> DriveState:
    """The reference of plem.fieldbus.cia402.drive_transition."""
    if state is DriveState.NOT_READY_TO_SWITCH_ON:
        return DriveState.SWITCH_ON_DISABLED
    if state is DriveState.FAULT_REACTION_ACTIVE:
        return DriveState.FAULT
    if state is DriveState.FAULT:
        rising = controlword & RESET_BIT and not previous & RESET_BIT
        return DriveState.SWITCH_ON_DISABLED if rising else state
    if controlword & RESET_BIT:
        return state
    if not controlword & 0x02:
        return DriveState.SWITCH_ON_DISABLED
    running = state is DriveState.OPERATION_ENABLED or state is DriveState.QUICK_STOP_ACTIVE
    if not controlword & 0x04:
        return DriveState.QUICK_STOP_ACTIVE if running else DriveState.SWITCH_ON_DISABLED
    if not controlword & 0x01:
        return state if state is DriveState.QUICK_STOP_ACTIVE else DriveState.READY_TO_SWITCH_ON
    if state is DriveState.READY_TO_SWITCH_ON:
        return DriveState.SWITCHED_ON
    if controlword & 0x08:
        return DriveState.OPERATION_ENABLED if state is DriveState.SWITCHED_ON or running else state
    return DriveState.SWITCHED_ON if state is DriveState.OPERATION_ENABLED else state


class PowerSequencer:
    """The master's side of CiA402 power control: the controlword each drive gets this cycle.

    `request()` sets the state wanted of every drive and `request_reset()` asks for one fault-reset edge;
    `commands(seen)` then chooses, from the states the drives last reported, the controlword that moves
    each one step toward it. A drive seen in fault is wanted down (switch on disabled) until enabled again.
    Once the controlwords stop changing for unchanged states, they are returned as they are until a state
    or a request changes, so a settled arm costs a list comparison per cycle.
    """

    def __init__(self, dof: int) -> None:
        self.wanted = [DriveState.SWITCH_ON_DISABLED] * dof
        self.reset = [False] * dof
        self.sent = [int(Controlword.DISABLE_VOLTAGE)] * dof
        self._settled_for: list[DriveState] | None = None  # the states the controlwords settled for

    def request(self, state: DriveState) -> None:
        """Ask every drive for `state`; it is reached over the next cycles."""
        self.wanted = [state] * len(self.wanted)
        self._settled_for = None

    def request_reset(self) -> None:
        """Send one fault-reset edge to every drive that is in fault."""
        self.reset = [True] * len(self.wanted)
        self._settled_for = None

    def master_lost(self) -> None:
        """The exchange failed: stop asking for operation and forget pending resets."""
        self.request(DriveState.SWITCH_ON_DISABLED)
        self.reset = [False] * len(self.wanted)

    def commands(self, seen: list[DriveState]) -> list[int]:
        """This cycle's controlwords for drives last seen in the states `seen` (remembered as sent)."""
        if seen == self._settled_for:
            return self.sent
        reset = list(self.reset)
        commands = [self._command(drive, state, self.sent[drive]) for drive, state in enumerate(seen)]
        self._settled_for = list(seen) if commands == self.sent and self.reset == reset else None
        self.sent = commands
        return commands

    def _command(self, drive: int, seen: DriveState, previous: int) -> int:
        if seen is DriveState.FAULT:
            self.wanted[drive] = DriveState.SWITCH_ON_DISABLED
            if not self.reset[drive]:
                return Controlword.DISABLE_VOLTAGE
            command = next_controlword(seen, DriveState.SWITCH_ON_DISABLED, previous)
            self.reset[drive] = command != Controlword.FAULT_RESET
            return command
        self.reset[drive] = False
        return next_controlword(seen, self.wanted[drive], previous)



def sample_polynomial(knots: np.ndarray, coefficients: np.ndarray, final: np.ndarray, t: float) -> np.ndarray:
    """Position, velocity and acceleration (3, dof) of a piecewise polynomial at `t`: powers of the time into the
    segment times the coefficients and their derivatives' weights."""
    segments, order = coefficients.shape[0], coefficients.shape[1]
    if not segments or t >= knots[segments]:
        return np.array(final, dtype=float)
    s = min(max(int(np.searchsorted(knots[:segments + 1], t, side="right")) - 1, 0), segments - 1)
    tau = max(t - knots[s], 0.0)
    powers = np.arange(order, dtype=float)
    exponents = np.maximum(powers - np.arange(3)[:, None], 0.0)
    weights = np.array([np.ones(order), powers, powers * (powers - 1)])
    return np.asarray((weights * tau ** exponents) @ coefficients[s])

