"""Fieldbus access: the bus interface, CiA402 drive profile, the simulated bus, EtherCAT.

Everything but the network-interface checks is imported on first use (it pulls in numpy, and the
simulated arm pinocchio), so commands that only check an interface start fast.
"""

from importlib import import_module
from typing import Any

from plem.fieldbus.network_interface import available_interfaces, check_network_interface

_BUS = ("IBus", "BusIO", "BusSetup", "BusStatus", "DriveState", "OperationMode")
_CIA402 = ("Controlword", "decode_statusword", "describe_drive_fault", "describe_error_code",
           "describe_statusword", "drive_transition", "next_controlword")
_LAZY = {"MockBus": "plem.fieldbus.mock"} | dict.fromkeys(_BUS, "plem.fieldbus.bus") | dict.fromkeys(
    _CIA402, "plem.fieldbus.cia402")

__all__ = ["MockBus", *_BUS, *_CIA402, "available_interfaces", "check_network_interface"]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'plem.fieldbus' has no attribute {name!r}")
