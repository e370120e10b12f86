"""The firmware of an emulated CiA402 drive: AL state machine, CoE SDO server, object dictionary, process data.

It sits behind one `Esc` and does what a slave stack on the drive's microcontroller does:

- AL states INIT → PREOP (mailbox sync managers checked, 0x0016) → SAFEOP (process data layout from
  0x1C12/0x1C13 and the mapping objects, checked against the SM2/SM3 lengths, 0x001D/0x001E) → OP. OP is
  entered with the first outputs after the request when the sync-manager watchdog is on, and refused with
  0x001B if none arrive within the watchdog time. Errors set flag 0x10 in AL status until the master
  acknowledges them (bit 4 of AL control); invalid requests answer 0x0011/0x0012/0x0013.
- An SDO server (expedited and normal upload/download) over CoE, with the abort codes of ETG.1000.6, and
  SDO Information (CoE service 8: the object list, each object's and each entry's description), so that
  `slaveinfo <if> -sdo` lists the dictionary; other CoE services get mailbox error 0x0004 (service not supported).
- Process data: outputs are taken from SM2 into the application's arrays in OP, inputs are packed into
  SM3 from them in SAFEOP and OP, by a `struct` layout precomputed when SAFEOP is entered.

The drive's own PDO mapping differs from plem's table (`DEFAULT_MAPPING`), so a master that does not
write the assignment in PREOP gets a different process image. `missing_objects` leaves objects out of the
dictionary, as drives that implement fewer objects do (many have no rated torque 0x6076).
"""

from __future__ import annotations

import functools
import operator
import struct
from collections import deque
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from plem.fieldbus.ethercat import objects
from plem.fieldbus.ethercat.virtual import esc as escmod
from plem.fieldbus.ethercat.virtual.application import DriveApplication
from plem.fieldbus.ethercat.virtual.sii import (
    SM_INPUTS,
    SM_MAILBOX_IN,
    SM_MAILBOX_OUT,
    SM_OUTPUTS,
    SlaveIdentity,
    SyncManagerSpec,
    build_image,
)

INIT = 0x01
PREOP = 0x02
BOOT = 0x03
SAFEOP = 0x04
OP = 0x08
ERROR_FLAG = 0x10

#: AL status codes (0x0134).
INVALID_STATE_CHANGE = 0x0011
UNKNOWN_STATE = 0x0012
BOOTSTRAP_NOT_SUPPORTED = 0x0013
INVALID_MAILBOX_CONFIGURATION = 0x0016
SYNC_MANAGER_WATCHDOG = 0x001B
INVALID_OUTPUT_CONFIGURATION = 0x001D
INVALID_INPUT_CONFIGURATION = 0x001E

#: SDO abort codes.
COMMAND_SPECIFIER_INVALID = 0x05040001
UNSUPPORTED_ACCESS = 0x06010000
READ_ONLY = 0x06010002
SUBINDEX0_NOT_ZERO = 0x06010003
OBJECT_DOES_NOT_EXIST = 0x06020000
CANNOT_BE_MAPPED = 0x06040041
LENGTH_MISMATCH = 0x06070010
SUBINDEX_DOES_NOT_EXIST = 0x06090011
VALUE_RANGE_EXCEEDED = 0x06090030
WRONG_STATE = 0x08000022

