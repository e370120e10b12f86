"""Bringing an EtherCAT segment up to OP and down again on the core's SOEM master, with an error for every step
that fails.

Opening: the interface and the raw-socket permission are checked, SOEM enumerates the slaves, the slaves
found are compared with the drives the arm expects (one CiA402 drive per joint, in order, with the ids
the description package gives), the PDO assignment of `objects` is written by SDO in PREOP, the process
data is mapped and its size checked, distributed clocks are set up where the slaves have them, and the
segment goes SAFEOP → OP within timeouts, naming each slave's AL status code when a transition fails.
The master is the one the real-time cycle then exchanges through (`plem.control._core.Master`): one SOEM
context per interface, never two.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import struct
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from plem.control.compiled import core
from plem.description.drives import DriveParameters
from plem.errors import ConfigError, PlemError
from plem.fieldbus.ethercat import objects
from plem.fieldbus.ethercat.host import Finding, check_raw_sockets
from plem.fieldbus.network_interface import check_network_interface

ETHERLAB_CONF = Path("/opt/etherlab/etc/ethercat.conf")
STATE_TIMEOUT_S = 5.0          # for each of PREOP, SAFEOP and OP to be reached by every slave
REG_AL_STATUS = 0x0130
REG_ESC_FEATURES = 0x0008
DC_SUPPORTED = 0x0004
INIT_STATE, PREOP_STATE, SAFEOP_STATE, OP_STATE = 0x01, 0x02, 0x04, 0x08
#: Longest wait for a register read's answer (µs).
REGISTER_TIMEOUT_US = 2000


class EtherCATError(PlemError):
    """The EtherCAT segment could not be brought up, or does not match the arm."""


class Slave(Protocol):
    """What the bring-up uses of a slave: its identity, mapped sizes (bytes) and SDO access."""

    @property
    def name(self) -> str: ...  # noqa: D102
    @property
    def vendor_id(self) -> int: ...  # noqa: D102
    @property
    def product_code(self) -> int: ...  # noqa: D102
    @property
    def revision(self) -> int: ...  # noqa: D102
    @property
    def outputs(self) -> int: ...  # noqa: D102
    @property
    def inputs(self) -> int: ...  # noqa: D102
    def sdo_read(self, index: int, subindex: int) -> bytes: ...  # noqa: D102
    def sdo_write(self, index: int, subindex: int, data: bytes) -> None: ...  # noqa: D102


@dataclass(frozen=True)
class SegmentSlave:
    """One slave of the master, as enumeration (and the mapping, once done) found it; `position` counts from 0."""

    master: Any
    position: int
    name: str
    vendor_id: int
    product_code: int
    revision: int
    outputs: int
    inputs: int
    coe: bool

    def sdo_read(self, index: int, subindex: int) -> bytes:
        """Up to 4 bytes of an object (the sizes plem reads)."""
        data: bytes = self.master.sdo_read(self.position + 1, index, subindex, 4)
        return data

    def sdo_write(self, index: int, subindex: int, data: bytes) -> None:
        """Write an object by SDO (the slave in PREOP)."""
        self.master.sdo_write(self.position + 1, index, subindex, data)

    def register(self, address: int, size: int = 2) -> int | None:
        """A little-endian ESC register, None when the slave does not answer."""
        data = self.master.read_register(self.position + 1, address, size, REGISTER_TIMEOUT_US)
        return None if data is None else int.from_bytes(data, "little")


def segment_slaves(master: Any) -> tuple[SegmentSlave, ...]:
    """The master's slaves in network order."""
    return tuple(SegmentSlave(master, i, s["name"], s["vendor"], s["product"], s["revision"], s["outputs"],
                              s["inputs"], s["coe"]) for i, s in enumerate(master.slaves()))


def default_interface(master_index: int, conf: Path = ETHERLAB_CONF) -> str | None:
    """`MASTER<index>_DEVICE` of an EtherLab configuration, when one is installed and names an interface."""
    try:
        text = conf.read_text()
    except (OSError, UnicodeDecodeError):
        return None
    key = f"MASTER{master_index}_DEVICE"
    for line in text.splitlines():
        name, _, value = line.partition("=")
        if name.strip() == key:
            value = value.split("#")[0].strip().strip("\"'")
            return value or None
    return None


def _permission_error(interface: str, finding: Finding) -> EtherCATError:
    return EtherCATError(f"no permission to open {interface} for EtherCAT", what=finding.what, why=finding.why,
                         how=finding.how)


LOCK_DIR = Path("/dev/shm")


