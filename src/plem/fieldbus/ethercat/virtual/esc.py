"""One emulated EtherCAT slave controller (ESC): its registers and process RAM as the wire sees them.

The ESC answers physical reads and writes (register space 0x0000-0x0FFF, process RAM from 0x1000) and
logical ones through its FMMUs, applying what a real ESC applies on the way: read-only registers, the
SII EEPROM interface (0x0500-0x050F, 4- or 8-byte reads), sync managers (mailboxes with their full/empty
status bit 3 at 0x0805+8n, buffered process data), the distributed clock registers SOEM configures and
reads (receive-time latch at 0x0900, system time 0x0910, offset 0x0920, delay 0x0928), and the process
data watchdog (divider 0x0400, time 0x0420, status 0x0440, counter 0x0442).

Whatever goes beyond the ESC is the firmware's (`Firmware`): AL control writes, mailbox messages, the
repeat request. The firmware answers through `set_al_status`, `post_mailbox`, `set_sync_manager_active`.
Only byte-granular FMMUs are mapped (start bit 0, stop bit 7), which is what SOEM programs for byte slaves.
"""

from __future__ import annotations

import struct
from typing import NamedTuple, Protocol

from plem.fieldbus.ethercat.virtual import frames

REGISTERS = 0x1000
MEMORY_SIZE = 0x3000                   # 4 KiB registers + 8 KiB process RAM

TYPE = 0x0000
FMMU_COUNT = 0x0004
SM_COUNT = 0x0005
RAM_SIZE = 0x0006
PORT_DESCRIPTOR = 0x0007
FEATURES = 0x0008
STATION_ADDRESS = 0x0010
STATION_ALIAS = 0x0012
DL_STATUS = 0x0110
AL_CONTROL = 0x0120
AL_STATUS = 0x0130
AL_STATUS_CODE = 0x0134
PDI_CONTROL = 0x0140
WD_DIVIDER = 0x0400
WD_TIME_PDI = 0x0410
WD_TIME_PROCESS_DATA = 0x0420
WD_STATUS_PROCESS_DATA = 0x0440
WD_COUNTER_PROCESS_DATA = 0x0442
EEPROM_CONFIG = 0x0500
EEPROM_CONTROL = 0x0502
EEPROM_ADDRESS = 0x0504
EEPROM_DATA = 0x0508
FMMU0 = 0x0600
SM0 = 0x0800
DC_RECEIVE_TIME = 0x0900               # port 0..3 at +4n, 32 bits each; writing 0x0900 latches them
DC_SYSTEM_TIME = 0x0910
DC_RECEIVE_TIME_EPU = 0x0918
DC_SYSTEM_OFFSET = 0x0920
DC_SYSTEM_DELAY = 0x0928

FMMUS = 8
FMMU_SIZE = 16
SYNC_MANAGERS = 8
SM_SIZE = 8

FEATURE_DC = 0x0004
FEATURE_DC64 = 0x0008
#: DL status of a slave with port 0 (and, with a neighbour behind it, port 1) linked, ports 2/3 closed.
DL_PDI_OPERATIONAL = 0x0001
DL_LINK_PORT0 = 0x0010
DL_LINK_PORT1 = 0x0020
DL_COMMUNICATION_PORT0 = 0x0200
DL_LOOP_PORT1 = 0x0400
DL_COMMUNICATION_PORT1 = 0x0800
DL_LOOP_PORTS23 = 0x5000

#: Sync manager control byte: operation mode (bits 0-1), direction (bits 2-3), PDI event (bit 5), watchdog (bit 6).
SM_MODE = 0x03
SM_BUFFERED = 0x00
SM_MAILBOX = 0x02
SM_DIRECTION = 0x0C
SM_ECAT_READS = 0x00
SM_ECAT_WRITES = 0x04
SM_PDI_EVENT = 0x20
SM_WATCHDOG = 0x40
SM_STATUS_FULL = 0x08                  # status byte (+5): mailbox full
SM_ENABLE = 0x01                       # activate byte (+6)
SM_REPEAT = 0x02
SM_PDI_DEACTIVATE = 0x01               # PDI control byte (+7)
SM_REPEAT_ACK = 0x02

EEPROM_R64 = 0x0040
EEPROM_COMMAND_ERROR = 0x2000
EEPROM_WRITE_ENABLE_ERROR = 0x4000
EEPROM_ERRORS = 0x7800
_EEPROM_READ = 1
_EEPROM_WRITE = 2

_WD_DIVIDER_DEFAULT = 0x09C2           # 100 µs watchdog ticks
_WD_TIME_DEFAULT = 1000                # 100 ms

