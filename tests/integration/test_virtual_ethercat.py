"""The virtual EtherCAT network against the real SOEM master (pysoem) over a veth pair into a namespace.

Each test starts a fresh segment of emulated drives in a process of its own, serving a socket opened inside
the network's namespace (the master's config_map holds the GIL, so the slaves cannot live in a thread of
this process), and talks to it through a pipe to inject faults and look at the drives' arrays. Conditions
are awaited with deadlines; nothing asserts on timing.
"""

from __future__ import annotations

import contextlib
import itertools
import multiprocessing
import os
import struct
import threading
import time
from collections.abc import Callable, Iterator
from multiprocessing.connection import Connection
from typing import Any

import numpy as np
import pysoem
import pytest

from plem.fieldbus.ethercat import objects
from plem.fieldbus.ethercat.virtual.network import NamespacePermissionError, VethNamespace
from plem.fieldbus.ethercat.virtual.segment import Segment
from plem.fieldbus.ethercat.virtual.sii import SlaveIdentity
from plem.fieldbus.ethercat.virtual.stack import DEFAULT_MAPPING
from plem.fieldbus.ethercat.virtual.wire import serve

IDENTITIES = (
    SlaveIdentity(0x00000A5E, 0x00402001, 0x00010002, 1001, "Virtual servo A"),
    SlaveIdentity(0x00000A5E, 0x00402001, 0x00010002, 1002, "Virtual servo A"),
    SlaveIdentity(0x00000A5E, 0x00402003, 0x00020000, 1003, "Virtual servo B"),
)
OUTPUT_BYTES = objects.pdo_bytes(objects.RX_ENTRIES)
INPUT_BYTES = objects.pdo_bytes(objects.TX_ENTRIES)
WATCHDOG_MS = 5000                     # long enough that a stalled test process never trips it by accident
DEADLINE_S = 20.0
EPOCH_2000 = 946684800                 # EtherCAT system time counts from 2000-01-01


class FakeDrives:
    """A DriveApplication: arrays named like the PDO entries, a step that echoes outputs into inputs."""

    def __init__(self, count: int) -> None:
        self.count = count
        for entry in objects.RX_ENTRIES + objects.TX_ENTRIES + (objects.DIGITAL_INPUTS,):
            setattr(self, entry.name, np.zeros(count, dtype=entry.dtype))
        self.rated_torque = np.full(count, 2500, dtype=np.uint32)
        self.error_code[:] = 0x1000 + np.arange(count)
        self.steps = 0
        self.lost: list[int] = []

    def step(self, operational: np.ndarray) -> None:
        self.steps += 1
        self.position_actual[operational] = self.target_position[operational]
        self.velocity_actual[operational] = self.velocity_offset[operational]
        self.torque_actual[operational] = self.torque_offset[operational]
        self.statusword[operational] = self.controlword[operational]
        self.mode_display[operational] = self.mode[operational]

    def communication_lost(self, drive: int) -> None:
        self.lost.append(drive)


def _serve(link: VethNamespace, identities: tuple[SlaveIdentity, ...], connection: Connection) -> None:
    """The emulator process: a segment on the drives' end of `link`, steered by commands on `connection`."""
    with contextlib.suppress(PermissionError):              # above the master's priority
        os.sched_setscheduler(0, os.SCHED_FIFO | os.SCHED_RESET_ON_FORK, os.sched_param(20))
    drives = FakeDrives(len(identities))
    segment = Segment(identities, drives, seed=7)
    sock = link.open_drive_socket()
    stop = threading.Event()

    def command() -> None:
        name, *args = connection.recv()
        result: Any = None
        if name == "set":
            setattr(segment, *args)
        elif name in ("disappear", "reappear"):
            getattr(segment, name)(*args)
        elif name == "drives":
            result = {entry.name: getattr(drives, entry.name).tolist()
                      for entry in objects.RX_ENTRIES + objects.TX_ENTRIES}
            result.update(steps=drives.steps, lost=list(drives.lost))
        elif name == "stop":
            stop.set()
        connection.send(result)

    connection.send("ready")
    with sock:
        serve(sock, segment, stop=stop, extra={connection.fileno(): command})