@contextlib.contextmanager
def interface_lock(interface: str, holder: str = "plem ethercat scan") -> Iterator[None]:
    """Hold `interface` for one master (a running robot or a scan); a clear error when it is taken."""
    check_access(interface)
    path = LOCK_DIR / f"plem-ethercat-{interface}.lock"
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC, 0o644)
        writable = True
    except PermissionError:  # another user's lock file: a read-only descriptor locks it as well
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_CLOEXEC)
        writable = False
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            owner = os.pread(fd, 200, 0).decode("utf-8", "replace").strip() or "another process"
            raise EtherCATError(
                f"{interface} is in use by another EtherCAT master",
                what=f"{interface} free for {holder}",
                why=f"{owner} holds it ({path})",
                how="stop that robot first (Ctrl-C in its `plem launch`), or give each robot its own interface "
                    "with eth_interface:= and master_index:=") from None
        if writable:
            os.ftruncate(fd, 0)
            os.pwrite(fd, f"{holder} (pid {os.getpid()})".encode(), 0)
        yield
    finally:
        os.close(fd)


def check_access(interface: str) -> None:
    """The interface can carry EtherCAT and this process may open it; an EtherCATError naming the fix if not."""
    check_network_interface(interface)
    permission = check_raw_sockets()
    if not permission.ok:
        raise _permission_error(interface, permission)


def open_master(interface: str) -> Any:
    """The core's master on `interface`, after checking that the interface can carry EtherCAT and may be opened."""
    check_access(interface)
    master = core.Master()
    try:
        master.open(interface)
    except ConnectionError as error:
        raise EtherCATError(f"{interface} could not be opened for EtherCAT",
                            what="a raw socket on the interface for EtherCAT frames",
                            why=f"SOEM could not open a raw socket on {interface}: {error}",
                            how="check `ip link show` for the interface and `plem doctor "
                                f"{interface}` for the host's permissions") from error
    return master


def find_slaves(master: Any, interface: str) -> int:
    """Enumerate the slaves on the open master; 'EtherCAT master not found' when nothing answers."""
    found: int = master.config_init()
    if found <= 0:
        raise EtherCATError(
            "EtherCAT master not found",
            what=f"EtherCAT slaves answering on {interface}",
            why=f"no slave answered the master's frames on {interface}",
            how=f"check the cable and the drives' power, that {interface} is the port the robot is wired to "
                f"(`plem ethercat scan {interface}`; `ip link show {interface}` must say LOWER_UP), and that "
                "no other EtherCAT master uses the interface; without hardware use bus:=ethercat_sim (the virtual "
                "EtherCAT network) or bus:=mock")
    return found


def _hex(value: int | None) -> str:
    return "any" if value is None else f"0x{value:08X}"


def check_topology(slaves: Sequence[Slave], joint_names: Sequence[str], drives: Sequence[DriveParameters]) -> None:
    """One drive per joint in order, with the description's vendor/product/revision where it gives them."""
    if len(slaves) != len(joint_names):
        listing = "; ".join(f"{i}: {s.name} (vendor 0x{s.vendor_id:08X}, product 0x{s.product_code:08X})"
                            for i, s in enumerate(slaves))
        raise EtherCATError(
            f"the EtherCAT segment has {len(slaves)} slaves, the arm has {len(joint_names)} joints",
            what=f"one CiA402 drive per actuated joint, in joint order: {', '.join(joint_names)}",
            why=f"found {listing}",
            how="check the cabling and the drives' power (`plem ethercat scan` lists what answers), or use "
                "the description package of this arm")
    for position, (slave, joint, drive) in enumerate(zip(slaves, joint_names, drives, strict=True)):
        wrong = [(name, expected, found) for name, expected, found in (
            ("vendor_id", drive.vendor_id, slave.vendor_id), ("product_code", drive.product_code, slave.product_code),
            ("revision", drive.revision, slave.revision)) if expected is not None and expected != found]
        if wrong:
            found = ", ".join(f"{name} 0x{value:08X}" for name, _, value in wrong)
            expected = ", ".join(f"{name} {_hex(value)}" for name, value, _ in wrong)
            raise EtherCATError(
                f"slave {position} ({slave.name}) is not the drive of {joint}",
                what=f"at position {position}: the drive of {joint} with {expected}",
                why=f"found {found}",
                how=f"wire the drives in joint order, or correct the <param> tags of {joint} in the "
                    "description package's ros2_control block (`plem ethercat scan` shows each slave's ids)")