# What the ECAT side may write in the register space: (address, length).
_WRITABLE = ((STATION_ADDRESS, 2), (0x0100, 4), (AL_CONTROL, 2), (0x0200, 2), (0x0300, 0x14), (WD_DIVIDER, 2),
             (WD_TIME_PDI, 2), (WD_TIME_PROCESS_DATA, 2), (WD_COUNTER_PROCESS_DATA, 2), (EEPROM_CONFIG, 1),
             (EEPROM_ADDRESS, 12), (FMMU0, FMMUS * FMMU_SIZE), (DC_SYSTEM_OFFSET, 12), (0x0930, 2), (0x0934, 2),
             (0x0980, 2), (0x0990, 8), (0x09A0, 8),
             *((SM0 + SM_SIZE * n, 5) for n in range(SYNC_MANAGERS)),
             *((SM0 + SM_SIZE * n + 6, 1) for n in range(SYNC_MANAGERS)))

# Kinds of sync-manager areas in the process RAM, seen from the master.
_MAILBOX_IN = 0                        # the master writes a mailbox message
_MAILBOX_OUT = 1                       # the master reads the slave's mailbox message
_OUTPUTS = 2
_INPUTS = 3

_U16 = struct.Struct("<H")
_U32 = struct.Struct("<I")
_U64 = struct.Struct("<Q")


class Firmware(Protocol):
    """The slave stack behind the PDI: told what the master did that the ESC passes on."""

    def al_control(self, value: int) -> None:
        """The master wrote the AL control register (0x0120)."""

    def mailbox_received(self, message: bytes) -> None:
        """The master filled the mailbox-out sync manager; `message` is its whole buffer."""

    def mailbox_read(self) -> None:
        """The master read the slave's mailbox message, the mailbox-in sync manager is empty again."""

    def mailbox_repeat(self) -> None:
        """The master toggled the repeat request: the last mailbox message got lost on the way."""


class SyncManager(NamedTuple):
    """A sync manager's configuration as the master wrote it."""

    start: int
    length: int
    control: int
    enabled: bool


class _Area(NamedTuple):
    start: int
    stop: int
    number: int
    kind: int
    blocked: bool                      # deactivated by the firmware: the ESC refuses access


class _Fmmu(NamedTuple):
    start: int
    stop: int
    physical: int
    reads: bool
    writes: bool
    areas: tuple[_Area, ...]