#: Mailbox types and errors (mailbox error detail codes of ETG.1000.6).
MAILBOX_ERROR = 0x00
MAILBOX_COE = 0x03
PROTOCOL_NOT_SUPPORTED = 0x0002
SERVICE_NOT_SUPPORTED = 0x0004
SIZE_TOO_SHORT = 0x0006
SIZE_INCONSISTENT = 0x0008
#: CoE services.
SDO_REQUEST = 2
SDO_RESPONSE = 3
SDO_INFORMATION = 8
#: SDO Information opcodes (ETG.1000.6), and the flag of a fragment that more fragments follow.
GET_OD_LIST, OD_LIST, GET_OD, OD, GET_OE, OE, SDO_INFO_ERROR = 1, 2, 3, 4, 5, 6, 7
INCOMPLETE = 0x80
#: Object list types of Get OD List: counts per type, all, RxPDO-mappable, TxPDO-mappable, backup, settings.
LIST_COUNTS, LIST_ALL, LIST_RX_MAPPABLE, LIST_TX_MAPPABLE, LIST_BACKUP, LIST_SETTINGS = range(6)
#: Object codes and data types (CiA 301) of the object descriptions.
VAR, ARRAY, RECORD = 0x07, 0x08, 0x09
DATA_TYPES = {"b": 0x0002, "h": 0x0003, "i": 0x0004, "B": 0x0005, "H": 0x0006, "I": 0x0007, "s": 0x0009}
PDO_MAPPING_TYPE, IDENTITY_TYPE = 0x0021, 0x0023
#: Object access bits of an entry description: read in PREOP/SAFEOP/OP, write in PREOP/SAFEOP/OP, PDO-mappable.
READ_ALL, WRITE_PREOP, WRITE_ALL, RX_MAPPABLE, TX_MAPPABLE = 0x0007, 0x0008, 0x0038, 0x0040, 0x0080
IDENTITY_ENTRIES = ("Vendor ID", "Product code", "Revision number", "Serial number")

#: Modes of operation the drives offer (0x6502): cyclic synchronous position, velocity and torque.
SUPPORTED_MODES = 0x0380
MAILBOX_SIZE = 128
RX_PDOS = (objects.RX_PDO, objects.RX_PDO + 1)
TX_PDOS = (objects.TX_PDO, objects.TX_PDO + 1)
MAX_PDO_ENTRIES = 8

_TX_MAPPABLE = objects.TX_ENTRIES + (objects.DIGITAL_INPUTS,)
_ENTRY = {entry.name: entry for entry in objects.RX_ENTRIES + _TX_MAPPABLE}
#: The drive's own mapping: 0x1600 lacks the velocity and torque offsets, 0x1A00 the actual torque.
DEFAULT_MAPPING: dict[int, tuple[objects.PdoEntry, ...]] = {
    RX_PDOS[0]: tuple(_ENTRY[name] for name in ("controlword", "target_position", "mode")),
    RX_PDOS[1]: tuple(_ENTRY[name] for name in ("velocity_offset", "torque_offset")),
    TX_PDOS[0]: tuple(_ENTRY[name] for name in ("statusword", "position_actual", "velocity_actual", "error_code",
                                                 "mode_display")),
    TX_PDOS[1]: (_ENTRY["torque_actual"],),
}
DEFAULT_ASSIGNMENT = {objects.RX_ASSIGN: (RX_PDOS[0],), objects.TX_ASSIGN: (TX_PDOS[0],)}

_MAPPABLE = {**{pdo: {e.mapping: e for e in objects.RX_ENTRIES} for pdo in RX_PDOS},
             **{pdo: {e.mapping: e for e in _TX_MAPPABLE} for pdo in TX_PDOS}}
_ASSIGNABLE = {objects.RX_ASSIGN: RX_PDOS, objects.TX_ASSIGN: TX_PDOS}

#: Sync managers 0-3 and their defaults, as the SII announces them (each raises a PDI event when accessed).
SYNC_MANAGERS = (
    SyncManagerSpec(0x1000, MAILBOX_SIZE, escmod.SM_MAILBOX | escmod.SM_ECAT_WRITES | escmod.SM_PDI_EVENT,
                    SM_MAILBOX_OUT),
    SyncManagerSpec(0x1080, MAILBOX_SIZE, escmod.SM_MAILBOX | escmod.SM_ECAT_READS | escmod.SM_PDI_EVENT,
                    SM_MAILBOX_IN),
    SyncManagerSpec(0x1100, objects.pdo_bytes(DEFAULT_MAPPING[RX_PDOS[0]]),
                    escmod.SM_BUFFERED | escmod.SM_ECAT_WRITES | escmod.SM_PDI_EVENT | escmod.SM_WATCHDOG, SM_OUTPUTS),
    SyncManagerSpec(0x1180, objects.pdo_bytes(DEFAULT_MAPPING[TX_PDOS[0]]),
                    escmod.SM_BUFFERED | escmod.SM_ECAT_READS | escmod.SM_PDI_EVENT, SM_INPUTS),
)