#: What plem uses each object it reads or writes by SDO for, as its errors say.
PURPOSES: dict[int, str] = {
    objects.DEVICE_TYPE: "read to check that the slave is a CiA402 drive",
    objects.RX_ASSIGN: "written to assign plem's RxPDO 0x1600 (the drive's outputs) to sync manager 2",
    objects.TX_ASSIGN: "written to assign plem's TxPDO 0x1A00 (the drive's inputs) to sync manager 3",
    objects.RX_PDO: "written to map plem's outputs: 0x6040 controlword, 0x607A target position, 0x60B1 velocity "
                    "offset, 0x60B2 torque offset, 0x6060 mode of operation",
    objects.TX_PDO: "written to map plem's inputs: 0x6041 statusword, 0x6064 position, 0x606C velocity, 0x6077 "
                    "torque, 0x603F error code, 0x6061 mode display",
    0x6060: "written to select cyclic synchronous position mode (8)",
    objects.RATED_TORQUE: "read to turn the drive's torque (thousandths of its rated torque) into N·m",
}


def sdo_failure(error: Exception) -> str:
    """An SDO failure in words: the abort code with its text (SOEM's), or what went wrong without one."""
    abort, words = error.args if isinstance(error, core.SdoError) and len(error.args) == 2 else (0, str(error))
    return f"SDO abort 0x{abort:08X}: {words}" if abort else str(words)


def _sdo_error(slave: Slave, position: int, joint: str, index: int, subindex: int, error: Exception) -> EtherCATError:
    entry = objects.ENTRIES_BY_OBJECT.get((index, subindex))
    size = f", {entry.bits} bits" if entry else ""
    mapping = index in (objects.RX_ASSIGN, objects.TX_ASSIGN, objects.RX_PDO, objects.TX_PDO)
    return EtherCATError(
        f"slave {position} ({slave.name}, {joint}) refused object {objects.object_name(index, subindex)}",
        what=f"object {objects.object_name(index, subindex)}{size}, {PURPOSES.get(index, 'used by plem')}",
        why=sdo_failure(error),
        how=("check in the drive's documentation that it maps these objects with these sizes (a drive that cannot "
             "map one needs a firmware or configuration change)" if mapping else
             f"check in the drive's documentation that it offers object 0x{index:04X} as CiA402 defines it")
            + "; `plem ethercat scan` shows the drive, SOEM's `slaveinfo <interface> -sdo` its objects")


def _read_u32(slave: Slave, position: int, joint: str, index: int) -> int:
    try:
        return _u32(slave.sdo_read(index, 0))
    except RuntimeError as error:  # the master's SdoError: an abort, no answer or a mailbox error
        raise _sdo_error(slave, position, joint, index, 0, error) from error


def _u32(data: bytes) -> int:
    return int(struct.unpack("<I", data[:4].ljust(4, b"\0"))[0])


def assign_process_data(slave: Slave, position: int, joint: str) -> bool:
    """Check that one slave is a CiA402 drive, write plem's PDO assignment by SDO (in PREOP) and set CSP mode;
    whether the drive maps its digital inputs too (a drive that refuses them runs without)."""
    device_type = _read_u32(slave, position, joint, objects.DEVICE_TYPE)
    if device_type & 0xFFFF != objects.CIA402_DEVICE_TYPE & 0xFFFF:
        raise EtherCATError(
            f"slave {position} ({slave.name}, {joint}) is not a CiA402 drive",
            what="a drive following the CiA402 profile (device type 0x1000 = 0x....0192)",
            why=f"its device type is 0x{device_type:08X} (profile {device_type & 0xFFFF})",
            how="wire only the arm's servo drives, one per joint in joint order (`plem ethercat scan` lists "
                "the slaves); I/O terminals and couplers belong on another segment")

    def write(index: int, subindex: int, data: bytes) -> None:
        try:
            slave.sdo_write(index, subindex, data)
        except RuntimeError as error:  # the master's SdoError: an abort, no answer or a mailbox error
            raise _sdo_error(slave, position, joint, index, subindex, error) from error

    def accepted(index: int, subindex: int, data: bytes) -> bool:
        try:
            slave.sdo_write(index, subindex, data)
        except RuntimeError:  # an abort: the drive does not map that object
            return False
        return True

    inputs = False
    for assign, pdo, entries in ((objects.RX_ASSIGN, objects.RX_PDO, objects.RX_ENTRIES),
                                 (objects.TX_ASSIGN, objects.TX_PDO, objects.TX_ENTRIES)):
        write(assign, 0, b"\x00")
        write(pdo, 0, b"\x00")
        for subindex, entry in enumerate(entries, start=1):
            write(pdo, subindex, struct.pack("<I", entry.mapping))
        if pdo == objects.TX_PDO:
            extra = len(entries) + 1
            inputs = accepted(pdo, extra, struct.pack("<I", objects.DIGITAL_INPUTS.mapping)) \
                and accepted(pdo, 0, bytes([extra]))
        if not inputs:
            write(pdo, 0, bytes([len(entries)]))
        write(assign, 1, struct.pack("<H", pdo))
        write(assign, 0, b"\x01")
    write(0x6060, 0, struct.pack("<b", 8))
    return inputs


