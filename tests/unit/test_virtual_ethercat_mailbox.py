"""The emulated drive's mailbox, message by message: SDO Information answered (object list, object and entry
descriptions, in fragments when long), mailbox errors with the code each case calls for, missing objects."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from plem.fieldbus.ethercat import objects
from plem.fieldbus.ethercat.virtual import stack as stackmod
from plem.fieldbus.ethercat.virtual.sii import SlaveIdentity
from plem.fieldbus.ethercat.virtual.stack import DriveStack

COE, EOE = 0x03, 0x02


class Drives:
    """One drive's arrays, as the firmware reads and writes them."""

    count = 1

    def __init__(self) -> None:
        for entry in objects.RX_ENTRIES + objects.TX_ENTRIES:
            setattr(self, entry.name, np.zeros(1, dtype=entry.dtype))
        self.rated_torque = np.full(1, 2500, dtype=np.uint32)

    def step(self, operational: np.ndarray) -> None: ...

    def communication_lost(self, drive: int) -> None: ...


def drive(missing: frozenset[int] = frozenset()) -> tuple[DriveStack, list[bytes]]:
    """A drive's firmware and the mailbox messages it posts for the master (each taken at once)."""
    firmware = DriveStack(SlaveIdentity(0x66F, 0x402, 0x10000, 1, "drive"), Drives(), 0, missing_objects=missing)
    posted: list[bytes] = []

    def post(message: bytes) -> bool:
        posted.append(message)
        return True

    firmware.esc.post_mailbox = post  # type: ignore[method-assign]
    return firmware, posted


def request(firmware: DriveStack, kind: int, body: bytes, counter: int = 1) -> None:
    firmware.mailbox_received(struct.pack("<HHBB", len(body), 0, 0, kind | counter << 4) + body)


def info(opcode: int, data: bytes) -> bytes:
    """A CoE SDO Information request."""
    return struct.pack("<HBBH", stackmod.SDO_INFORMATION << 12, opcode, 0, 0) + data


def mailbox_error(message: bytes) -> int | None:
    kind = message[5] & 0x0F
    return struct.unpack_from("<H", message, 8)[0] if kind == stackmod.MAILBOX_ERROR else None


def answer(message: bytes) -> tuple[int, int, bytes]:
    """(opcode with its incomplete flag, fragments left, data) of an SDO Information answer."""
    length = struct.unpack_from("<H", message)[0]
    assert message[5] & 0x0F == COE and struct.unpack_from("<H", message, 6)[0] >> 12 == stackmod.SDO_INFORMATION
    return message[8], struct.unpack_from("<H", message, 10)[0], message[12:6 + length]


def test_an_sdo_information_request_is_answered_not_refused_as_too_short():
    firmware, posted = drive()
    request(firmware, COE, info(stackmod.GET_OD_LIST, struct.pack("<H", stackmod.LIST_ALL)))
    opcode, left, data = answer(posted[-1])
    assert (opcode, left) == (stackmod.OD_LIST, 0)
    indices = struct.unpack(f"<{len(data) // 2}H", data)
    assert indices[0] == stackmod.LIST_ALL and objects.RATED_TORQUE in indices[1:]
    assert list(indices[1:]) == sorted(indices[1:])


def test_object_and_entry_descriptions_name_type_size_and_access():
    firmware, posted = drive()
    request(firmware, COE, info(stackmod.GET_OD, struct.pack("<H", objects.RATED_TORQUE)))
    _, _, data = answer(posted[-1])
    assert struct.unpack_from("<HHBB", data) == (objects.RATED_TORQUE, 0x0007, 0, stackmod.VAR)
    assert data[6:].decode() == "Rated torque"
    request(firmware, COE, info(stackmod.GET_OE, struct.pack("<HBB", 0x6077, 0, 7)), counter=2)
    _, _, data = answer(posted[-1])
    assert struct.unpack_from("<HBBHHH", data) == (0x6077, 0, 7, 0x0003, 16, 0x0087)
    assert data[10:].decode() == "Torque actual value"


def test_what_the_dictionary_lacks_is_an_sdo_information_error_with_its_abort_code():
    firmware, posted = drive(frozenset({objects.RATED_TORQUE}))
    request(firmware, COE, info(stackmod.GET_OD, struct.pack("<H", objects.RATED_TORQUE)))
    opcode, _, data = answer(posted[-1])
    assert (opcode, struct.unpack("<I", data)[0]) == (stackmod.SDO_INFO_ERROR, 0x06020000)
    request(firmware, COE, info(stackmod.GET_OE, struct.pack("<HBB", objects.IDENTITY, 9, 7)), counter=2)
    opcode, _, data = answer(posted[-1])
    assert (opcode, struct.unpack("<I", data)[0]) == (stackmod.SDO_INFO_ERROR, 0x06090011)
    request(firmware, COE, info(stackmod.GET_OD_LIST, struct.pack("<H", stackmod.LIST_ALL)), counter=3)
    _, _, data = answer(posted[-1])
    assert objects.RATED_TORQUE not in struct.unpack(f"<{len(data) // 2}H", data)[1:]


def test_a_long_answer_comes_in_mailbox_sized_fragments():
    firmware, posted = drive()
    request(firmware, COE, info(stackmod.GET_OD_LIST, struct.pack("<H", stackmod.LIST_ALL)))
    single = answer(posted[-1])[2]
    fragments = stackmod._fragments(stackmod.OD_LIST, single * 6)
    assert len(fragments) > 1 and all(len(f) <= stackmod.MAILBOX_SIZE - 6 for f in fragments)
    assert [f[2] for f in fragments] == [stackmod.OD_LIST | stackmod.INCOMPLETE] * (len(fragments) - 1) + \
        [stackmod.OD_LIST]
    assert [struct.unpack_from("<H", f, 4)[0] for f in fragments] == list(range(len(fragments) - 1, -1, -1))
    assert b"".join(f[6:] for f in fragments) == single * 6


@pytest.mark.parametrize(("kind", "body", "code"), [
    (COE, struct.pack("<H", 5 << 12) + bytes(6), stackmod.SERVICE_NOT_SUPPORTED),   # TxPDO over the mailbox
    (COE, struct.pack("<H", 1 << 12) + bytes(8), stackmod.SERVICE_NOT_SUPPORTED),   # an emergency, to a slave
    (EOE, bytes(10), stackmod.PROTOCOL_NOT_SUPPORTED),
    (COE, struct.pack("<HB", stackmod.SDO_REQUEST << 12, 0x40), stackmod.SIZE_TOO_SHORT),
    (COE, b"", stackmod.SIZE_TOO_SHORT),
])
def test_what_the_drive_does_not_serve_gets_the_mailbox_error_that_says_why(kind, body, code):
    firmware, posted = drive()
    request(firmware, kind, body)
    assert mailbox_error(posted[-1]) == code