class _Abort(Exception):
    """An SDO request refused with an abort code."""

    def __init__(self, code: int) -> None:
        super().__init__(f"SDO abort {code:#010x}")
        self.code = code


class _Variable(NamedTuple):
    """One object dictionary entry: its struct code ('s' for a visible string), reader and writer (None: read-only)."""

    code: str
    get: Callable[[], int | str]
    set: Callable[[int], None] | None = None

    def encode(self) -> bytes:
        value = self.get()
        return value.encode("ascii") if isinstance(value, str) else struct.pack("<" + self.code, value)

    @property
    def bits(self) -> int:
        """Its size in bits, as an entry description gives it."""
        return 8 * len(self.encode())


class _Layout(NamedTuple):
    """The process image of one slave: SM2/SM3 addresses, struct formats, and the application arrays they map."""

    outputs_at: int
    outputs: struct.Struct
    output_arrays: Callable[[DriveApplication], tuple[np.ndarray, ...]]
    inputs_at: int
    inputs: struct.Struct
    input_arrays: Callable[[DriveApplication], tuple[np.ndarray, ...]]

    @classmethod
    def of(cls, outputs_at: int, outputs: tuple[objects.PdoEntry, ...],
           inputs_at: int, inputs: tuple[objects.PdoEntry, ...]) -> _Layout:
        return cls(outputs_at, _format(outputs), _arrays(outputs), inputs_at, _format(inputs), _arrays(inputs))


def _format(entries: tuple[objects.PdoEntry, ...]) -> struct.Struct:
    """The packed little-endian struct of `entries`, in order."""
    return struct.Struct("<" + "".join(_struct_code(e.dtype) for e in entries))


def _arrays(entries: tuple[objects.PdoEntry, ...]) -> Callable[[DriveApplication], tuple[np.ndarray, ...]]:
    """The application's arrays of `entries`, fetched in one call each cycle (so arrays may be replaced)."""
    names = tuple(e.name for e in entries)
    if len(names) > 1:
        return operator.attrgetter(*names)
    return lambda app: tuple(getattr(app, name) for name in names)


def _struct_code(dtype: str) -> str:
    """The struct format character of a little-endian integer numpy dtype."""
    kind = np.dtype(dtype)
    code = {1: "b", 2: "h", 4: "i", 8: "q"}[kind.itemsize]
    return code.upper() if kind.kind == "u" else code


def _constant(value: int | str) -> Callable[[], int | str]:
    """The reader of an object that never changes."""
    return lambda: value


_NO_PROCESS_DATA = _Layout.of(0, (), 0, ())