@dataclass(frozen=True)
class RatedTorque:
    """A drive's rated motor torque in N·m and where it came from; None when neither the package nor the drive
    gives it (the drive's torque then stays in per mille of it), `source` saying why."""

    newton_metres: float | None
    source: str


def rated_torque(slave: Slave, drive: DriveParameters) -> RatedTorque:
    """The package's `rated_torque` when it gives one, else the drive's 0x6076 (mN·m); unknown when the drive has no
    such object, or reads 0, or does not answer it."""
    if drive.rated_torque is not None:
        return RatedTorque(drive.rated_torque, "the package's rated_torque")
    name = objects.object_name(objects.RATED_TORQUE)
    try:
        value = _u32(slave.sdo_read(objects.RATED_TORQUE, 0))
    except RuntimeError as error:  # the master's SdoError: a drive without the object aborts the read
        return RatedTorque(None, f"reading {name} failed: {sdo_failure(error)}")
    if value == 0:
        return RatedTorque(None, f"{name} reads 0")
    return RatedTorque(value / 1000.0, name)


def per_mille_warning(joint_names: Sequence[str], rated: Sequence[RatedTorque]) -> str | None:
    """The start-up warning for drives whose rated torque is unknown (None when every drive's is known)."""
    unknown = [(joint, r.source) for joint, r in zip(joint_names, rated, strict=True) if r.newton_metres is None]
    if not unknown:
        return None
    reasons = {source for _, source in unknown}
    why = (next(iter(reasons)) if len(reasons) == 1
           else "; ".join(f"{joint}: {source}" for joint, source in unknown))
    joints = ", ".join(joint for joint, _ in unknown)
    return (f"effort of {joints} is in per mille of each drive's rated torque, not N·m: the drive gives no rated "
            f"torque ({why}). Those readings (joint_states effort, `plem state`) count thousandths of the motor's "
            "rated torque, and free drive is refused (its gravity torque cannot be sent). For N·m and free drive, "
            "give each of those joints "
            '<param name="rated_torque"> (the motor\'s rated torque in N·m) in the description package\'s '
            "ros2_control block")


def check_mapping(slaves: Sequence[Slave], joint_names: Sequence[str], digital_inputs: Sequence[bool]) -> None:
    """Every slave's mapped process data has exactly the size of plem's PDOs (with its digital inputs where it
    mapped them)."""
    for position, (slave, joint, extra) in enumerate(zip(slaves, joint_names, digital_inputs, strict=True)):
        rx = objects.pdo_bytes(objects.RX_ENTRIES)
        tx = objects.pdo_bytes(objects.TX_ENTRIES + ((objects.DIGITAL_INPUTS,) if extra else ()))
        outputs, inputs = slave.outputs, slave.inputs
        if (outputs, inputs) != (rx, tx):
            raise EtherCATError(
                f"slave {position} ({slave.name}, {joint}) mapped {outputs} output and {inputs} input bytes",
                what=f"{rx} output and {tx} input bytes: plem's RxPDO and TxPDO",
                why="the drive accepted the PDO assignment but its sync managers carry a different size",
                how="the drive ignores SDO PDO assignment: configure its PDOs to plem's objects with the "
                    "vendor's tool, or check its ESI file for fixed PDOs")


def slave_states(master: Any) -> list[tuple[int, int]]:
    """(AL state, AL status code) of every slave, read afresh."""
    master.read_state()
    return [(slave["state"], slave["al_status"]) for slave in master.slaves()]


def state_name(state: int) -> str:
    """An AL state as EtherCAT tools print it, e.g. SAFEOP+ERROR."""
    names = {1: "INIT", 2: "PREOP", 3: "BOOT", 4: "SAFEOP", 8: "OP"}
    base = names.get(state & 0x0F, f"0x{state & 0x0F:X}")
    return base + ("+ERROR" if state & 0x10 else "")


