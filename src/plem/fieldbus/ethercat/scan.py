"""`plem ethercat scan`: what answers on an interface, slave by slave, without changing the slaves' setup.

Enumerating a segment resets its slaves to INIT, so a scan first takes the interface's lock: it refuses
while a robot runs on that interface instead of stopping the robot's drives under it.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

from plem.control.compiled import core
from plem.fieldbus.ethercat.bringup import (
    DC_SUPPORTED,
    REG_ESC_FEATURES,
    close_master,
    find_slaves,
    interface_lock,
    open_master,
    segment_slaves,
    slave_states,
    state_name,
)


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


def scan(interface: str) -> list[SlaveInfo]:
    """Every slave on `interface` in network order; 'EtherCAT master not found' when none answers."""
    with interface_lock(interface):
        master = open_master(interface)
        try:
            find_slaves(master, interface)
            states = slave_states(master)
            found = []
            for slave, (state, code) in zip(segment_slaves(master), states, strict=True):
                features = slave.register(REG_ESC_FEATURES) or 0
                found.append(SlaveInfo(slave.position, slave.name, slave.vendor_id, slave.product_code, slave.revision,
                                       state_name(state), code, core.al_status_text(code), slave.coe,
                                       bool(features & DC_SUPPORTED)))
            return found
        finally:
            close_master(master)