class Esc:
    """One slave controller: memory, EEPROM, and the wire-side behaviour of its registers and sync managers."""

    def __init__(self, eeprom: bytes, *, eeprom_8byte: bool = True, clock_offset_ns: int = 0) -> None:
        self.memory = bytearray(MEMORY_SIZE)
        self.eeprom = bytearray(eeprom)
        self.firmware: Firmware | None = None
        self.station = 0
        #: When the current frame left the master, and when it reaches this ESC / comes back to port 1.
        self.frame_ns = 0
        self.forward_ns = 0
        self.return_ns: int | None = None
        self.clock_offset_ns = clock_offset_ns
        #: Set when the master completed the outputs buffer; the firmware clears it when it takes them.
        self.outputs_written = False
        self.outputs_ns = 0
        #: The process data watchdog time, 0 when no outputs sync manager has its watchdog enabled.
        self.watchdog_ns = 0
        self._watchdog_expired = False
        self._writable = bytearray(REGISTERS)
        for address, length in _WRITABLE:
            self._writable[address:address + length] = b"\x01" * length
        self._effects = bytearray(self._writable)      # writable, or a write triggers something
        self._effects[EEPROM_CONTROL + 1] = self._effects[DC_RECEIVE_TIME] = 1
        self._areas: tuple[_Area, ...] = ()
        self._fmmus: tuple[_Fmmu, ...] = ()
        memory = self.memory
        memory[TYPE] = 0x11
        memory[FMMU_COUNT] = FMMUS
        memory[SM_COUNT] = SYNC_MANAGERS
        memory[RAM_SIZE] = (MEMORY_SIZE - REGISTERS) // 1024
        memory[PORT_DESCRIPTOR] = 0x0F                         # ports 0 and 1 MII, 2 and 3 not implemented
        _U16.pack_into(memory, FEATURES, FEATURE_DC | FEATURE_DC64)
        memory[STATION_ALIAS:STATION_ALIAS + 2] = self.eeprom[8:10]
        memory[PDI_CONTROL:PDI_CONTROL + 2] = self.eeprom[0:2]
        _U16.pack_into(memory, AL_CONTROL, 1)
        _U16.pack_into(memory, AL_STATUS, 1)
        _U16.pack_into(memory, WD_DIVIDER, _WD_DIVIDER_DEFAULT)
        _U16.pack_into(memory, WD_TIME_PDI, _WD_TIME_DEFAULT)
        _U16.pack_into(memory, WD_TIME_PROCESS_DATA, _WD_TIME_DEFAULT)
        _U16.pack_into(memory, EEPROM_CONTROL, EEPROM_R64 if eeprom_8byte else 0)
        memory[WD_STATUS_PROCESS_DATA] = 1
        self.set_links(downstream=False)

    # ---- the wire side -------------------------------------------------------------------------------------

    def read(self, address: int, length: int) -> bytes | None:
        """A physical read by the master; None when the ESC refuses it (no working counter)."""
        return self._read(address, length, self._areas_at(address, address + length))

    def write(self, address: int, data: bytes | memoryview) -> bool:
        """A physical write by the master; False when the ESC refuses it (no working counter)."""
        if address < REGISTERS:
            self._write_registers(address, data)
            return True
        return self._write(address, data, self._areas_at(address, address + len(data)))

    def logical(self, command: int, address: int, data: memoryview) -> int:
        """An LRD/LWR/LRW through the FMMUs; the working counter increment (LRW: 1 read, 2 write, 3 both)."""
        end = address + len(data)
        done = 0
        writing, reading = command != frames.Command.LRD, command != frames.Command.LWR
        # Writing FMMUs come first, so they take the frame's data before reading ones replace it.
        for fmmu in self._fmmus:
            if fmmu.start < end and address < fmmu.stop:
                start, stop = max(fmmu.start, address), min(fmmu.stop, end)
                if writing and fmmu.writes and self._write(fmmu.physical + start - fmmu.start,
                                                           data[start - address:stop - address], fmmu.areas):
                    done |= 2
                if reading and fmmu.reads:
                    value = self._read(fmmu.physical + start - fmmu.start, stop - start, fmmu.areas)
                    if value is not None:
                        data[start - address:stop - address] = value
                        done |= 1
        if command == frames.Command.LRW:
            return done
        return 1 if done else 0

    def set_links(self, *, downstream: bool) -> None:
        """Port 0 faces the master; port 1 is open and linked when another slave follows this one."""
        status = DL_PDI_OPERATIONAL | DL_LINK_PORT0 | DL_COMMUNICATION_PORT0 | DL_LOOP_PORTS23
        status |= DL_LINK_PORT1 | DL_COMMUNICATION_PORT1 if downstream else DL_LOOP_PORT1
        _U16.pack_into(self.memory, DL_STATUS, status)

    # ---- the PDI side, for the firmware --------------------------------------------------------------------

    def set_al_status(self, state: int, *, error: bool, code: int) -> None:
        """Publish the AL state, error flag (0x10) and status code, as the firmware does after a request."""
        _U16.pack_into(self.memory, AL_STATUS, state | (0x10 if error else 0))
        _U16.pack_into(self.memory, AL_STATUS_CODE, code)

    def sync_manager(self, number: int) -> SyncManager:
        """The configuration the master wrote to sync manager `number`."""
        start, length, control, _status, activate = struct.unpack_from("<HHBBB", self.memory, SM0 + SM_SIZE * number)
        return SyncManager(start, length, control, bool(activate & SM_ENABLE))

    def set_sync_manager_active(self, number: int, active: bool) -> None:
        """Let the master use a sync manager's buffer, or deactivate it from the PDI side (access refused)."""
        at = SM0 + SM_SIZE * number + 7
        self.memory[at] = self.memory[at] & ~SM_PDI_DEACTIVATE | (0 if active else SM_PDI_DEACTIVATE)
        self._map()

    def post_mailbox(self, message: bytes) -> bool:
        """Put a message into the mailbox the master reads; False while it is still full or not usable."""
        for area in self._areas:
            if area.kind == _MAILBOX_OUT and not area.blocked:
                status = SM0 + SM_SIZE * area.number + 5
                if self.memory[status] & SM_STATUS_FULL or len(message) > area.stop - area.start:
                    return False
                self.memory[area.start:area.stop] = message.ljust(area.stop - area.start, b"\x00")
                self.memory[status] |= SM_STATUS_FULL
                return True
        return False

    def acknowledge_repeat(self) -> None:
        """Answer the master's repeat request: the PDI's repeat-ack bit follows the master's repeat bit."""
        for area in self._areas:
            if area.kind == _MAILBOX_OUT:
                at = SM0 + SM_SIZE * area.number
                self.memory[at + 7] = self.memory[at + 7] & ~SM_REPEAT_ACK | self.memory[at + 6] & SM_REPEAT

    def watchdog_expired(self, now_ns: int) -> bool:
        """True when the outputs sync manager's watchdog saw no complete write for longer than `watchdog_ns`."""
        expired = 0 < self.watchdog_ns < now_ns - self.outputs_ns
        if expired != self._watchdog_expired:
            self._watchdog_expired = expired
            self.memory[WD_STATUS_PROCESS_DATA] = 0 if expired else 1
            if expired:
                count = _U16.unpack_from(self.memory, WD_COUNTER_PROCESS_DATA)[0]
                _U16.pack_into(self.memory, WD_COUNTER_PROCESS_DATA, min(count + 1, 0xFFFF))
        return expired

    # ---- inside ---------------------------------------------------------------------------------------------

    def _areas_at(self, start: int, stop: int) -> tuple[_Area, ...]:
        return tuple(area for area in self._areas if area.start < stop and start < area.stop)

    def _read(self, address: int, length: int, areas: tuple[_Area, ...]) -> bytes | None:
        stop = address + length
        for area in areas:
            if area.blocked or area.kind == _MAILBOX_IN:
                return None
            if area.kind == _MAILBOX_OUT and not self.memory[SM0 + SM_SIZE * area.number + 5] & SM_STATUS_FULL:
                return None
        if address < DC_RECEIVE_TIME_EPU and stop > DC_SYSTEM_TIME:
            _U64.pack_into(self.memory, DC_SYSTEM_TIME, self._system_time())
        value = bytes(self.memory[address:min(stop, MEMORY_SIZE)]).ljust(length, b"\x00")
        for area in areas:
            if area.kind == _MAILBOX_OUT and address < area.stop <= stop:
                self.memory[SM0 + SM_SIZE * area.number + 5] &= ~SM_STATUS_FULL
                if self.firmware is not None:
                    self.firmware.mailbox_read()
        return value

    def _write(self, address: int, data: bytes | memoryview, areas: tuple[_Area, ...]) -> bool:
        stop = address + len(data)
        for area in areas:
            if area.blocked or area.kind in (_MAILBOX_OUT, _INPUTS):
                return False
            if area.kind == _MAILBOX_IN and self.memory[SM0 + SM_SIZE * area.number + 5] & SM_STATUS_FULL:
                return False
        end = min(stop, MEMORY_SIZE)
        if end > address:
            self.memory[address:end] = data[:end - address]
        for area in areas:
            if address < area.stop <= stop:
                if area.kind == _OUTPUTS:
                    self.outputs_written = True
                    self.outputs_ns = self.frame_ns
                elif self.firmware is not None:        # a mailbox message: full until the firmware took it
                    status = SM0 + SM_SIZE * area.number + 5
                    self.memory[status] |= SM_STATUS_FULL
                    self.firmware.mailbox_received(bytes(self.memory[area.start:area.stop]))
                    self.memory[status] &= ~SM_STATUS_FULL
        return True

    def _write_registers(self, address: int, data: bytes | memoryview) -> None:
        stop = min(address + len(data), REGISTERS)
        if not any(self._effects[address:stop]):
            return                                     # read-only registers only, such as 0x0910 written by FRMW
        memory, writable = self.memory, self._writable
        old_sms = bytes(memory[SM0:SM0 + SYNC_MANAGERS * SM_SIZE])
        for at in range(address, stop):
            if writable[at]:
                memory[at] = data[at - address]

        def touched(start: int, length: int) -> bool:
            return start < stop and address < start + length

        if touched(STATION_ADDRESS, 2):
            self.station = _U16.unpack_from(memory, STATION_ADDRESS)[0]
        if touched(EEPROM_CONTROL + 1, 1):
            enable = bool(data[EEPROM_CONTROL - address] & 1) if address <= EEPROM_CONTROL else False
            self._eeprom_command(data[EEPROM_CONTROL + 1 - address] & 0x07, write_enable=enable)
        if touched(FMMU0, FMMUS * FMMU_SIZE) or touched(SM0, SYNC_MANAGERS * SM_SIZE):
            self._sync_managers_written(old_sms)
        elif touched(WD_DIVIDER, 2) or touched(WD_TIME_PROCESS_DATA, 2):
            self._map()
        if touched(DC_RECEIVE_TIME, 4):
            self._latch_receive_times()
        if touched(AL_CONTROL, 2) and self.firmware is not None:
            self.firmware.al_control(_U16.unpack_from(memory, AL_CONTROL)[0])

    def _sync_managers_written(self, old: bytes) -> None:
        memory = self.memory
        repeat = False
        for number in range(SYNC_MANAGERS):
            at = SM0 + SM_SIZE * number
            before, after = old[at - SM0:at - SM0 + SM_SIZE], memory[at:at + SM_SIZE]
            if before[:5] != after[:5] or (before[6] ^ after[6]) & SM_ENABLE:
                memory[at + 5] = 0                     # a reconfigured sync manager starts empty
            elif (before[6] ^ after[6]) & SM_REPEAT and after[4] & (SM_MODE | SM_DIRECTION) == SM_MAILBOX:
                repeat = True
        self._map()
        if repeat and self.firmware is not None:
            self.firmware.mailbox_repeat()

    def _map(self) -> None:
        """Rebuild what the access paths use: sync-manager areas, FMMU table, watchdog time."""
        areas = []
        for number in range(SYNC_MANAGERS):
            start, length, control, _status, activate, pdi = struct.unpack_from("<HHBBBB", self.memory,
                                                                                SM0 + SM_SIZE * number)
            if activate & SM_ENABLE and length:
                writes = control & SM_DIRECTION == SM_ECAT_WRITES
                if control & SM_MODE == SM_MAILBOX:
                    kind = _MAILBOX_IN if writes else _MAILBOX_OUT
                else:
                    kind = _OUTPUTS if writes else _INPUTS
                areas.append(_Area(start, start + length, number, kind, bool(pdi & SM_PDI_DEACTIVATE)))
        self._areas = tuple(areas)
        divider = _U16.unpack_from(self.memory, WD_DIVIDER)[0]
        ticks = _U16.unpack_from(self.memory, WD_TIME_PROCESS_DATA)[0]
        guarded = any(area.kind == _OUTPUTS and not area.blocked
                      and self.memory[SM0 + SM_SIZE * area.number + 4] & SM_WATCHDOG for area in areas)
        self.watchdog_ns = 40 * (divider + 2) * ticks if guarded else 0
        fmmus = []
        for number in range(FMMUS):
            logical, length, _start_bit, _stop_bit, physical, _bit, kind, active = struct.unpack_from(
                "<IHBBHBBB", self.memory, FMMU0 + FMMU_SIZE * number)
            if active & 1 and length and kind & 3:
                fmmus.append(_Fmmu(logical, logical + length, physical, bool(kind & 1), bool(kind & 2),
                                   self._areas_at(physical, physical + length)))
        self._fmmus = tuple(sorted(fmmus, key=lambda fmmu: not fmmu.writes))

    def _eeprom_command(self, command: int, *, write_enable: bool) -> None:
        control = _U16.unpack_from(self.memory, EEPROM_CONTROL)[0] & ~EEPROM_ERRORS
        word = _U32.unpack_from(self.memory, EEPROM_ADDRESS)[0]
        if command == _EEPROM_READ:
            size = 8 if control & EEPROM_R64 else 4
            chunk = self.eeprom[word * 2:word * 2 + size]
            self.memory[EEPROM_DATA:EEPROM_DATA + size] = chunk.ljust(size, b"\xff")
        elif command == _EEPROM_WRITE and not write_enable:
            control |= EEPROM_WRITE_ENABLE_ERROR
        elif command == _EEPROM_WRITE and word * 2 + 2 <= len(self.eeprom):
            self.eeprom[word * 2:word * 2 + 2] = self.memory[EEPROM_DATA:EEPROM_DATA + 2]
        elif command:
            control |= EEPROM_COMMAND_ERROR
        _U16.pack_into(self.memory, EEPROM_CONTROL, control)

    def _local_time(self, at_ns: int) -> int:
        return (at_ns + self.clock_offset_ns) & 0xFFFFFFFFFFFFFFFF

    def _system_time(self) -> int:
        offset: int = _U64.unpack_from(self.memory, DC_SYSTEM_OFFSET)[0]
        return (self._local_time(self.frame_ns + self.forward_ns) + offset) & 0xFFFFFFFFFFFFFFFF

    def _latch_receive_times(self) -> None:
        arrival = self._local_time(self.frame_ns + self.forward_ns)
        back = 0 if self.return_ns is None else self._local_time(self.frame_ns + self.return_ns)
        struct.pack_into("<IIII", self.memory, DC_RECEIVE_TIME, arrival & 0xFFFFFFFF, back & 0xFFFFFFFF, 0, 0)
        _U64.pack_into(self.memory, DC_RECEIVE_TIME_EPU, arrival)