def reach_state(master: Any, state: int, joint_names: Sequence[str], *, while_waiting: Callable[[], None] | None = None,
                timeout_s: float = STATE_TIMEOUT_S) -> None:
    """Request `state` of every slave and wait for it, exchanging process data meanwhile when asked to."""
    master.write_state(state)
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if while_waiting is not None:
            while_waiting()
        if master.state_check(state, 5000) == state:
            return
    states = zip(master.slaves(), slave_states(master), strict=True)
    stuck = [(i, slave["name"], st, code) for i, (slave, (st, code)) in enumerate(states) if st != state]
    detail = "; ".join(f"slave {i} ({name}, {joint_names[i] if i < len(joint_names) else '?'}) is in "
                       f"{state_name(st)}, AL status 0x{code:04X} ({core.al_status_text(code)})"
                       for i, name, st, code in stuck)
    raise EtherCATError(
        f"the EtherCAT slaves did not reach {state_name(state)} within {timeout_s:g} s",
        what=f"every drive in {state_name(state)}",
        why=detail or "the state check timed out",
        how="read the AL status code in the drive's documentation; invalid sync manager or PDO configuration "
            "(0x001D/0x001E) means the drive rejects plem's process data; 0x001B is a watchdog (cycle too slow); "
            "power-cycle the drives and launch again")


def setup_distributed_clocks(master: Any, slaves: Sequence[SegmentSlave], cycle_time_ns: int) -> list[bool]:
    """SYNC0 at the cycle time on every slave that has distributed clocks; which slaves have them."""
    if not master.config_dc():
        return [False] * len(slaves)
    has_dc = []
    for slave in slaves:  # a slave that does not answer a register read has no usable clock
        has_dc.append(bool((slave.register(REG_ESC_FEATURES) or 0) & DC_SUPPORTED))
        if has_dc[-1]:
            master.dc_sync0(slave.position + 1, True, cycle_time_ns)
    return has_dc


def close_master(master: Any) -> None:
    """Bring every slave down to INIT (outputs off first: SAFEOP) and release the interface; never raises."""
    for state in (SAFEOP_STATE, INIT_STATE):
        try:
            master.write_state(state)
            master.state_check(state, 50000)
        except Exception:  # noqa: BLE001 - the segment may already be gone; closing goes on
            pass
    with contextlib.suppress(Exception):  # closing an interface that vanished
        master.close()


@dataclass(frozen=True)
class Segment:
    """What opening found: the master, its slaves in joint order, their rated torques and DC support."""

    master: Any
    slaves: tuple[SegmentSlave, ...]
    rated_torque: tuple[RatedTorque, ...]
    distributed_clocks: tuple[bool, ...]
    digital_inputs: tuple[bool, ...]   # per drive: it reports its digital inputs (0x60FD)


def bring_up(interface: str, joint_names: Sequence[str], drives: Sequence[DriveParameters], cycle_time_ns: int,
             first_exchange: Callable[[Any], None]) -> Segment:
    """Open `interface` and bring the arm's drives to OP; `first_exchange(master)` runs while waiting for OP.

    On any failure the slaves are brought down again and the interface released before the error is raised.
    """
    if len(drives) != len(joint_names):
        raise ConfigError("the arm has no drive parameters for EtherCAT",
                          what="encoder_resolution, gear_ratio and direction <param> tags for every joint",
                          why=f"{len(drives)} drives for {len(joint_names)} joints",
                          how="add the <param> tags to each <joint> of the description package's ros2_control "
                              "block (docs/ethercat.md), then `plem validate` the package")
    master = open_master(interface)
    try:
        find_slaves(master, interface)
        slaves = segment_slaves(master)
        check_topology(slaves, joint_names, drives)
        reach_state(master, PREOP_STATE, joint_names)
        inputs = tuple(assign_process_data(slave, position, joint_names[position])
                       for position, slave in enumerate(slaves))
        rated = tuple(rated_torque(slave, drive) for slave, drive in zip(slaves, drives, strict=True))
        master.config_map()
        slaves = segment_slaves(master)
        check_mapping(slaves, joint_names, inputs)
        dc = setup_distributed_clocks(master, slaves, cycle_time_ns)
        reach_state(master, SAFEOP_STATE, joint_names)
        first_exchange(master)
        reach_state(master, OP_STATE, joint_names, while_waiting=lambda: first_exchange(master))
        return Segment(master, slaves, rated, tuple(dc), inputs)
    except BaseException:
        close_master(master)
        raise