class Emulator:
    """The handle on an emulator process: send it a command, get its answer."""

    def __init__(self, connection: Connection) -> None:
        self.connection = connection

    def __call__(self, *command: Any) -> Any:
        self.connection.send(command)
        assert self.connection.poll(DEADLINE_S), f"the emulator did not answer {command}"
        return self.connection.recv()


@pytest.fixture(scope="module", autouse=True)
def realtime_master() -> Iterator[None]:
    """Run the master at a real-time priority (below the emulator's), as EtherCAT masters run: on a busy host a
    preempted master would miss answers that did arrive in time. Children start with the normal policy again."""
    before = os.sched_getscheduler(0), os.sched_getparam(0)
    with contextlib.suppress(PermissionError):
        os.sched_setscheduler(0, os.SCHED_FIFO | os.SCHED_RESET_ON_FORK, os.sched_param(10))
    yield
    os.sched_setscheduler(0, *before)


@pytest.fixture(scope="module")
def network() -> Iterator[VethNamespace]:
    link = VethNamespace(1000 + os.getpid() % 90000)
    try:
        link.create()
    except NamespacePermissionError as error:
        pytest.skip(f"cannot create network namespaces here: {error.what}")
    yield link
    link.remove()


@pytest.fixture
def emulator(network: VethNamespace) -> Iterator[Emulator]:
    context = multiprocessing.get_context("spawn")
    ours, theirs = context.Pipe()
    process = context.Process(target=_serve, args=(network, IDENTITIES, theirs), daemon=True)
    process.start()
    assert ours.poll(60), "the emulator process did not start"
    assert ours.recv() == "ready"
    handle = Emulator(ours)
    yield handle
    handle("stop")
    process.join(DEADLINE_S)
    if process.is_alive():
        process.kill()


@pytest.fixture
def master(network: VethNamespace, emulator: Emulator) -> Iterator[pysoem.Master]:
    ecat = pysoem.Master()
    ecat.open(network.master_end)
    yield ecat
    ecat.close()


def until(condition: Callable[[], bool], what: str) -> None:
    """Wait for `condition` with a deadline."""
    deadline = time.monotonic() + DEADLINE_S
    while not condition():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.01)


def write_plem_mapping(slave: Any) -> None:
    """Assign plem's PDO table by SDO, as a master does in PREOP."""
    for assign, pdo, entries in ((objects.RX_ASSIGN, objects.RX_PDO, objects.RX_ENTRIES),
                                 (objects.TX_ASSIGN, objects.TX_PDO, objects.TX_ENTRIES)):
        slave.sdo_write(assign, 0, b"\x00")
        slave.sdo_write(pdo, 0, b"\x00")
        for subindex, entry in enumerate(entries, 1):
            slave.sdo_write(pdo, subindex, struct.pack("<I", entry.mapping))
        slave.sdo_write(pdo, 0, bytes([len(entries)]))
        slave.sdo_write(assign, 1, struct.pack("<H", pdo))
        slave.sdo_write(assign, 0, b"\x01")


def configure(master: pysoem.Master) -> None:
    """config_init, plem's mapping written in the PREOP hook, config_map (which asks for SAFEOP), config_dc."""
    assert master.config_init() == len(IDENTITIES)
    for slave in master.slaves:
        slave.config_func = lambda position: write_plem_mapping(master.slaves[position])
    master.config_map()
    assert master.config_dc()
    for slave in master.slaves:
        slave.set_watchdog("processdata", WATCHDOG_MS)
    reach(master, pysoem.SAFEOP_STATE)


def reach(master: pysoem.Master, state: int, *, cycling: bool = False) -> None:
    """Wait until every slave reports `state`, exchanging process data meanwhile when `cycling`."""
    def arrived() -> bool:
        if cycling:
            master.send_processdata()
            master.receive_processdata(2000)
        return master.state_check(state, 20000) == state
    until(arrived, f"state {state:#x}")


