"""The EtherCAT bring-up's checks on stand-in slaves: topology, PDO assignment, mapping sizes, EtherLab default."""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from plem.control.compiled import core
from plem.description.drives import DriveParameters
from plem.fieldbus.ethercat import objects
from plem.fieldbus.ethercat.bringup import (
    EtherCATError,
    RatedTorque,
    assign_process_data,
    check_mapping,
    check_topology,
    default_interface,
    per_mille_warning,
    rated_torque,
)
from plem.fieldbus.ethercat.master import torque_units

NO_OBJECT = (0x06020000, "The object does not exist in the object directory")

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
    rated_torque_mnm: int | None = 3562        # None: no object 0x6076

    def sdo_write(self, index: int, subindex: int, data: bytes) -> None:
        if (index, subindex) == self.refuse:
            raise core.SdoError(0x06040041, "Object can not be mapped into the PDO")
        self.written.append((index, subindex, data))

    device_type: int = objects.CIA402_DEVICE_TYPE

    def sdo_read(self, index: int, subindex: int) -> bytes:
        if index == objects.RATED_TORQUE and self.rated_torque_mnm is None:
            raise core.SdoError(*NO_OBJECT)
        return struct.pack("<I", self.device_type if index == objects.DEVICE_TYPE else self.rated_torque_mnm)


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
    assign_process_data(slave, 0, "joint0")
    assert rated_torque(slave, DRIVES[0]) == RatedTorque(3.562, "0x6076:0 (Rated torque)")
    rx = [struct.unpack("<I", data)[0] for index, sub, data in slave.written if index == objects.RX_PDO and sub > 0]
    assert rx == [entry.mapping for entry in objects.RX_ENTRIES]
    assert (objects.RX_ASSIGN, 1, struct.pack("<H", objects.RX_PDO)) in slave.written
    assert slave.written[-1] == (0x6060, 0, struct.pack("<b", 8))


def test_the_digital_inputs_are_mapped_after_the_inputs_where_the_drive_takes_them():
    slave = Slave()
    assert assign_process_data(slave, 0, "joint0")
    tx = [(sub, data) for index, sub, data in slave.written if index == objects.TX_PDO]
    assert tx[-2:] == [(len(objects.TX_ENTRIES) + 1, struct.pack("<I", objects.DIGITAL_INPUTS.mapping)),
                       (0, bytes([len(objects.TX_ENTRIES) + 1]))]
    refusing = Slave(refuse=(objects.TX_PDO, len(objects.TX_ENTRIES) + 1))
    assert not assign_process_data(refusing, 0, "joint0")   # runs without them
    assert (objects.TX_PDO, 0, bytes([len(objects.TX_ENTRIES)])) in refusing.written
    check_mapping([Slave(inputs=objects.pdo_bytes(objects.TX_ENTRIES) + 4), Slave()], JOINTS, [True, False])
    with pytest.raises(EtherCATError):
        check_mapping([Slave(), Slave()], JOINTS, [True, False])


def test_a_slave_that_is_not_a_cia402_drive_is_named():
    with pytest.raises(EtherCATError) as caught:
        assign_process_data(Slave(device_type=0x00001389), 0, "joint0")
    assert caught.value.summary == "slave 0 (drive, joint0) is not a CiA402 drive" and "5001" in caught.value.why


def test_a_refused_object_names_slave_joint_object_its_purpose_and_the_abort_code_with_its_text():
    with pytest.raises(EtherCATError) as caught:
        assign_process_data(Slave(refuse=(objects.RX_PDO, 4)), 1, "joint1")
    assert "slave 1 (drive, joint1) refused object 0x1600:4 (RxPDO mapping 1)" in caught.value.summary
    assert "to map plem's outputs" in caught.value.what
    assert caught.value.why == "SDO abort 0x06040041: Object can not be mapped into the PDO"
    with pytest.raises(EtherCATError) as caught:
        assign_process_data(Slave(refuse=(0x6060, 0)), 0, "joint0")
    assert "0x6060:0 (Modes of operation)" in caught.value.summary and "cyclic synchronous position" in \
        caught.value.what


def test_a_drive_without_rated_torque_runs_in_per_mille_said_once_with_the_fix():
    missing = [rated_torque(Slave(rated_torque_mnm=None), drive) for drive in DRIVES]
    assert all(r.newton_metres is None for r in missing)
    assert missing[0].source == ("reading 0x6076:0 (Rated torque) failed: SDO abort 0x06020000: The object does "
                                 "not exist in the object directory")
    assert rated_torque(Slave(rated_torque_mnm=0), DRIVES[0]).newton_metres is None
    warning = per_mille_warning(JOINTS, missing)
    assert warning is not None and warning.count("0x6076") == 1
    assert "effort of joint0, joint1 is in per mille" in warning and '<param name="rated_torque">' in warning
    # one unit of 0x6077 is one per mille, signed by the drive's direction; no torque is sent to these drives
    assert torque_units(missing, DRIVES) == [1.0, -1.0]


def test_the_package_rated_torque_comes_before_the_drive_and_gives_newton_metres():
    given = DriveParameters(65536, 101.0, -1, rated_torque=2.5)
    assert rated_torque(Slave(rated_torque_mnm=None), given) == RatedTorque(2.5, "the package's rated_torque")
    known = [rated_torque(Slave(), DRIVES[0]), rated_torque(Slave(), given)]
    assert per_mille_warning(JOINTS, known) is None
    assert torque_units(known, (DRIVES[0], given)) == pytest.approx([3.562e-3 * 121, -2.5e-3 * 101])


def test_a_mapping_of_another_size_is_named():
    with pytest.raises(EtherCATError) as caught:
        check_mapping([Slave(), Slave(outputs=9)], JOINTS, [False, False])
    assert caught.value.summary == "slave 1 (drive, joint1) mapped 9 output and 15 input bytes"


def test_an_etherlab_configuration_names_the_default_interface(tmp_path: Path):
    conf = tmp_path / "ethercat.conf"
    conf.write_text('MASTER0_DEVICE="enp3s0"  # the robot\nMASTER1_DEVICE=""\n')
    assert default_interface(0, conf) == "enp3s0"
    assert default_interface(1, conf) is None
    assert default_interface(0, tmp_path / "missing.conf") is None
