"""`plem ethercat scan`: what answers on an interface, slave by slave, without changing the slaves' setup.

Enumerating a segment resets its slaves to INIT, so a scan first takes the interface's lock: it refuses
while a robot runs on that interface instead of stopping the robot's drives under it.
"""

from __future__ import annotations

import struct
from dataclasses import asdict, dataclass
from typing import Any

from plem.fieldbus.ethercat.bringup import (
    DC_SUPPORTED,
    REG_ESC_FEATURES,
    close_master,
    find_slaves,
    interface_lock,
    open_master,
    slave_states,
    state_name,
)

SII_MAILBOX_PROTOCOLS = 0x1C
COE = 0x0004


@dataclass(frozen=True)
class SlaveInfo:
    """One slave as the scan saw it."""

    position: int
    name: str
    vendor_id: int
    product_code: int
    revision: int
    state: str
    al_status_code: int
    al_status: str
    coe: bool
    distributed_clocks: bool

    def as_dict(self) -> dict[str, Any]:
        """The fields as a JSON-ready dict, for `--format json`."""
        return asdict(self)


def _register(slave: Any, address: int) -> int | None:
    from pysoem import WkcError

    try:
        return int(struct.unpack("<H", slave._fprd(address, 2))[0])  # noqa: SLF001 — plain register read
    except WkcError:  # a slave that does not answer: unknown
        return None


def _sii_word(slave: Any, word: int) -> int | None:
    from pysoem import NetworkInterfaceNotOpenError

    try:
        return int.from_bytes(slave.eeprom_read(word)[:2], "little")
    except NetworkInterfaceNotOpenError:  # the interface went away: unknown (a read that fails just reads 0)
        return None


def scan(interface: str) -> list[SlaveInfo]:
    """Every slave on `interface` in network order; 'EtherCAT master not found' when none answers."""
    import pysoem

    with interface_lock(interface):
        master = open_master(interface)
        try:
            find_slaves(master, interface)
            states = slave_states(master)
            found = []
            for position, (slave, (state, code)) in enumerate(zip(master.slaves, states, strict=True)):
                features = _register(slave, REG_ESC_FEATURES) or 0
                protocols = _sii_word(slave, SII_MAILBOX_PROTOCOLS) or 0
                found.append(SlaveInfo(position, slave.name, slave.man, slave.id, slave.rev, state_name(state), code,
                                       pysoem.al_status_code_to_string(code), bool(protocols & COE),
                                       bool(features & DC_SUPPORTED)))
            return found
        finally:
            close_master(master)
