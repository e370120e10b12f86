"""Fieldbus access: the bus interface, the simulated bus, EtherCAT."""

from plem.fieldbus.network_interface import available_interfaces, check_network_interface

__all__ = ["available_interfaces", "check_network_interface"]
