"""CiA402 drive profile: statusword decoding, controlword sequencing and 0x603F error codes.

Pure tables and functions shared by every bus: the master side (which controlword moves a drive toward
the wanted power state) and the drive side (which state a controlword leads to), so the simulated drives
and real ones are driven by the same rules.
"""

from __future__ import annotations

from collections.abc import Mapping
from enum import IntEnum
from types import MappingProxyType

from plem.fieldbus.bus import DriveState


class Controlword(IntEnum):
    """Device-control commands of the controlword (0x6040), bits 0-3 and 7."""

    DISABLE_VOLTAGE = 0x00
    QUICK_STOP = 0x02
    SHUTDOWN = 0x06
    SWITCH_ON = 0x07
    DISABLE_OPERATION = 0x07
    ENABLE_OPERATION = 0x0F
    FAULT_RESET = 0x80


#: Names of the statusword (0x6041) bits, indexed by bit number. Bit 5 is active low in the profile
#: (cleared while a quick stop runs), hence its name; bits 12-13 are the cyclic-sync mode meanings.
STATUSWORD_BITS: tuple[str, ...] = (
    "ready to switch on", "switched on", "operation enabled", "fault", "voltage enabled",
    "quick stop not active", "switch on disabled", "warning", "manufacturer bit 8", "remote",
    "target reached", "internal limit active", "drive follows command", "following error",
    "manufacturer bit 14", "manufacturer bit 15",
)

FAULT_BIT = 0x0008
RESET_BIT = 0x0080

#: The statusword a healthy drive under fieldbus control reports in each state: the state pattern plus
#: remote (bit 9) and, once the drive is powered, voltage enabled (bit 4) and quick stop not active (bit 5).
STATUSWORD: Mapping[DriveState, int] = MappingProxyType({
    DriveState.NOT_READY_TO_SWITCH_ON: 0x0200,
    DriveState.SWITCH_ON_DISABLED: 0x0250,
    DriveState.READY_TO_SWITCH_ON: 0x0231,
    DriveState.SWITCHED_ON: 0x0233,
    DriveState.OPERATION_ENABLED: 0x0237,
    DriveState.QUICK_STOP_ACTIVE: 0x0217,
    DriveState.FAULT_REACTION_ACTIVE: 0x021F,
    DriveState.FAULT: 0x0218,
})

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
    """The power state a statusword reports; a pattern outside the profile never reads as enabled.

    Words matching no row of the CiA402 table decode as FAULT when the fault bit is set and as
    NOT_READY_TO_SWITCH_ON otherwise.
    """
    return _STATE_OF_BITS[sw & 0x6F]


def describe_statusword(sw: int) -> str:
    """The names of the bits set in a statusword, for logs and fault messages."""
    names = [name for bit, name in enumerate(STATUSWORD_BITS) if sw >> bit & 1]
    return ", ".join(names) if names else "no bits set"


_ENABLE_CHAIN = (DriveState.SWITCH_ON_DISABLED, DriveState.READY_TO_SWITCH_ON, DriveState.SWITCHED_ON,
                 DriveState.OPERATION_ENABLED)
_ENTERS = {
    DriveState.SWITCH_ON_DISABLED: Controlword.DISABLE_VOLTAGE,
    DriveState.READY_TO_SWITCH_ON: Controlword.SHUTDOWN,
    DriveState.SWITCHED_ON: Controlword.SWITCH_ON,
    DriveState.OPERATION_ENABLED: Controlword.ENABLE_OPERATION,
}


def next_controlword(state: DriveState, target: DriveState, previous: int = 0) -> int:
    """The controlword that moves a drive one step from `state` toward `target` (or keeps it there).

    `target` is one of switch on disabled, ready to switch on, switched on, operation enabled. Upward
    the drive climbs one state per command; downward it goes straight to the target. From quick stop,
    not ready or fault reaction the drive is sent to switch on disabled first. In FAULT the answer is the
    fault reset, which acts on a rising edge of bit 7: when `previous` (the last controlword sent)
    already has bit 7 set, bit 7 is cleared first and the reset goes out on the next call.
    """
    if target not in _ENTERS:
        raise ValueError(f"{target.name} is not a state a controlword can hold a drive in")
    if state is DriveState.FAULT:
        return Controlword.DISABLE_VOLTAGE if previous & RESET_BIT else Controlword.FAULT_RESET
    if state not in _ENTERS:
        return Controlword.DISABLE_VOLTAGE
    here, there = _ENABLE_CHAIN.index(state), _ENABLE_CHAIN.index(target)
    return _ENTERS[_ENABLE_CHAIN[here + 1] if here < there else target]


def drive_transition(state: DriveState, controlword: int, previous: int) -> DriveState:
    """The state a drive goes to when it receives `controlword` after `previous` (the drive's side).

    Not ready and fault reaction end by themselves (transitions 1 and 14); a fault is left only on a
    rising edge of bit 7 (transition 15). Commands not allowed in a state leave it unchanged.
    """
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


