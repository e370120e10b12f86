"""The real EtherCAT master path end to end: `plem ethercat simulate` (the virtual network), `plem ethercat scan`,
`plem launch bus:=ethercat` on it, calibration, motion, injected faults, and the errors of a wrong setup."""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from plem.bridge.client import RobotClient, connect
from plem.control.events import EventKind
from plem.core.paths import BUILTIN_PACKAGES_DIR
from plem.fieldbus.ethercat.virtual.emulator import Control
from tests.e2e.cli import plem_executable, run_plem
from tests.e2e.launched import (Launch, clean_environment, launched, new_robot_id, process_gone, read_line,
                                wait_until)

pytestmark = pytest.mark.skipif(os.geteuid() != 0, reason="the virtual EtherCAT network needs root "
                                                          "(network namespaces and raw sockets)")

INDEX = 41                                  # the tests' virtual network: its own interface names
ENCODER_ZERO = (120_000, -80_000, 50_000, 0, 7_000, -3_000)
PERIOD_S = 0.001


class Network:
    """A running `plem ethercat simulate`, its interface and its control socket."""

    def __init__(self, arguments: list[str], home: Path) -> None:
        self.process = subprocess.Popen([plem_executable(), "ethercat", "simulate", *arguments],
                                        stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                        text=True, env=clean_environment(home))
        self.lines: list[str] = []
        while not any("behind" in line for line in self.lines):
            line = read_line(self.process, 60)
            if not line:
                self.process.kill()
                raise AssertionError("no virtual network:\n" + "".join(self.lines) + self.process.stderr.read())
            self.lines.append(line)
        self.interface = re.search(r"behind (\S+)", "".join(self.lines)).group(1)
        index = re.search(r"master_index:=(\d+)", " ".join(arguments))
        self.control = Control(int(index.group(1)) if index else 0)

    def close(self) -> None:
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
            try:
                self.process.wait(30)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()