def operate(master: pysoem.Master) -> None:
    """From SAFEOP to OP the way a master does it: outputs flowing while OP is requested."""
    master.send_processdata()
    master.receive_processdata(2000)
    master.state = pysoem.OP_STATE
    master.write_state()
    reach(master, pysoem.OP_STATE, cycling=True)


def cycle(master: pysoem.Master) -> int:
    master.send_processdata()
    return master.receive_processdata(2000)


def set_outputs(master: pysoem.Master, target: int) -> None:
    """Write controlword, target position, offsets and mode of every slave, distinct per slave."""
    for number, slave in enumerate(master.slaves):
        slave.output = struct.pack("<HiihB", 0x000F, target + number, 10 * number, number, 8)


def test_config_init_finds_each_slave_with_its_identity(master: pysoem.Master) -> None:
    assert master.config_init() == len(IDENTITIES)
    assert [(s.name, s.man, s.id, s.rev) for s in master.slaves] == \
        [(i.name, i.vendor_id, i.product_code, i.revision) for i in IDENTITIES]
    reach(master, pysoem.PREOP_STATE)
    serial = master.slaves[2].sdo_read(objects.IDENTITY, 4)
    assert struct.unpack("<I", serial)[0] == IDENTITIES[2].serial
    assert master.slaves[0].sdo_read(objects.DEVICE_NAME, 0).decode() == IDENTITIES[0].name
    assert struct.unpack("<I", master.slaves[0].sdo_read(objects.DEVICE_TYPE, 0))[0] == objects.CIA402_DEVICE_TYPE


def test_without_the_assignment_the_drives_own_mapping_applies(master: pysoem.Master) -> None:
    assert master.config_init() == len(IDENTITIES)
    master.config_map()
    own = (objects.pdo_bytes(DEFAULT_MAPPING[objects.RX_PDO]), objects.pdo_bytes(DEFAULT_MAPPING[objects.TX_PDO]))
    assert own != (OUTPUT_BYTES, INPUT_BYTES)
    assert [(len(s.output), len(s.input)) for s in master.slaves] == [own] * len(IDENTITIES)


def test_mapping_written_in_preop_gives_plems_process_image(master: pysoem.Master) -> None:
    configure(master)
    assert [(len(s.output), len(s.input)) for s in master.slaves] == [(OUTPUT_BYTES, INPUT_BYTES)] * len(IDENTITIES)
    assert master.expected_wkc == 3 * len(IDENTITIES)


def test_cyclic_exchange_in_op_reaches_the_drives_and_comes_back(master: pysoem.Master, emulator: Emulator) -> None:
    configure(master)
    operate(master)
    steps_before = emulator("drives")["steps"]
    dc_times = []
    for target in range(300):
        set_outputs(master, 1000 * target)
        assert cycle(master) == master.expected_wkc
        dc_times.append(master.dc_time)
    assert cycle(master) == master.expected_wkc            # inputs answer the previous frame's outputs
    drives = emulator("drives")
    assert drives["steps"] - steps_before == 301
    assert drives["target_position"] == [299000 + n for n in range(len(IDENTITIES))]
    assert drives["velocity_offset"] == [10 * n for n in range(len(IDENTITIES))]
    assert drives["torque_offset"] == list(range(len(IDENTITIES)))
    assert drives["mode"] == [8] * len(IDENTITIES)
    for number, slave in enumerate(master.slaves):
        statusword, position, velocity, torque, error_code, mode = struct.unpack("<HiihHb", slave.input)
        assert (statusword, position, velocity, torque, mode) == (0x000F, 299000 + number, 10 * number, number, 8)
        assert error_code == 0x1000 + number
        assert struct.unpack("<i", slave.sdo_read(0x6064, 0))[0] == 299000 + number
    assert struct.unpack("<I", master.slaves[0].sdo_read(objects.RATED_TORQUE, 0))[0] == 2500
    # The reference clock (FRMW of 0x0910 in every frame) runs, set by config_dc to nanoseconds since 2000.
    assert all(earlier < later for earlier, later in itertools.pairwise(dc_times))
    assert abs(dc_times[-1] / 1e9 - (time.time() - EPOCH_2000)) < 3600