#: Specific 0x603F error codes (CiA402 / IEC 61800-7-201, with the CiA301 communication codes).
ERROR_CODES: Mapping[int, str] = MappingProxyType({
    0x0000: "no error",
    0x1000: "generic error",
    0x2110: "short circuit/earth leakage, device input side",
    0x2130: "short circuit, device input side",
    0x2211: "internal current no. 1",
    0x2213: "over current during ramp",
    0x2220: "continuous over current inside the device",
    0x2230: "short circuit/earth leakage inside the device",
    0x2310: "continuous over current",
    0x2311: "continuous over current no. 1",
    0x2320: "short circuit/earth leakage, motor side",
    0x2330: "earth leakage, motor side",
    0x2340: "short circuit, motor side",
    0x2350: "load level fault (I²t, thermal state)",
    0x3110: "mains over voltage",
    0x3120: "mains under voltage",
    0x3130: "phase failure",
    0x3210: "DC link over voltage",
    0x3220: "DC link under voltage",
    0x3230: "load error",
    0x3310: "output over voltage",
    0x4110: "excess ambient temperature",
    0x4210: "excess temperature device",
    0x4220: "too low temperature device",
    0x4310: "excess temperature drive",
    0x4320: "too low temperature drive",
    0x4410: "excess temperature supply",
    0x5110: "supply low voltage",
    0x5112: "supply +24 V low",
    0x5210: "measurement circuit",
    0x5220: "computing circuit",
    0x5410: "output stages",
    0x5420: "chopper",
    0x5440: "contacts",
    0x5441: "contact 1 (manufacturer-specific input)",
    0x5442: "contact 2 (manufacturer-specific input)",
    0x5530: "non-volatile data memory",
    0x6010: "software reset (watchdog)",
    0x6100: "internal software",
    0x6200: "user software",
    0x6310: "loss of parameters",
    0x6320: "parameter error",
    0x7110: "brake chopper",
    0x7111: "brake chopper failure",
    0x7120: "motor",
    0x7121: "motor blocked",
    0x7122: "motor error or commutation malfunction",
    0x7123: "motor tilted",
    0x7303: "resolver 1 fault",
    0x7305: "incremental encoder 1 broken",
    0x7306: "incremental encoder 2 broken",
    0x7310: "speed sensor",
    0x7320: "position sensor",
    0x7500: "communication",
    0x7510: "serial interface no. 1",
    0x8110: "process data overrun (objects lost)",
    0x8120: "bus in error passive mode",
    0x8130: "heartbeat or life guard error",
    0x8140: "recovered from bus off",
    0x8210: "PDO not processed due to length error",
    0x8220: "PDO length exceeded",
    0x8311: "excess torque",
    0x8312: "difficult start up",
    0x8313: "standstill torque",
    0x8321: "insufficient torque",
    0x8331: "torque fault",
    0x8400: "velocity speed controller",
    0x8500: "position controller",
    0x8611: "following error",
    0x8612: "reference limit",
    0x8700: "sync controller",
    0x9000: "external error",
    0xA000: "EtherCAT state change PRE-OP to SAFE-OP failed",
    0xA001: "EtherCAT state change SAFE-OP to OP failed",
    0xF001: "deceleration",
    0xF002: "sub-synchronous run",
    0xF003: "stroke operation",
    0xF004: "control",
})

# Meaning of the 0xXYxx ranges, then of the 0xXxxx classes, for codes the table does not list.
_RANGES = MappingProxyType({
    0x21: "current, device input side", 0x22: "current inside the device", 0x23: "current, device output side",
    0x31: "mains voltage", 0x32: "voltage inside the device", 0x33: "output voltage",
    0x41: "ambient temperature", 0x42: "device temperature", 0x43: "drive temperature",
    0x44: "supply temperature",
    0x51: "device hardware, supply", 0x52: "device hardware, control", 0x53: "device hardware, operating unit",
    0x54: "device hardware, power section", 0x55: "device hardware, data storage",
    0x61: "internal software", 0x62: "user software", 0x63: "data set",
    0x71: "power (motor, brake chopper)", 0x72: "measurement circuit", 0x73: "sensor (encoder, resolver)",
    0x74: "computation circuit", 0x75: "communication", 0x76: "data storage",
    0x81: "communication monitoring", 0x82: "protocol error", 0x83: "torque control",
    0x84: "velocity speed controller", 0x85: "position controller", 0x86: "positioning controller",
    0x87: "sync controller", 0x88: "winding controller", 0x89: "process data monitoring", 0x8A: "control",
    0xF0: "additional functions",
})
_CLASSES = MappingProxyType({
    0x1: "generic error", 0x2: "current", 0x3: "voltage", 0x4: "temperature", 0x5: "device hardware",
    0x6: "device software", 0x7: "additional modules", 0x8: "monitoring", 0x9: "external error",
    0xF: "additional functions",
})


def describe_error_code(code: int) -> str:
    """A 0x603F error code with its meaning: the specific one when known, else its range or class."""
    text = f"0x{code:04X}"
    if code in ERROR_CODES:
        return f"{text} {ERROR_CODES[code]}"
    if code >> 8 == 0xFF:
        return f"{text} manufacturer-specific"
    if code >> 8 in _RANGES:
        return f"{text} {_RANGES[code >> 8]} (0x{code >> 8:02X}xx)"
    if code >> 12 in _CLASSES:
        return f"{text} {_CLASSES[code >> 12]} (0x{code >> 12:X}xxx)"
    return f"{text} unknown error code"


def describe_drive_fault(joint: str, statusword: int, error_code: int) -> str:
    """One line naming the joint, the decoded error code and the statusword bits, for events and errors."""
    return (f"{joint} drive fault: {describe_error_code(error_code)} "
            f"(statusword 0x{statusword:04X}: {describe_statusword(statusword)})")


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

