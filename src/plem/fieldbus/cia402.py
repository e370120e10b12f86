"""CiA402 drive profile: statusword decoding, controlword sequencing and 0x603F error codes.

The state machines are the compiled core's (plem.control.csrc/cia402.c), which every bus uses: the master
side (which controlword moves a drive toward the wanted power state) and the drive side (which state a
controlword leads to), so the simulated drives and real ones are driven by the same rules. This module gives
them their Python names and keeps the texts: bit names and 0x603F error codes.
"""

from __future__ import annotations

from collections.abc import Mapping
from enum import IntEnum
from types import MappingProxyType

import numpy as np

from plem.control import compiled
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

#: The statusword a healthy drive under fieldbus control reports in each state: the state pattern plus
#: remote (bit 9) and, once the drive is powered, voltage enabled (bit 4) and quick stop not active (bit 5).
STATUSWORD: Mapping[DriveState, int] = MappingProxyType({state: compiled.core.statusword_of(state)
                                                         for state in DriveState})
#: The states a controlword can hold a drive in (the way up to operation enabled).
HOLDABLE = frozenset({DriveState.SWITCH_ON_DISABLED, DriveState.READY_TO_SWITCH_ON, DriveState.SWITCHED_ON,
                      DriveState.OPERATION_ENABLED})


def decode_statusword(sw: int) -> DriveState:
    """The power state a statusword reports; a pattern outside the profile never reads as enabled.

    Words matching no row of the CiA402 table decode as FAULT when the fault bit is set and as
    NOT_READY_TO_SWITCH_ON otherwise.
    """
    return DriveState(compiled.core.decode_statusword(sw & 0xFFFF))


def describe_statusword(sw: int) -> str:
    """The names of the bits set in a statusword, for logs and fault messages."""
    names = [name for bit, name in enumerate(STATUSWORD_BITS) if sw >> bit & 1]
    return ", ".join(names) if names else "no bits set"


def next_controlword(state: DriveState, target: DriveState, previous: int = 0) -> int:
    """The controlword that moves a drive one step from `state` toward `target` (or keeps it there).

    `target` is one of switch on disabled, ready to switch on, switched on, operation enabled. Upward
    the drive climbs one state per command; downward it goes straight to the target. From quick stop,
    not ready or fault reaction the drive is sent to switch on disabled first. In FAULT the answer is the
    fault reset, which acts on a rising edge of bit 7: when `previous` (the last controlword sent)
    already has bit 7 set, bit 7 is cleared first and the reset goes out on the next call.
    """
    if target not in HOLDABLE:
        raise ValueError(f"{target.name} is not a state a controlword can hold a drive in")
    return int(compiled.core.next_controlword(state, target, previous & 0xFFFF))


def drive_transition(state: DriveState, controlword: int, previous: int) -> DriveState:
    """The state a drive goes to when it receives `controlword` after `previous` (the drive's side).

    Not ready and fault reaction end by themselves (transitions 1 and 14); a fault is left only on a
    rising edge of bit 7 (transition 15). Commands not allowed in a state leave it unchanged.
    """
    return DriveState(compiled.core.drive_transition(state, controlword & 0xFFFF, previous & 0xFFFF))


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
    The sequencer is the compiled core's (`plem_power`), the one every bus's master uses.
    """

    def __init__(self, dof: int) -> None:
        self._power = compiled.new(compiled.POWER)
        compiled.core.power_init(self._power, dof)
        self._seen = np.zeros(dof, dtype=np.int32)
        self._out = np.zeros(dof, dtype=np.uint16)

    def request(self, state: DriveState) -> None:
        """Ask every drive for `state`; it is reached over the next cycles."""
        compiled.core.power_request(self._power, state)

    def request_reset(self) -> None:
        """Send one fault-reset edge to every drive that is in fault."""
        compiled.core.power_request_reset(self._power)

    def master_lost(self) -> None:
        """The exchange failed: stop asking for operation and forget pending resets."""
        compiled.core.power_master_lost(self._power)

    def commands(self, seen: list[DriveState]) -> np.ndarray:
        """This cycle's controlwords for drives last seen in the states `seen` (remembered as sent)."""
        self._seen[:] = seen
        compiled.core.power_commands(self._power, self._seen, self._out)
        return self._out