def test_bad_sdo_requests_are_refused_with_their_abort_codes(master: pysoem.Master) -> None:
    assert master.config_init() == len(IDENTITIES)
    reach(master, pysoem.PREOP_STATE)
    slave = master.slaves[0]

    def abort_code(action: Callable[[], object]) -> int:
        with pytest.raises(pysoem.SdoError) as refused:
            action()
        return refused.value.abort_code

    slave.sdo_write(objects.RX_PDO, 0, b"\x00")
    controlword_as_32_bits = struct.pack("<I", 0x6040 << 16 | 32)
    statusword = struct.pack("<I", objects.TX_ENTRIES[0].mapping)
    assert abort_code(lambda: slave.sdo_write(objects.RX_PDO, 1, controlword_as_32_bits)) == 0x06040041
    assert abort_code(lambda: slave.sdo_write(objects.RX_PDO, 1, statusword)) == 0x06040041
    assert abort_code(lambda: slave.sdo_write(objects.TX_PDO, 1, statusword)) == 0x06010003    # 0x1A00:0 is not 0
    assert abort_code(lambda: slave.sdo_read(0x2000, 0)) == 0x06020000
    assert abort_code(lambda: slave.sdo_write(objects.DEVICE_TYPE, 0, b"\x00\x00\x00\x00")) == 0x06010002
    assert abort_code(lambda: slave.sdo_write(0x6040, 0, b"\x00\x00\x00\x00")) == 0x06070010
    slave.sdo_write(0x6040, 0, b"\x06\x00")
    assert slave.sdo_read(0x6040, 0) == b"\x06\x00"


def test_pdo_assignment_is_writable_in_preop_only(master: pysoem.Master) -> None:
    configure(master)
    with pytest.raises(pysoem.SdoError) as refused:
        master.slaves[1].sdo_write(objects.RX_ASSIGN, 0, b"\x00")
    assert refused.value.abort_code == 0x08000022


def test_a_sync_manager_length_that_does_not_fit_the_mapping_is_refused(master: pysoem.Master) -> None:
    configure(master)
    master.state = pysoem.PREOP_STATE
    master.write_state()
    reach(master, pysoem.PREOP_STATE)
    outputs, inputs = master.slaves[0], master.slaves[1]
    outputs.sdo_write(objects.RX_PDO, 0, bytes([len(objects.RX_ENTRIES) - 1]))     # SM2 keeps the old length
    inputs.sdo_write(objects.TX_PDO, 0, bytes([len(objects.TX_ENTRIES) - 1]))
    master.state = pysoem.SAFEOP_STATE
    master.write_state()
    until(lambda: master.read_state() and outputs.al_status == 0x001D and inputs.al_status == 0x001E,
          "AL status codes 0x001D and 0x001E")
    assert outputs.state == inputs.state == pysoem.PREOP_STATE | 0x10
    assert master.slaves[2].state == pysoem.SAFEOP_STATE
    outputs.state = pysoem.PREOP_STATE | 0x10                                     # acknowledge the error
    outputs.write_state()
    until(lambda: outputs.state_check(pysoem.PREOP_STATE, 20000) == pysoem.PREOP_STATE and outputs.al_status == 0,
          "the acknowledged error to clear")


