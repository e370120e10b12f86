"""What sits behind the emulated slave controllers: the drives' CiA402 objects and their cycle.

The slave stack (`virtual.stack`) owns the wire side: registers, mailbox, PDO mapping. It reads and
writes the objects of `objects.RX_ENTRIES` / `TX_ENTRIES` (and SDO access to them) as elements of these
arrays, one element per drive in network order, and calls `step` once per cyclic frame after copying the
outputs in, so the inputs the next frame reads are the drives' answer to this one.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np


class DriveApplication(Protocol):
    """The CiA402 drives behind a virtual segment, as arrays named like the PdoEntry names."""

    count: int
    # outputs, written by the master through RxPDO or SDO
    controlword: np.ndarray       # uint16 (0x6040)
    target_position: np.ndarray   # int32 (0x607A)
    velocity_offset: np.ndarray   # int32 (0x60B1)
    torque_offset: np.ndarray     # int16 (0x60B2)
    mode: np.ndarray              # int8 (0x6060)
    # inputs, read by the master through TxPDO or SDO
    statusword: np.ndarray        # uint16 (0x6041)
    position_actual: np.ndarray   # int32 (0x6064)
    velocity_actual: np.ndarray   # int32 (0x606C)
    torque_actual: np.ndarray     # int16 (0x6077)
    error_code: np.ndarray        # uint16 (0x603F)
    mode_display: np.ndarray      # int8 (0x6061)
    digital_inputs: np.ndarray    # uint32 (0x60FD)
    rated_torque: np.ndarray      # uint32 mN·m (0x6076), read-only

    def step(self, operational: np.ndarray) -> None:
        """Advance the drives by one cycle; `operational[i]` is False where drive i's slave is not in OP."""
        ...

    def communication_lost(self, drive: int) -> None:
        """Drive `drive` stopped receiving process data (watchdog expired or left OP): it stops on its own."""
        ...