class DriveStack:
    """The firmware of one emulated drive (`drive` is its element in the application's arrays), behind `esc`."""

    def __init__(self, identity: SlaveIdentity, application: DriveApplication, drive: int, *,
                 clock_offset_ns: int = 0, missing_objects: frozenset[int] = frozenset()) -> None:
        self.identity = identity
        self.application = application
        self.drive = drive
        self.esc = escmod.Esc(build_image(identity, SYNC_MANAGERS), clock_offset_ns=clock_offset_ns)
        self.esc.firmware = self
        self.state = INIT
        self.error = False
        self.status_code = 0
        self._op_requested_ns: int | None = None
        self._layout = _NO_PROCESS_DATA
        self._outbox: deque[bytes] = deque()
        self._last_sent: bytes | None = None
        self._last_request_counter = 0
        self._counter = 0
        self._pdo_entries = {index: [0] * MAX_PDO_ENTRIES for index in (*_ASSIGNABLE, *_MAPPABLE)}
        self._pdo_counts = dict.fromkeys(self._pdo_entries, 0)
        for index, pdos in DEFAULT_ASSIGNMENT.items():
            self._pdo_entries[index][:len(pdos)] = pdos
            self._pdo_counts[index] = len(pdos)
        for pdo, entries in DEFAULT_MAPPING.items():
            self._pdo_entries[pdo][:len(entries)] = [e.mapping for e in entries]
            self._pdo_counts[pdo] = len(entries)
        self._objects = {index: entries for index, entries in self._dictionary().items()
                         if index not in missing_objects}
        self._enter(INIT)

    # ---- AL state machine ------------------------------------------------------------------------------------

    def al_control(self, value: int) -> None:
        """The master asked for a state (bits 0-3), maybe acknowledging an error (bit 4)."""
        requested = value & 0x0F
        if requested != OP:
            self._op_requested_ns = None
        if value & ERROR_FLAG:
            self.error, self.status_code = False, 0
        elif self.error and requested >= self.state:
            return                                     # an error is acknowledged before the slave goes up again
        if requested != self.state and self._op_requested_ns is None:
            code = self._change(requested)
            if code:
                self.error, self.status_code = True, code
        self._publish()

    def _change(self, requested: int) -> int:
        """Carry out a state change; the AL status code when it is refused."""
        if requested not in (INIT, PREOP, BOOT, SAFEOP, OP):
            return UNKNOWN_STATE
        if requested == BOOT:
            return BOOTSTRAP_NOT_SUPPORTED if self.state == INIT else INVALID_STATE_CHANGE
        if requested < self.state:
            self._enter(requested)
            return 0
        if (self.state, requested) == (INIT, PREOP):
            return self._start_mailbox()
        if (self.state, requested) == (PREOP, SAFEOP):
            return self._start_process_data()
        if (self.state, requested) == (SAFEOP, OP):
            if self._layout.outputs.size and self.esc.watchdog_ns:
                self._op_requested_ns = self.esc.frame_ns          # OP comes with the first outputs
            else:
                self._enter(OP)
            return 0
        return INVALID_STATE_CHANGE

    def _enter(self, state: int) -> None:
        left = self.state
        self.state = state
        mailbox, process_data = state != INIT, state in (SAFEOP, OP)
        for number, active in ((0, mailbox), (1, mailbox), (2, process_data), (3, process_data)):
            self.esc.set_sync_manager_active(number, active)
        if not mailbox:
            self._outbox.clear()
            self._last_sent = None
            self._last_request_counter = 0
        if not process_data:
            self._layout = _NO_PROCESS_DATA
        if left == OP and state != OP:
            self.application.communication_lost(self.drive)

    def _fault(self, code: int, state: int) -> None:
        self.error, self.status_code = True, code
        self._op_requested_ns = None
        self._enter(state)
        self._publish()

    def _publish(self) -> None:
        self.esc.set_al_status(self.state, error=self.error, code=self.status_code)

    def _start_mailbox(self) -> int:
        for number in (0, 1):
            spec, sm = SYNC_MANAGERS[number], self.esc.sync_manager(number)
            mode = escmod.SM_MODE | escmod.SM_DIRECTION
            if not (sm.enabled and sm.start == spec.start and sm.length == spec.length
                    and sm.control & mode == spec.control & mode):
                return INVALID_MAILBOX_CONFIGURATION
        self._enter(PREOP)
        return 0

    def _start_process_data(self) -> int:
        outputs, inputs = self._mapped(objects.RX_ASSIGN), self._mapped(objects.TX_ASSIGN)
        if not self._sync_manager_fits(2, objects.pdo_bytes(outputs), escmod.SM_ECAT_WRITES):
            return INVALID_OUTPUT_CONFIGURATION
        if not self._sync_manager_fits(3, objects.pdo_bytes(inputs), escmod.SM_ECAT_READS):
            return INVALID_INPUT_CONFIGURATION
        self._enter(SAFEOP)
        self._layout = _Layout.of(self.esc.sync_manager(2).start, outputs, self.esc.sync_manager(3).start, inputs)
        self.esc.outputs_written = False
        self.give_inputs()
        return 0

    def _sync_manager_fits(self, number: int, size: int, direction: int) -> bool:
        sm = self.esc.sync_manager(number)
        if not size:
            return not sm.enabled or not sm.length
        return (sm.enabled and sm.length == size
                and sm.control & (escmod.SM_MODE | escmod.SM_DIRECTION) == escmod.SM_BUFFERED | direction
                and sm.start >= escmod.REGISTERS and sm.start + size <= escmod.MEMORY_SIZE)

    def _mapped(self, assignment: int) -> tuple[objects.PdoEntry, ...]:
        return tuple(_MAPPABLE[pdo][mapping]
                     for pdo in self._pdo_entries[assignment][:self._pdo_counts[assignment]]
                     for mapping in self._pdo_entries[pdo][:self._pdo_counts[pdo]])

    # ---- cycle -----------------------------------------------------------------------------------------------

    def take_outputs(self) -> None:
        """After a process-data frame: a completed SM2 write enters a pending OP and, in OP, reaches the arrays."""
        esc = self.esc
        if not esc.outputs_written:
            return
        esc.outputs_written = False
        if self._op_requested_ns is not None:
            self._op_requested_ns = None
            self._enter(OP)
            self._publish()
        layout = self._layout
        if self.state == OP and layout.outputs.size:
            drive = self.drive
            for array, value in zip(layout.output_arrays(self.application),
                                    layout.outputs.unpack_from(esc.memory, layout.outputs_at), strict=True):
                array[drive] = value

    def give_inputs(self) -> None:
        """In SAFEOP and OP, pack the drive's inputs into SM3 for the next frame to read."""
        layout = self._layout
        if layout.inputs.size:
            drive = self.drive
            layout.inputs.pack_into(self.esc.memory, layout.inputs_at,
                                    *[array[drive] for array in layout.input_arrays(self.application)])

    def poll(self, now_ns: int) -> None:
        """Check the sync-manager watchdog in OP, and the wait for the first outputs of a requested OP."""
        if (self.state == OP and self.esc.watchdog_expired(now_ns)
                or self._op_requested_ns is not None and now_ns - self._op_requested_ns > self.esc.watchdog_ns):
            self._fault(SYNC_MANAGER_WATCHDOG, SAFEOP)

    # ---- mailbox ---------------------------------------------------------------------------------------------

    def mailbox_received(self, message: bytes) -> None:
        """Serve one mailbox message: CoE SDO and SDO Information requests; anything else gets a mailbox error."""
        length, _address, _channel, kind = struct.unpack_from("<HHBB", message)
        counter = kind >> 4 & 0x07
        if counter and counter == self._last_request_counter:
            return                                     # the master repeated a message it already sent
        self._last_request_counter = counter
        service = struct.unpack_from("<H", message, 6)[0] >> 12 if length >= 2 else None
        if length > len(message) - 6:
            self._mailbox_error(SIZE_INCONSISTENT)
        elif kind & 0x0F != MAILBOX_COE:
            self._mailbox_error(PROTOCOL_NOT_SUPPORTED)
        elif service not in (SDO_REQUEST, SDO_INFORMATION):
            self._mailbox_error(SIZE_TOO_SHORT if service is None else SERVICE_NOT_SUPPORTED)
        elif length < (10 if service == SDO_REQUEST else 8):
            self._mailbox_error(SIZE_TOO_SHORT)
        elif service == SDO_INFORMATION:
            for fragment in self._sdo_information(message[6:6 + length]):
                self._send(MAILBOX_COE, fragment)
        else:
            answer = self._sdo(message[6:6 + length])
            if answer is not None:
                self._send(MAILBOX_COE, answer)

    def mailbox_read(self) -> None:
        """The master took the last message: post the next one."""
        self._flush()

    def mailbox_repeat(self) -> None:
        """The master lost the last message: post it again and acknowledge the repeat request."""
        if self._last_sent is not None:
            self.esc.post_mailbox(self._last_sent)
        self.esc.acknowledge_repeat()

    def _mailbox_error(self, detail: int) -> None:
        self._send(MAILBOX_ERROR, struct.pack("<HH", 0x0001, detail))

    def _send(self, kind: int, body: bytes) -> None:
        self._counter = self._counter % 7 + 1
        self._outbox.append(struct.pack("<HHBB", len(body), 0, 0, kind | self._counter << 4) + body)
        self._flush()

    def _flush(self) -> None:
        while self._outbox and self.esc.post_mailbox(self._outbox[0]):
            self._last_sent = self._outbox.popleft()

    # ---- SDO server ------------------------------------------------------------------------------------------

    def _sdo(self, request: bytes) -> bytes | None:
        command = request[2]
        index, subindex = struct.unpack_from("<HB", request, 3)
        try:
            if command >> 5 == 2:
                return self._upload(command, index, subindex)
            if command >> 5 == 1:
                return self._download(command, index, subindex, request)
            if command >> 5 == 4:
                return None                            # the master aborted a transfer: nothing to answer
            raise _Abort(COMMAND_SPECIFIER_INVALID)
        except _Abort as abort:
            return struct.pack("<HBHBI", SDO_REQUEST << 12, 0x80, index, subindex, abort.code)

    def _variable(self, index: int, subindex: int) -> _Variable:
        entries = self._objects.get(index)
        if entries is None:
            raise _Abort(OBJECT_DOES_NOT_EXIST)
        if subindex not in entries:
            raise _Abort(SUBINDEX_DOES_NOT_EXIST)
        return entries[subindex]

    def _upload(self, command: int, index: int, subindex: int) -> bytes:
        if command & 0x10:
            raise _Abort(UNSUPPORTED_ACCESS)
        value = self._variable(index, subindex).encode()
        if len(value) <= 4:
            return struct.pack("<HBHB", SDO_RESPONSE << 12, 0x43 | (4 - len(value)) << 2, index, subindex) \
                + value.ljust(4, b"\x00")
        return struct.pack("<HBHBI", SDO_RESPONSE << 12, 0x41, index, subindex, len(value)) + value

    def _download(self, command: int, index: int, subindex: int, request: bytes) -> bytes:
        if command & 0x10:
            raise _Abort(UNSUPPORTED_ACCESS)
        variable = self._variable(index, subindex)
        if variable.set is None:
            raise _Abort(READ_ONLY)
        wanted = struct.calcsize("<" + variable.code)
        if command & 0x02:
            size = 4 - (command >> 2 & 0x03) if command & 0x01 else wanted
            data = request[6:6 + size]
        else:
            (size,) = struct.unpack_from("<I", request, 6)
            data = request[10:10 + size]
        if size != wanted or len(data) != wanted:
            raise _Abort(LENGTH_MISMATCH)
        variable.set(struct.unpack("<" + variable.code, data)[0])
        return struct.pack("<HBHBI", SDO_RESPONSE << 12, 0x60, index, subindex, 0)

    # ---- SDO Information --------------------------------------------------------------------------------------

    def _sdo_information(self, request: bytes) -> list[bytes]:
        """The answer to one SDO Information request, in as many mailbox messages as it takes."""
        opcode = request[2] & 0x7F
        index = struct.unpack_from("<H", request, 6)[0]
        try:
            if opcode == GET_OD_LIST:
                return _fragments(OD_LIST, struct.pack("<H", index) + self._object_list(index))
            if opcode == GET_OD:
                return _fragments(OD, self._object_description(index))
            if opcode == GET_OE and len(request) >= 9:
                return _fragments(OE, self._entry_description(index, request[8], request[9] if len(request) > 9
                                                              else 0))
            raise _Abort(COMMAND_SPECIFIER_INVALID)
        except _Abort as abort:
            return _fragments(SDO_INFO_ERROR, struct.pack("<I", abort.code))

    def _object_list(self, list_type: int) -> bytes:
        """Get OD List: the indices of one list type, or (type 0) how many objects each type has."""
        lists = {LIST_ALL: sorted(self._objects), LIST_BACKUP: [], LIST_SETTINGS: [],
                 LIST_RX_MAPPABLE: sorted({e.index for e in objects.RX_ENTRIES} & set(self._objects)),
                 LIST_TX_MAPPABLE: sorted({e.index for e in objects.TX_ENTRIES} & set(self._objects))}
        if list_type == LIST_COUNTS:
            return struct.pack("<5H", *(len(lists[kind]) for kind in range(LIST_ALL, LIST_SETTINGS + 1)))
        if list_type not in lists:
            raise _Abort(VALUE_RANGE_EXCEEDED)
        return struct.pack(f"<{len(lists[list_type])}H", *lists[list_type])

    def _object_description(self, index: int) -> bytes:
        """Get OD: an object's data type, highest subindex, object code and name."""
        entries = self._objects.get(index)
        if entries is None:
            raise _Abort(OBJECT_DOES_NOT_EXIST)
        code, data_type = self._object_kind(index, entries)
        name = objects.NAMES.get(index, f"Object 0x{index:04X}")
        return struct.pack("<HHBB", index, data_type, max(entries), code) + name.encode("ascii")

    @staticmethod
    def _object_kind(index: int, entries: dict[int, _Variable]) -> tuple[int, int]:
        """The object code and data type of an object: a variable, an array of one type, or a record."""
        if len(entries) == 1:
            return VAR, DATA_TYPES[entries[0].code]
        if index == objects.IDENTITY:
            return RECORD, IDENTITY_TYPE
        if index in _MAPPABLE:
            return RECORD, PDO_MAPPING_TYPE
        return ARRAY, DATA_TYPES[entries[1].code]

    def _entry_description(self, index: int, subindex: int, value_info: int) -> bytes:
        """Get OE: one entry's data type, size, access rights and name (no unit, default or limits)."""
        variable = self._variable(index, subindex)
        return struct.pack("<HBBHHH", index, subindex, value_info & 0x07, DATA_TYPES[variable.code], variable.bits,
                           self._access(index, subindex, variable)) \
            + _entry_name(index, subindex, len(self._objects[index]) == 1).encode("ascii")

    @staticmethod
    def _access(index: int, subindex: int, variable: _Variable) -> int:
        """The object access bits of an entry: who may write it when, and whether it can be mapped."""
        entry = objects.ENTRIES_BY_OBJECT.get((index, subindex))
        if entry is not None:
            return READ_ALL | (WRITE_PREOP | WRITE_ALL | RX_MAPPABLE if entry in objects.RX_ENTRIES else TX_MAPPABLE)
        if variable.set is None:
            return READ_ALL
        return READ_ALL | WRITE_PREOP

    # ---- object dictionary -----------------------------------------------------------------------------------

    def _dictionary(self) -> dict[int, dict[int, _Variable]]:
        identity = self.identity

        def constants(code: str, *values: int) -> dict[int, _Variable]:
            record = {0: _Variable("B", _constant(len(values)))}
            record.update({i: _Variable(code, _constant(value)) for i, value in enumerate(values, 1)})
            return record

        dictionary = {
            objects.DEVICE_TYPE: {0: _Variable("I", _constant(objects.CIA402_DEVICE_TYPE))},
            objects.DEVICE_NAME: {0: _Variable("s", _constant(identity.name))},
            objects.IDENTITY: constants("I", identity.vendor_id, identity.product_code, identity.revision,
                                        identity.serial),
            objects.SM_COMM_TYPE: constants("B", *(sm.use for sm in SYNC_MANAGERS)),
            objects.RATED_TORQUE: {0: _Variable("I", self._array_reader("rated_torque"))},
            objects.SUPPORTED_MODES: {0: _Variable("I", _constant(SUPPORTED_MODES))},
        }
        for index, entries in self._pdo_entries.items():
            code = "H" if index in _ASSIGNABLE else "I"
            record = {0: _Variable("B", functools.partial(self._pdo_counts.__getitem__, index),
                                   self._pdo_count_writer(index))}
            record.update({sub: _Variable(code, functools.partial(entries.__getitem__, sub - 1),
                                          self._pdo_entry_writer(index, sub))
                           for sub in range(1, MAX_PDO_ENTRIES + 1)})
            dictionary[index] = record
        for entry in objects.RX_ENTRIES + _TX_MAPPABLE:
            writer = self._array_writer(entry.name) if entry in objects.RX_ENTRIES else None
            dictionary.setdefault(entry.index, {})[entry.subindex] = _Variable(
                _struct_code(entry.dtype), self._array_reader(entry.name), writer)
        return dictionary

    def _array_reader(self, name: str) -> Callable[[], int]:
        def read() -> int:
            return int(getattr(self.application, name)[self.drive])
        return read

    def _array_writer(self, name: str) -> Callable[[int], None]:
        def write(value: int) -> None:
            getattr(self.application, name)[self.drive] = value
        return write

    def _require_preop(self) -> None:
        if self.state != PREOP:
            raise _Abort(WRONG_STATE)

    def _pdo_count_writer(self, index: int) -> Callable[[int], None]:
        def write(count: int) -> None:
            self._require_preop()
            if count > MAX_PDO_ENTRIES or 0 in self._pdo_entries[index][:count]:
                raise _Abort(VALUE_RANGE_EXCEEDED)
            self._pdo_counts[index] = count
        return write

    def _pdo_entry_writer(self, index: int, subindex: int) -> Callable[[int], None]:
        def write(value: int) -> None:
            self._require_preop()
            if self._pdo_counts[index]:
                raise _Abort(SUBINDEX0_NOT_ZERO)
            if index in _ASSIGNABLE and value and value not in _ASSIGNABLE[index]:
                raise _Abort(VALUE_RANGE_EXCEEDED)
            if index in _MAPPABLE and value and value >> 16 not in self._objects:
                raise _Abort(OBJECT_DOES_NOT_EXIST)
            if index in _MAPPABLE and value and value not in _MAPPABLE[index]:
                raise _Abort(CANNOT_BE_MAPPED)
            self._pdo_entries[index][subindex - 1] = value
        return write


def _entry_name(index: int, subindex: int, variable: bool) -> str:
    """An entry's name: the object's own for a variable, the count at subindex 0, the identity's fields."""
    if variable:
        return objects.NAMES.get(index, f"Object 0x{index:04X}")
    if subindex == 0:
        return "Number of entries"
    if index == objects.IDENTITY and subindex <= len(IDENTITY_ENTRIES):
        return IDENTITY_ENTRIES[subindex - 1]
    return f"SubIndex {subindex:03d}"


def _fragments(opcode: int, data: bytes) -> list[bytes]:
    """An SDO Information response in mailbox-sized fragments, each with its CoE and information headers."""
    room = MAILBOX_SIZE - 6 - 6                    # the mailbox header, then the CoE and SDO information headers
    chunks = [data[at:at + room] for at in range(0, len(data), room)] or [b""]
    return [struct.pack("<HBBH", SDO_INFORMATION << 12, opcode | (INCOMPLETE if left else 0), 0, left) + chunk
            for left, chunk in zip(range(len(chunks) - 1, -1, -1), chunks, strict=True)]