@pytest.fixture(scope="module")
def home(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("ethercat_home")


@pytest.fixture(scope="module")
def network(home: Path) -> Iterator[Network]:
    zero = ",".join(str(x) for x in ENCODER_ZERO)
    running = Network(["robot_type:=indy7_v2", f"master_index:={INDEX}", f"--encoder-zero={zero}"], home)
    try:
        yield running
    finally:
        running.close()
    assert not Path(f"/sys/class/net/{running.interface}").exists(), "the virtual network was not removed"


def launch_on(network: Network, home: Path, tmp_path: Path, *extra: str) -> Launch:
    robot_id = new_robot_id()
    return launched(["bus:=ethercat", f"eth_interface:={network.interface}", f"master_index:={INDEX}",
                     f"robot_id:={robot_id}", "robot_type:=indy7_v2", "bridge:=false", "record:=false", *extra],
                    [robot_id], tmp_path, clean_environment(home))


def faults(client: RobotClient) -> list:
    return [event for event in client.events(timeout=0, from_oldest=True) if event.kind is EventKind.FAULT]


# -- scan ---------------------------------------------------------------------------------------------------------
def test_scan_lists_every_emulated_drive(network: Network):
    result = run_plem("ethercat", "scan", network.interface, "--format", "json")
    assert result.returncode == 0, result.stderr
    slaves = json.loads(result.stdout)["slaves"]
    assert [s["position"] for s in slaves] == list(range(6))
    assert all(s["name"] == "plem virtual CiA402 drive" and s["coe"] and s["state"] in ("INIT", "PREOP")
               for s in slaves)
    text = run_plem("ethercat", "scan", network.interface)
    assert text.returncode == 0 and "0x00000402" in text.stdout


# -- bring-up, calibration, motion ---------------------------------------------------------------------------------
def test_bring_up_calibrate_move_free_drive_and_stop(network: Network, home: Path, tmp_path: Path):
    with launch_on(network, home, tmp_path) as launch, connect(launch.robot_id) as client:
        assert "bus ethercat" in launch.output
        assert wait_until(lambda: (client.stats() or {}).get("encoders") is not None, 10)
        assert client.stats()["encoders"] == list(ENCODER_ZERO)
        counts_per_radian = 65536 * np.array([121, 121, 121, 101, 101, 101]) / (2 * np.pi)
        assert np.allclose(client.state().position, np.array(ENCODER_ZERO) / counts_per_radian, atol=1e-9)
        result = run_plem("profile", "calibrate", "--serial", "VIRT001", "--robot-id", launch.robot_id,
                          env=clean_environment(home))
        assert result.returncode == 0, result.stderr
        assert "robot_serial:=VIRT001" in result.stdout
    profile = json.loads((home / "profiles" / "VIRT001.json").read_text())
    assert profile["joint_offsets"] == [-x for x in ENCODER_ZERO]

    with launch_on(network, home, tmp_path, "robot_serial:=VIRT001") as launch, connect(launch.robot_id) as client:
        assert np.max(np.abs(client.state().position)) < 1e-6
        client.set_mode("hold")
        target = [0.2, -0.15, 0.1, 0.3, -0.2, 0.25]
        client.move_joints(target).wait(30)
        wait_until(lambda: np.max(np.abs(client.state().velocity)) < 1e-4, 10)
        measured = client.state().position
        true = np.array(network.control.state()["positions"])
        assert np.allclose(measured, target, atol=2e-4), measured
        assert np.allclose(true, measured, atol=1e-5), (true, measured)
        client.set_mode("free_drive")
        client.set_mode("hold")
        assert faults(client) == []
        pid = launch.driver_pids()[launch.robot_id]
        assert launch.stop() == 0, launch.describe()
        assert wait_until(lambda: process_gone(pid), 10)
    statuswords = network.control.state()["statuswords"]
    assert all(sw & 0x6F == 0x40 or sw & 0x4F == 0x40 for sw in statuswords), [hex(sw) for sw in statuswords]


# -- errors --------------------------------------------------------------------------------------------------------
def test_interface_that_does_not_exist_lists_those_that_do(home: Path):
    result = run_plem("launch", "bus:=ethercat", "eth_interface:=nosuch0", f"robot_id:={new_robot_id()}",
                      env=clean_environment(home))
    assert result.returncode == 1
    assert "Network interface does not exist: nosuch0" in result.stderr and "lo" in result.stderr


def test_loopback_is_refused(home: Path):
    result = run_plem("launch", "bus:=ethercat", "eth_interface:=lo", f"robot_id:={new_robot_id()}",
                      env=clean_environment(home))
    assert result.returncode == 1 and "loopback" in result.stderr


def test_nothing_answering_is_master_not_found(home: Path):
    subprocess.run(["ip", "link", "add", "plemtest0", "type", "veth", "peer", "name", "plemtest1"], check=True)
    try:
        for name in ("plemtest0", "plemtest1"):
            subprocess.run(["ip", "link", "set", name, "up"], check=True)
        result = run_plem("ethercat", "scan", "plemtest0", env=clean_environment(home))
        assert result.returncode == 1
        assert "EtherCAT master not found" in result.stderr and "cable" in result.stderr
    finally:
        subprocess.run(["ip", "link", "del", "plemtest0"], check=False)


def test_a_drive_with_other_ids_is_named_with_what_was_expected(network: Network, home: Path, tmp_path: Path):
    package = tmp_path / "indy7_v2_description"
    shutil.copytree(BUILTIN_PACKAGES_DIR / "indy7_v2_description", package)
    xacro = package / "urdf" / "indy7_v2.ros2_control.xacro"
    text = xacro.read_text()
    xacro.write_text(text.replace('<param name="direction">1</param>',
                                  '<param name="direction">1</param><param name="product_code">0x1234</param>', 1))
    result = run_plem("launch", "bus:=ethercat", f"eth_interface:={network.interface}", f"robot_id:={new_robot_id()}",
                      f"description_package:={package}", "bridge:=false", "record:=false",
                      env=clean_environment(home))
    assert result.returncode == 1, result.stdout
    assert "slave 0" in result.stderr and "product_code 0x00001234" in result.stderr
    assert "0x00000402" in result.stderr
