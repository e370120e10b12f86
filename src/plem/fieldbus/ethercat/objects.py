"""CiA402 objects of cyclic synchronous position and the process data plem maps, shared by master and drives.

One table serves both ends of the wire: the master writes exactly this PDO assignment by SDO in PREOP
(a drive's defaults are not trusted), and the emulated drives of the virtual network offer these objects.
"""

from __future__ import annotations

from dataclasses import dataclass

#: Object indices of the PDO assignment (sync manager 2 outputs, 3 inputs) and the PDO mappings used.
RX_ASSIGN = 0x1C12
TX_ASSIGN = 0x1C13
RX_PDO = 0x1600
TX_PDO = 0x1A00
SM_COMM_TYPE = 0x1C00
DEVICE_TYPE = 0x1000
DEVICE_NAME = 0x1008
IDENTITY = 0x1018
RATED_TORQUE = 0x6076          # mN·m; torque objects (0x6077, 0x60B2) are in thousandths of it
SUPPORTED_MODES = 0x6502

#: Device type 0x1000 of a CiA402 servo drive: profile 402, "servo drive" in the additional information.
CIA402_DEVICE_TYPE = 0x00020192

#: The names CiA 301 and CiA 402 give the objects plem and its emulated drives use (as a drive's ESI file and
#: `slaveinfo -sdo` print them).
NAMES: dict[int, str] = {
    DEVICE_TYPE: "Device type",
    DEVICE_NAME: "Manufacturer device name",
    IDENTITY: "Identity object",
    SM_COMM_TYPE: "Sync manager communication type",
    RX_PDO: "RxPDO mapping 1",
    RX_PDO + 1: "RxPDO mapping 2",
    TX_PDO: "TxPDO mapping 1",
    TX_PDO + 1: "TxPDO mapping 2",
    RX_ASSIGN: "Sync manager 2 PDO assignment (RxPDO)",
    TX_ASSIGN: "Sync manager 3 PDO assignment (TxPDO)",
    0x603F: "Error code",
    0x6040: "Controlword",
    0x6041: "Statusword",
    0x6060: "Modes of operation",
    0x6061: "Modes of operation display",
    0x6064: "Position actual value",
    0x606C: "Velocity actual value",
    RATED_TORQUE: "Rated torque",
    0x6077: "Torque actual value",
    0x60FD: "Digital inputs",
    0x607A: "Target position",
    0x60B1: "Velocity offset",
    0x60B2: "Torque offset",
    SUPPORTED_MODES: "Supported drive modes",
}


def object_name(index: int, subindex: int = 0) -> str:
    """`0x6076:0 (Rated torque)`: an object as error messages name it."""
    name = NAMES.get(index)
    return f"0x{index:04X}:{subindex}" + (f" ({name})" if name else "")


@dataclass(frozen=True)
class PdoEntry:
    """One object mapped into process data: its index/subindex, size in bits, and numpy dtype."""

    name: str
    index: int
    subindex: int
    bits: int
    dtype: str

    @property
    def mapping(self) -> int:
        """The 32-bit value of this entry in a PDO mapping object (index << 16 | subindex << 8 | bits)."""
        return self.index << 16 | self.subindex << 8 | self.bits


#: Outputs (master → drive), in the order plem maps them into RxPDO 0x1600.
RX_ENTRIES: tuple[PdoEntry, ...] = (
    PdoEntry("controlword", 0x6040, 0, 16, "<u2"),
    PdoEntry("target_position", 0x607A, 0, 32, "<i4"),
    PdoEntry("velocity_offset", 0x60B1, 0, 32, "<i4"),
    PdoEntry("torque_offset", 0x60B2, 0, 16, "<i2"),
    PdoEntry("mode", 0x6060, 0, 8, "<i1"),
)

#: Inputs (drive → master), in the order plem maps them into TxPDO 0x1A00.
TX_ENTRIES: tuple[PdoEntry, ...] = (
    PdoEntry("statusword", 0x6041, 0, 16, "<u2"),
    PdoEntry("position_actual", 0x6064, 0, 32, "<i4"),
    PdoEntry("velocity_actual", 0x606C, 0, 32, "<i4"),
    PdoEntry("torque_actual", 0x6077, 0, 16, "<i2"),
    PdoEntry("error_code", 0x603F, 0, 16, "<u2"),
    PdoEntry("mode_display", 0x6061, 0, 8, "<i1"),
)

#: Mapped after the inputs above where the drive maps it: its digital inputs (CiA402 bits 0-3 limit switches, home
#: and interlock; 16-31 the manufacturer's, often general-purpose inputs). A drive that refuses it runs without.
DIGITAL_INPUTS = PdoEntry("digital_inputs", 0x60FD, 0, 32, "<u4")

ENTRIES_BY_OBJECT: dict[tuple[int, int], PdoEntry] = {(e.index, e.subindex): e
                                                      for e in RX_ENTRIES + TX_ENTRIES + (DIGITAL_INPUTS,)}


def pdo_bytes(entries: tuple[PdoEntry, ...]) -> int:
    """Size in bytes of a PDO made of `entries`."""
    return sum(e.bits for e in entries) // 8


def offsets(entries: tuple[PdoEntry, ...]) -> dict[str, int]:
    """Byte offset of each entry in a PDO made of `entries` (packed, in order)."""
    found, at = {}, 0
    for entry in entries:
        found[entry.name] = at
        at += entry.bits // 8
    return found
