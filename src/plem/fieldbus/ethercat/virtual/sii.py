"""The SII EEPROM image of an emulated slave: who it is, its mailbox, and the categories a master reads.

Word addresses follow ETG.2010: the ESC configuration area (words 0-7, with its CRC), the identity at
0x08 vendor, 0x0A product, 0x0C revision, 0x0E serial, the standard mailbox at 0x18-0x1B, the mailbox
protocols at 0x1C, then categories from word 0x40 (Strings, General, FMMU, SyncManager), ended by 0xFFFF.
SOEM takes the slave's name from string 1 and the sync managers' defaults from the SyncManager category.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass

from plem.errors import PlemError

#: Word addresses of the fixed part.
PDI_CONTROL_WORD = 0x00
STATION_ALIAS_WORD = 0x04
CHECKSUM_WORD = 0x07
VENDOR_WORD = 0x08
PRODUCT_WORD = 0x0A
REVISION_WORD = 0x0C
SERIAL_WORD = 0x0E
RX_MAILBOX_WORD = 0x18         # mailbox master → slave: offset, size
TX_MAILBOX_WORD = 0x1A         # mailbox slave → master: offset, size
MAILBOX_PROTOCOLS_WORD = 0x1C
SIZE_WORD = 0x3E
VERSION_WORD = 0x3F
CATEGORIES_WORD = 0x40

CATEGORY_STRINGS = 10
CATEGORY_GENERAL = 30
CATEGORY_FMMU = 40
CATEGORY_SYNC_MANAGER = 41
CATEGORY_END = 0xFFFF

PROTOCOL_COE = 0x0004
#: CoE details of the General category: SDO, PDO assignment and PDO configuration (no complete access).
COE_SDO = 0x01
COE_PDO_ASSIGN = 0x04
COE_PDO_CONFIG = 0x08
#: Uses of an FMMU in the FMMU category.
FMMU_OUTPUTS = 1
FMMU_INPUTS = 2
FMMU_MAILBOX_STATE = 3
#: Uses of a sync manager (its "type" in the SyncManager category and object 0x1C00).
SM_MAILBOX_OUT = 1             # master → slave
SM_MAILBOX_IN = 2              # slave → master
SM_OUTPUTS = 3
SM_INPUTS = 4

_PDI_SPI = 0x0005              # PDI control: SPI slave, the usual ESC to microcontroller link of a drive
_MAX_NAME = 100                # fits the SII string (255) and an SDO upload in one mailbox (112)


@dataclass(frozen=True)
class SlaveIdentity:
    """What a slave says it is, in its SII and object 0x1018: vendor, product code, revision, serial, and name."""

    vendor_id: int
    product_code: int
    revision: int
    serial: int
    name: str

    def __post_init__(self) -> None:
        for field in ("vendor_id", "product_code", "revision", "serial"):
            value = getattr(self, field)
            if not 0 <= value <= 0xFFFFFFFF:
                raise PlemError(f"slave identity {field} {value:#x} does not fit in 32 bits",
                                what=f"{field} of slave {self.name!r} is {value:#x}",
                                why="the SII and object 0x1018 hold it as UNSIGNED32",
                                how="give a value from 0 to 0xFFFFFFFF")
        if not (self.name.isascii() and self.name.isprintable() and 0 < len(self.name) <= _MAX_NAME):
            raise PlemError(f"slave name {self.name!r} cannot be stored",
                            what=f"the name is {len(self.name)} characters: {self.name!r}",
                            why=f"the SII string and object 0x1008 take 1 to {_MAX_NAME} printable ASCII characters",
                            how="give a shorter, plain ASCII name")


@dataclass(frozen=True)
class SyncManagerSpec:
    """A sync manager as the SII describes it: start address, default length, control byte and use (SM_*)."""

    start: int
    length: int
    control: int
    use: int


def build_image(identity: SlaveIdentity, sync_managers: Sequence[SyncManagerSpec], *,
                coe_details: int = COE_SDO | COE_PDO_ASSIGN | COE_PDO_CONFIG) -> bytes:
    """The EEPROM content of a CoE slave with these sync managers (the mailbox ones first, as SOEM expects)."""
    words = [0] * CATEGORIES_WORD
    words[PDI_CONTROL_WORD] = _PDI_SPI
    words[CHECKSUM_WORD] = _crc8(struct.pack("<7H", *words[:CHECKSUM_WORD]))
    for at, value in ((VENDOR_WORD, identity.vendor_id), (PRODUCT_WORD, identity.product_code),
                      (REVISION_WORD, identity.revision), (SERIAL_WORD, identity.serial)):
        words[at], words[at + 1] = value & 0xFFFF, value >> 16
    mailboxes = {sm.use: sm for sm in sync_managers if sm.use in (SM_MAILBOX_OUT, SM_MAILBOX_IN)}
    for at, use in ((RX_MAILBOX_WORD, SM_MAILBOX_OUT), (TX_MAILBOX_WORD, SM_MAILBOX_IN)):
        if use in mailboxes:
            words[at], words[at + 1] = mailboxes[use].start, mailboxes[use].length
    words[MAILBOX_PROTOCOLS_WORD] = PROTOCOL_COE if mailboxes else 0
    words[VERSION_WORD] = 1
    name = identity.name.encode("ascii")
    general = bytearray(32)
    general[3] = 1                          # name: string 1
    general[5] = coe_details
    general[9] = 1                          # one CiA402 axis
    general[16] = 0x11                      # ports 0 and 1: MII
    categories = b"".join((
        _category(CATEGORY_STRINGS, bytes([1, len(name)]) + name),
        _category(CATEGORY_GENERAL, bytes(general)),
        _category(CATEGORY_FMMU, bytes([FMMU_OUTPUTS, FMMU_INPUTS, FMMU_MAILBOX_STATE])),
        _category(CATEGORY_SYNC_MANAGER, b"".join(struct.pack("<HHBBBB", sm.start, sm.length, sm.control, 0, 1, sm.use)
                                                  for sm in sync_managers)),
        struct.pack("<H", CATEGORY_END),
    ))
    size = len(words) * 2 + len(categories)
    kibit = 1
    while kibit * 128 < size:
        kibit *= 2
    words[SIZE_WORD] = kibit - 1
    image = struct.pack(f"<{len(words)}H", *words) + categories
    return image + b"\xff" * (kibit * 128 - len(image))


def _category(kind: int, data: bytes) -> bytes:
    """One category: its type, its length in words, and the data padded to whole words (0xFF, as unused bytes)."""
    if len(data) % 2:
        data += b"\xff"
    return struct.pack("<HH", kind, len(data) // 2) + data


def _crc8(data: bytes) -> int:
    """CRC-8 (x^8 + x^2 + x + 1, initial 0xFF) of the ESC configuration area, as the ESC checks it at power-up."""
    crc = 0xFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = ((crc << 1) ^ 0x07) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
    return crc
