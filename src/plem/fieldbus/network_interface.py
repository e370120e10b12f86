"""Checks that a network interface can carry EtherCAT: it exists, is wired, and is not loopback.

Run when a bus opens (and by diagnostics), not when a config is built, so configs can be made anywhere.
"""

from __future__ import annotations

from pathlib import Path

from plem.errors import ConfigError

SYS_CLASS_NET = Path("/sys/class/net")
ARPHRD_LOOPBACK = 772
IFF_LOOPBACK = 0x8


def available_interfaces(sys_class_net: Path = SYS_CLASS_NET) -> list[str]:
    """Names of the interfaces the kernel knows."""
    return sorted(p.name for p in sys_class_net.iterdir()) if sys_class_net.is_dir() else []


def _read_int(path: Path) -> int | None:
    try:
        return int(path.read_text().strip(), 0)
    except (OSError, ValueError):
        return None


def check_network_interface(name: str, sys_class_net: Path = SYS_CLASS_NET) -> None:
    """Raise a ConfigError when `name` is missing, wireless or loopback; return quietly when usable."""
    device = sys_class_net / name
    listing = ", ".join(available_interfaces(sys_class_net)) or "none"
    if not device.exists():
        raise ConfigError(
            f"Network interface does not exist: {name}",
            what="an existing wired Ethernet interface for EtherCAT (e.g. eth0, enp3s0)",
            why=f"{name!r} is not among this machine's interfaces: {listing}",
            how="list interfaces with `ip link show` and pass eth_interface:=<name>; without hardware use "
                "bus:=ethercat_sim (the virtual EtherCAT network) or bus:=mock (the simulated arm)",
        )
    if (device / "wireless").exists() or (device / "phy80211").exists():
        raise ConfigError(
            f"Network interface {name} is wireless",
            what="a wired Ethernet interface: EtherCAT frames cannot travel over Wi-Fi",
            why=f"{name} is a wireless interface",
            how=f"connect the robot to a wired port and pass its name (interfaces here: {listing})",
        )
    flags = _read_int(device / "flags") or 0
    if _read_int(device / "type") == ARPHRD_LOOPBACK or flags & IFF_LOOPBACK:
        raise ConfigError(
            f"Network interface {name} is the loopback interface",
            what="a wired Ethernet interface connected to the robot",
            why=f"{name} is loopback: frames never leave this machine",
            how=f"pass the port the robot is wired to (interfaces here: {listing}), or bus:=mock to simulate",
        )
