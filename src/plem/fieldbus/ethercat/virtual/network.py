"""The link of a virtual EtherCAT network: a veth pair whose drive end lives in a network namespace of its own.

`VethNamespace(index)` is the master's interface `plemec<index>` in the current network namespace,
wired to the drives' interface `plemecd<index>` inside the network namespace `plem-ec<index>`
(/run/netns), both up. A master opens the near end like a wired port and sees nothing on it but the
emulated slaves, which answer on the far end through a socket opened inside the namespace
(`open_drive_socket`, or anything run `inside()` it). Several networks coexist under different indices.
It takes iproute2's `ip` and the right to create namespaces: root, or user, network and mount namespaces
of one's own with a private /run.
"""

from __future__ import annotations

import ctypes
import os
import socket
import subprocess
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from plem.errors import PlemError
from plem.fieldbus.ethercat.virtual.wire import open_socket

NAMESPACES = Path("/run/netns")
_CLONE_NEWNET = 0x40000000
_CAP_NET_ADMIN = 12
_CAP_SYS_ADMIN = 21
_NOT_PERMITTED = ("Operation not permitted", "Permission denied")
_HOW_TO_GET_PERMISSION = ("run as root (sudo), or in user, network and mount namespaces of your own with a private "
                          "/run: unshare -Urnm sh -c 'mount -t tmpfs tmpfs /run && exec <command>'")


class NamespacePermissionError(PlemError):
    """This process may not create network namespaces and veth pairs."""


@dataclass(frozen=True)
class VethNamespace:
    """Virtual network `index`: the master's end here, the drives' end in the namespace; created on demand."""

    index: int

    @property
    def master_end(self) -> str:
        """The interface the EtherCAT master opens, in the current namespace."""
        return f"plemec{self.index}"

    @property
    def drive_end(self) -> str:
        """The interface the emulated slaves answer on, inside `namespace`."""
        return f"plemecd{self.index}"

    @property
    def namespace(self) -> str:
        """The network namespace of the drives' end."""
        return f"plem-ec{self.index}"

    def exists(self) -> bool:
        """True when any part of this network is present."""
        return Path("/sys/class/net", self.master_end).exists() or (NAMESPACES / self.namespace).exists()

    def create(self) -> None:
        """Create the namespace and the veth pair, both ends up; PlemError when the network exists already."""
        _check_permission()
        if self.exists():
            raise PlemError(f"virtual EtherCAT network {self.index} exists already",
                            what=f"interface {self.master_end} or namespace {self.namespace} is there",
                            why="each index names one network; another run may still be using it",
                            how=f"stop that run, or remove what is left of it (ip link delete {self.master_end}; "
                                f"ip netns delete {self.namespace}), "
                                "or use another master_index:=")
        try:
            _ip("netns", "add", self.namespace)
            _ip("link", "add", self.master_end, "type", "veth", "peer", "name", self.drive_end,
                "netns", self.namespace)
            _ip("link", "set", self.master_end, "up")
            _ip("-n", self.namespace, "link", "set", self.drive_end, "up")
        except PlemError:
            self.remove()
            raise

    def remove(self) -> None:
        """Remove whatever is left of this network; nothing happens when none of it exists."""
        if Path("/sys/class/net", self.master_end).exists():
            _ip("link", "delete", self.master_end)             # takes the drives' end with it
        if (NAMESPACES / self.namespace).exists():
            _ip("netns", "delete", self.namespace)

    @contextmanager
    def inside(self) -> Iterator[None]:
        """Run the calling thread inside the namespace for the `with` block (sockets opened there stay there)."""
        try:
            target = os.open(NAMESPACES / self.namespace, os.O_RDONLY | os.O_CLOEXEC)
        except FileNotFoundError:
            raise PlemError(f"virtual EtherCAT network {self.index} does not exist",
                            what=f"namespace {self.namespace} is missing", why="the drives' end lives in it",
                            how="start the virtual network first: `plem ethercat simulate`") from None
        own = os.open("/proc/thread-self/ns/net", os.O_RDONLY | os.O_CLOEXEC)
        try:
            _setns(target)
            try:
                yield
            finally:
                _setns(own)
        finally:
            os.close(own)
            os.close(target)

    def open_drive_socket(self) -> socket.socket:
        """A raw EtherCAT socket on the drives' end, for `wire.serve` (opened inside, usable from anywhere)."""
        with self.inside():
            return open_socket(self.drive_end)


def _setns(fd: int) -> None:
    """Move the calling thread into the network namespace open as `fd`."""
    if hasattr(os, "setns"):                                    # Python 3.12+
        os.setns(fd, _CLONE_NEWNET)
    elif ctypes.CDLL(None, use_errno=True).setns(fd, _CLONE_NEWNET) != 0:
        error = ctypes.get_errno()
        raise OSError(error, f"cannot enter a network namespace: {os.strerror(error)}")


def _check_permission() -> None:
    """Raise NamespacePermissionError unless this process holds CAP_NET_ADMIN and CAP_SYS_ADMIN."""
    status = Path("/proc/self/status").read_text()
    effective = int(next(line.split()[1] for line in status.splitlines() if line.startswith("CapEff:")), 16)
    if not (effective >> _CAP_NET_ADMIN & 1 and effective >> _CAP_SYS_ADMIN & 1):
        raise NamespacePermissionError(
            "no permission to create a virtual EtherCAT network",
            what="this process lacks CAP_NET_ADMIN or CAP_SYS_ADMIN",
            why="the network is a veth pair with one end in a network namespace of its own",
            how=_HOW_TO_GET_PERMISSION)


def _ip(*args: str) -> None:
    """Run iproute2's `ip` with `args`; PlemError (NamespacePermissionError when refused) on failure."""
    try:
        result = subprocess.run(["ip", *args], capture_output=True, text=True, env={**os.environ, "LC_ALL": "C"},
                                check=False)
    except FileNotFoundError as error:
        raise PlemError("the `ip` command is missing", what="iproute2's `ip` is not on PATH",
                        why="the virtual EtherCAT network is set up with it",
                        how="install iproute2 (apt-get install iproute2)") from error
    if result.returncode:
        message = result.stderr.strip() or f"exit status {result.returncode}"
        refused = any(text in message for text in _NOT_PERMITTED)
        kind = NamespacePermissionError if refused else PlemError
        raise kind(f"ip {' '.join(args)} failed", what=message, why="the virtual EtherCAT network needs this step",
                   how=_HOW_TO_GET_PERMISSION if refused
                   else "remove what is left of the network (ip link delete plemec<index>; ip netns delete "
                        "plem-ec<index>), then try again")