def test_watchdog_expires_when_cyclic_frames_stop(master: pysoem.Master, emulator: Emulator) -> None:
    configure(master)
    operate(master)
    for slave in master.slaves:
        slave.set_watchdog("processdata", 50)
    for target in range(20):
        set_outputs(master, target)
        cycle(master)
    until(lambda: master.read_state() == pysoem.SAFEOP_STATE and all(s.al_status == 0x001B for s in master.slaves),
          "the sync-manager watchdog to expire")
    assert all(s.state == pysoem.SAFEOP_STATE | 0x10 for s in master.slaves)
    until(lambda: sorted(emulator("drives")["lost"]) == list(range(len(IDENTITIES))), "communication_lost calls")


def test_leaving_op_tells_the_drives(master: pysoem.Master, emulator: Emulator) -> None:
    configure(master)
    operate(master)
    master.state = pysoem.SAFEOP_STATE
    master.write_state()
    reach(master, pysoem.SAFEOP_STATE)
    assert sorted(emulator("drives")["lost"]) == list(range(len(IDENTITIES)))


def test_dropped_frames_show_in_the_working_counter(master: pysoem.Master, emulator: Emulator) -> None:
    configure(master)
    operate(master)
    emulator("set", "drop_rate", 0.5)
    counters = [cycle(master) for _ in range(60)]
    emulator("set", "drop_rate", 0.0)
    assert any(wkc != master.expected_wkc for wkc in counters)
    assert any(wkc == master.expected_wkc for wkc in counters)
    until(lambda: cycle(master) == master.expected_wkc, "the working counter to recover")


def test_late_answers_are_missed(master: pysoem.Master, emulator: Emulator) -> None:
    configure(master)
    operate(master)
    emulator("set", "delay_s", 0.05)
    assert cycle(master) < 0                                                       # SOEM's EC_NOFRAME
    emulator("set", "delay_s", 0.0)
    until(lambda: cycle(master) == master.expected_wkc, "answers in time again")


def test_a_disappeared_slave_is_missing_from_the_working_counter(master: pysoem.Master, emulator: Emulator) -> None:
    configure(master)
    operate(master)
    assert cycle(master) == master.expected_wkc
    emulator("disappear", 1)
    assert cycle(master) == master.expected_wkc - 3
    emulator("reappear", 1)
    until(lambda: cycle(master) == master.expected_wkc, "the slave to count again")


def test_sdo_information_lists_the_object_dictionary_through_soems_own_reader(master: pysoem.Master) -> None:
    """pysoem's `od` is SOEM's ecx_readODlist, ecx_readODdescription and ecx_readOE: what `slaveinfo -sdo` uses."""
    assert master.config_init() == len(IDENTITIES)
    reach(master, pysoem.PREOP_STATE)
    dictionary = {obj.index: obj for obj in master.slaves[0].od}
    assert {objects.DEVICE_TYPE, objects.IDENTITY, objects.RX_PDO, objects.TX_ASSIGN, objects.RATED_TORQUE,
            *(entry.index for entry in objects.RX_ENTRIES + objects.TX_ENTRIES)} <= set(dictionary)
    assert all(obj.name.decode() == objects.NAMES[index] for index, obj in dictionary.items())
    device_type, identity = dictionary[objects.DEVICE_TYPE], dictionary[objects.IDENTITY]
    assert (device_type.object_code, device_type.data_type, device_type.bit_length) == (0x07, 0x0007, 32)
    assert (identity.object_code, identity.data_type) == (0x09, 0x0023)
    assert [(e.name.decode(), e.data_type, e.bit_length) for e in identity.entries] == [
        ("Number of entries", 0x0005, 8), ("Vendor ID", 0x0007, 32), ("Product code", 0x0007, 32),
        ("Revision number", 0x0007, 32), ("Serial number", 0x0007, 32)]
    target, statusword = dictionary[0x607A], dictionary[0x6041]
    assert (target.data_type, target.bit_length, target.obj_access) == (0x0004, 32, 0x007F)   # rw, RxPDO-mappable
    assert (statusword.data_type, statusword.bit_length, statusword.obj_access) == (0x0006, 16, 0x0087)
    assert dictionary[objects.DEVICE_NAME].bit_length == 8 * len(IDENTITIES[0].name)
