"""The EtherCAT bring-up's checks on stand-in slaves: topology, PDO assignment, mapping sizes, EtherLab default."""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from plem.description.drives import DriveParameters
from plem.fieldbus.ethercat import objects
from plem.fieldbus.ethercat.bringup import (
    EtherCATError,
    assign_process_data,
    check_mapping,
    check_topology,
    default_interface,
)

JOINTS = ("joint0", "joint1")
DRIVES = (DriveParameters(65536, 121.0, 1), DriveParameters(65536, 101.0, -1, vendor_id=0x66F, product_code=0x1))


@dataclass
class Slave:
    """What the bring-up uses of a slave on the master."""

    name: str = "drive"
    vendor_id: int = 0x66F
    product_code: int = 0x1
    revision: int = 0x10000
    outputs: int = objects.pdo_bytes(objects.RX_ENTRIES)
    inputs: int = objects.pdo_bytes(objects.TX_ENTRIES)
    refuse: tuple[int, int] | None = None
    written: list[tuple[int, int, bytes]] = field(default_factory=list)

    def sdo_write(self, index: int, subindex: int, data: bytes) -> None:
        if (index, subindex) == self.refuse:
            raise RuntimeError("Object cannot be mapped into the PDO")
        self.written.append((index, subindex, data))

    device_type: int = objects.CIA402_DEVICE_TYPE

    def sdo_read(self, index: int, subindex: int) -> bytes:
        return struct.pack("<I", self.device_type if index == objects.DEVICE_TYPE else 3562)


def test_the_slaves_must_match_the_joints_in_number_and_ids():
    check_topology([Slave(), Slave()], JOINTS, DRIVES)
    with pytest.raises(EtherCATError) as caught:
        check_topology([Slave()], JOINTS, DRIVES)
    assert "1 slaves, the arm has 2 joints" in caught.value.summary and "0: drive" in caught.value.why
    with pytest.raises(EtherCATError) as caught:
        check_topology([Slave(), Slave(product_code=0x99)], JOINTS, DRIVES)
    assert caught.value.summary == "slave 1 (drive) is not the drive of joint1"
    assert "product_code 0x00000001" in caught.value.what and "product_code 0x00000099" in caught.value.why


def test_the_pdo_assignment_is_written_in_full_and_the_rated_torque_read():
    slave = Slave()
    assert assign_process_data(slave, 0, "joint0") == 3562
    rx = [struct.unpack("<I", data)[0] for index, sub, data in slave.written if index == objects.RX_PDO and sub > 0]
    assert rx == [entry.mapping for entry in objects.RX_ENTRIES]
    assert (objects.RX_ASSIGN, 1, struct.pack("<H", objects.RX_PDO)) in slave.written
    assert slave.written[-1] == (0x6060, 0, struct.pack("<b", 8))


def test_a_slave_that_is_not_a_cia402_drive_is_named():
    with pytest.raises(EtherCATError) as caught:
        assign_process_data(Slave(device_type=0x00001389), 0, "joint0")
    assert caught.value.summary == "slave 0 (drive, joint0) is not a CiA402 drive" and "5001" in caught.value.why


def test_a_refused_object_names_slave_joint_object_and_size():
    with pytest.raises(EtherCATError) as caught:
        assign_process_data(Slave(refuse=(objects.RX_PDO, 4)), 1, "joint1")
    assert "slave 1 (drive, joint1) refused object 0x1600:4" in caught.value.summary
    assert "cannot be mapped" in caught.value.why


def test_a_mapping_of_another_size_is_named():
    with pytest.raises(EtherCATError) as caught:
        check_mapping([Slave(), Slave(outputs=9)], JOINTS)
    assert caught.value.summary == "slave 1 (drive, joint1) mapped 9 output and 15 input bytes"


def test_an_etherlab_configuration_names_the_default_interface(tmp_path: Path):
    conf = tmp_path / "ethercat.conf"
    conf.write_text('MASTER0_DEVICE="enp3s0"  # the robot\nMASTER1_DEVICE=""\n')
    assert default_interface(0, conf) == "enp3s0"
    assert default_interface(1, conf) is None
    assert default_interface(0, tmp_path / "missing.conf") is None
