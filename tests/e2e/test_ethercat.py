"""The real EtherCAT master path end to end: `plem ethercat simulate` (the virtual network), `plem ethercat scan`,
`plem launch bus:=ethercat` on it, calibration, motion, injected faults, and the errors of a wrong setup."""

from __future__ import annotations

import contextlib
import json
import os
import re
import shutil
import signal
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from plem.bridge.client import RobotClient, connect
from plem.control.events import EventKind
from plem.control.reactions import Measure, Record
from plem.core.paths import BUILTIN_PACKAGES_DIR
from plem.errors import CommandRejected
from plem.fieldbus.ethercat.virtual.emulator import Control
from tests.e2e.cli import plem_executable, run_plem
from tests.e2e.launched import Launch, clean_environment, launched, new_robot_id, process_gone, read_line, wait_until

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
        client.set_mode("free_drive")   # gravity feed-forward through the drives' torque offset (0x60B2)
        assert wait_until(lambda: network.control.state()["torque_offsets"][1] != 0, 10)
        client.set_mode("hold")
        assert faults(client) == []
        pid = launch.driver_pids()[launch.robot_id]
        assert launch.stop() == 0, launch.describe()
        assert wait_until(lambda: process_gone(pid), 10)
    statuswords = network.control.state()["statuswords"]
    assert all(sw & 0x6F == 0x40 or sw & 0x4F == 0x40 for sw in statuswords), [hex(sw) for sw in statuswords]


def test_direction_gear_and_resolution_of_the_package_reach_the_drives(home: Path, tmp_path: Path):
    package = tmp_path / "indy7_v2_description"
    shutil.copytree(BUILTIN_PACKAGES_DIR / "indy7_v2_description", package)
    xacro = package / "urdf" / "indy7_v2.ros2_control.xacro"
    blocks = xacro.read_text().split("<joint ")
    blocks[2] = blocks[2].replace('<param name="direction">1</param>', '<param name="direction">-1</param>')
    blocks[3] = (blocks[3].replace('<param name="encoder_resolution">65536</param>',
                                   '<param name="encoder_resolution">131072</param>')
                 .replace('<param name="gear_ratio">121</param>', '<param name="gear_ratio">50</param>'))
    xacro.write_text("<joint ".join(blocks))
    network = Network([f"description_package:={package}", "master_index:=43"], home)
    try:
        robot_id = new_robot_id()
        with launched(["bus:=ethercat", f"eth_interface:={network.interface}", f"robot_id:={robot_id}",
                       f"description_package:={package}", "bridge:=false", "record:=false"], [robot_id], tmp_path,
                      clean_environment(home)) as launch, connect(robot_id) as client:
            client.set_mode("hold")
            target = [0.1, 0.3, -0.25, 0.0, 0.1, 0.0]
            client.move_joints(target).wait(30)
            wait_until(lambda: np.max(np.abs(client.state().velocity)) < 1e-4, 10)
            state = network.control.state()
            assert np.allclose(state["positions"], target, atol=2e-4), state["positions"]
            assert np.allclose(client.state().position, state["positions"], atol=1e-5)
            counts = np.array(state["position_actual"])
            assert counts[1] == pytest.approx(-0.3 * 65536 * 121 / (2 * np.pi), abs=400)
            assert counts[2] == pytest.approx(-0.25 * 131072 * 50 / (2 * np.pi), abs=400)
            # the drives' torques reach the core as joint torques: a push on the reversed joint is felt as itself
            network.control.request("push", drive=1, torque=150.0)
            [fault] = fault_events(client)
            assert fault.cause == "contact" and "the external torque on joint1 is 1" in fault.reason, fault.reason
            assert launch.stop() == 0
    finally:
        network.close()


def test_calibration_on_the_simulated_arm_refuses_a_moving_arm(home: Path, tmp_path: Path):
    robot_id = new_robot_id()
    with launched(["bus:=mock", f"robot_id:={robot_id}", "bridge:=false", "record:=false"], [robot_id], tmp_path,
                  clean_environment(home)), connect(robot_id) as client:
        client.set_mode("hold")
        # slow and long, so it still runs however long the command takes to start on a busy machine
        handle = client.move_joints([2.5, 0.0, 0.0, 0.0, 0.0, 0.0], speed_scale=0.02)
        assert wait_until(lambda: abs(client.state().velocity[0]) > 0.005, 30)
        moving = run_plem("profile", "calibrate", "--serial", "MOCK01", "--robot-id", robot_id,
                          env=clean_environment(home))
        assert not handle.done, "the motion ended before the command looked: nothing was tested"
        assert moving.returncode == 1 and "is moving" in moving.stderr, moving.stdout + moving.stderr
        handle.cancel()
        assert wait_until(lambda: handle.done and np.max(np.abs(client.state().velocity)) < 1e-4, 30)
        done = run_plem("profile", "calibrate", "--serial", "MOCK01", "--robot-id", robot_id,
                        env=clean_environment(home))
        assert done.returncode == 0, done.stderr
        raw = client.stats()["encoders"]
    offsets = json.loads((home / "profiles" / "MOCK01.json").read_text())["joint_offsets"]
    assert offsets == [-x for x in raw] and offsets[0] < -0.005 * 65536 * 121 / (2 * np.pi)   # joint0 moved +


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


# -- injected faults -----------------------------------------------------------------------------------------------
def fault_events(client: RobotClient, timeout: float = 10.0) -> list:
    """Fault events so far, waiting up to `timeout` for the first."""
    found: list = []
    wait_until(lambda: bool(found.extend(faults(client)) or found), timeout)
    return found


def slow_motion(client: RobotClient, joint: int, distance: float) -> None:
    """Start a motion of one joint (rad) at a tenth of the speed limit, without waiting for it."""
    target = client.state().position.copy()
    target[joint] += distance
    client.move_joints(target, speed_scale=0.1)


def assert_no_jump(client: RobotClient, seconds: float = 0.5) -> None:
    """Over `seconds` of cycles no joint's measured position moves more than a still arm's noise per cycle."""
    samples = [state.position.copy() for state in _states(client, seconds)]
    steps = np.abs(np.diff(np.array(samples), axis=0))
    assert steps.max() < 1e-3, steps.max()


def _states(client: RobotClient, seconds: float) -> Iterator:
    cycle = 0
    end = client.state().cycle + round(seconds / PERIOD_S)
    while cycle < end:
        state = client.wait_for_state(1.0, after_cycle=cycle)
        assert state is not None
        cycle = state.cycle
        yield state


@contextlib.contextmanager
def enabled_launch(network: Network, home: Path, tmp_path: Path) -> Iterator[tuple[Launch, RobotClient]]:
    with launch_on(network, home, tmp_path) as launch, connect(launch.robot_id) as client:
        client.set_mode("hold")
        yield launch, client


def whole_line_answers_since(client: RobotClient, since_ns: int) -> bool:
    """A statistics record taken after `since_ns` counts every slave: a record from before a slave left the line
    would count them all too."""
    stats = client.stats() or {}
    bus = stats.get("bus", {})
    return stats.get("monotonic_ns", 0) > since_ns and bus.get("working_counter") == bus.get(
        "expected_working_counter")


def reset_once_stopped(client: RobotClient, timeout: float = 10.0) -> bool:
    """Reset the fault as soon as the driver takes it: the stop that follows a fault runs to its end first, which on
    a busy machine may be a little after the arm's measured velocity reads zero."""
    def reset() -> bool:
        try:
            client.reset_fault()
        except CommandRejected as refused:
            if "while the arm moves" not in refused.summary:
                raise
            return False
        return True

    return bool(wait_until(reset, timeout, period=0.05))


def test_drive_fault_is_named_stops_the_arm_and_reset_reenables_without_a_jump(network, home, tmp_path):
    with enabled_launch(network, home, tmp_path) as (launch, client):
        slow_motion(client, 1, 0.3)
        wait_until(lambda: abs(client.state().velocity[1]) > 0.01, 10)
        network.control.request("drive_fault", drive=2, code=0x7121)
        events = fault_events(client)
        assert events and events[0].cause == "drive_fault", events
        assert "joint2" in events[0].reason and "0x7121" in events[0].reason, events[0].reason
        assert wait_until(lambda: np.max(np.abs(client.state().velocity)) < 1e-3, 10)
        assert reset_once_stopped(client)
        client.set_mode("hold")
        assert_no_jump(client)
        state = client.state()
        assert np.allclose(state.command_position, state.position, atol=1e-3)


def test_a_drive_that_refuses_to_enable_is_named(network, home, tmp_path):
    with launch_on(network, home, tmp_path) as launch, connect(launch.robot_id) as client:
        network.control.request("refuse_enable", drive=4, refuse=True)
        try:
            with pytest.raises(Exception) as caught:
                client.set_mode("hold")
        finally:
            network.control.request("refuse_enable", drive=4, refuse=False)
        assert "did not enable" in str(caught.value) and "joint4" in str(caught.value)


def test_a_digital_input_a_drive_reports_fires_a_reaction(network, home, tmp_path):
    with enabled_launch(network, home, tmp_path) as (launch, client):
        client.on(Measure.digital_input("joint5", 16) == 1, Record(), once=True)
        network.control.request("inputs", drive=5, value=1 << 16)
        try:
            assert wait_until(lambda: any(e.kind is EventKind.REACTION
                                          for e in client.events(timeout=0, from_oldest=True)), 10)
        finally:
            network.control.request("inputs", drive=5, value=0)
        [fired] = [e for e in client.events(timeout=0, from_oldest=True) if e.kind is EventKind.REACTION]
        assert "digital input 16 of joint5 == 1" in fired.reason


def test_lost_frames_are_counted_and_alone_do_not_fault(network, home, tmp_path):
    """Not even during motions, where the drives catch up after each lost frame with an acceleration the command
    did not have: the contact stop (here at a tenth of the effort limits) waits for them to settle. At half speed,
    so that the emulated drives, which step only on frames, catch up two lost frames in a row within the encoders'
    plausible jump."""
    with launch_on(network, home, tmp_path, "contact_share:=0.1") as launch, connect(launch.robot_id) as client:
        client.set_mode("hold")
        network.control.request("drop_rate", rate=0.05)
        try:
            for target in ([0.5, 0.6, -0.5, 0.3, 0.4, 0.2], [0.0] * 6, [0.5, 0.6, -0.5, 0.3, 0.4, 0.2]):
                client.move_joints(target, speed_scale=0.5).wait(30)
            assert wait_until(lambda: (client.stats() or {}).get("bus", {}).get("lost_frames", 0) >= 5, 20)
        finally:
            network.control.request("drop_rate", rate=0.0)
        assert faults(client) == []
        assert client.state().mode.name == "HOLD"


def test_a_slave_that_disappears_faults_naming_it_and_reset_recovers(network, home, tmp_path):
    with enabled_launch(network, home, tmp_path) as (launch, client):
        network.control.request("disappear", slave=3)
        try:
            events = fault_events(client)
        finally:
            network.control.request("reappear", slave=3)
            back_ns = time.monotonic_ns()
        assert events[0].cause == "communication_lost" and "slave 3" in events[0].reason, events[0].reason
        assert wait_until(lambda: whole_line_answers_since(client, back_ns), 10)
        assert reset_once_stopped(client)
        client.set_mode("hold")
        assert_no_jump(client)


def test_a_master_killed_leaves_the_drives_stopping_on_their_watchdog(network, home, tmp_path):
    with enabled_launch(network, home, tmp_path) as (launch, client):
        slow_motion(client, 0, 0.5)
        wait_until(lambda: abs(client.state().velocity[0]) > 0.01, 10)
        os.kill(launch.driver_pids()[launch.robot_id], signal.SIGKILL)
        assert wait_until(lambda: all(sw & 0x6F == 0x07 for sw in network.control.state()["statuswords"]), 10), \
            [hex(sw) for sw in network.control.state()["statuswords"]]
        assert wait_until(lambda: max(abs(v) for v in network.control.state()["velocities"]) < 1e-6, 10)


def test_robots_of_one_launch_on_one_master_index_are_refused(home: Path, tmp_path: Path):
    robots = tmp_path / "robots.yaml"
    robots.write_text("robots:\n"
                      "  - {robot_id: left, bus: ethercat, eth_interface: eth0, master_index: 0}\n"
                      "  - {robot_id: right, bus: ethercat, eth_interface: eth1, master_index: 0}\n")
    result = run_plem("launch", f"robots:={robots}", env=clean_environment(home))
    assert result.returncode == 1
    assert "robots left and right both use master_index 0" in result.stderr


def test_without_raw_socket_permission_the_fix_is_named(network: Network):
    from tests.e2e.launched import as_nobody, system_python

    if system_python() is None:
        pytest.skip("no system interpreter that user nobody can run")
    process = as_nobody("""
        import sys
        from plem.cli.app import run
        sys.exit(run(["ethercat", "scan", sys.argv[1]]))
    """, network.interface)
    _, errors = process.communicate(timeout=60)
    assert process.returncode == 1, errors
    assert "no permission to open" in errors and "CAP_NET_RAW" in errors and "setcap" in errors


def test_one_launch_brings_up_the_virtual_network_and_the_real_master_and_stops_cleanly(home: Path, tmp_path: Path):
    robot_id = new_robot_id()
    with launched(["bus:=ethercat_sim", "master_index:=42", f"robot_id:={robot_id}", "bridge:=false",
                   "record:=false"], [robot_id], tmp_path, clean_environment(home)) as launch, \
            connect(robot_id) as client:
        assert re.search(r"ethercat_sim\s+running, pid \d+, 6 emulated drives behind plemec42", launch.output)
        assert "bus ethercat_sim" in launch.output
        client.set_mode("hold")
        target = [0.1, 0.1, -0.1, 0.2, 0.0, -0.2]
        client.move_joints(target).wait(30)
        assert np.allclose(client.state().position, target, atol=2e-4)
        far = client.state().position.copy()
        far[0] -= 2.0
        client.move_joints(far)   # Ctrl-C at speed: stopping the arm within its limits takes the driver ~0.5 s
        assert wait_until(lambda: abs(client.state().velocity[0]) > 1.0, 10)
        assert launch.stop() == 0, launch.describe()
    # the driver stopped the arm and disabled the drives over the network, which went away only after the driver
    stopping = launch.output.split("stopping:")[1]
    assert "HOLD→IDLE" in stopping and "→FAULT" not in stopping, launch.describe()
    assert not Path("/sys/class/net/plemec42").exists()


def test_inject_reads_the_true_state_and_refuses_what_it_cannot_do(network: Network):
    state = run_plem("ethercat", "inject", "state", f"--index={INDEX}")
    assert state.returncode == 0, state.stderr
    assert len(json.loads(state.stdout)["positions"]) == 6
    unknown = run_plem("ethercat", "inject", "meltdown", f"--index={INDEX}")
    assert unknown.returncode == 2 and "one of drive-fault" in unknown.stderr
    garbage = run_plem("ethercat", "inject", "drop-frames", "rate=lots", f"--index={INDEX}")
    assert garbage.returncode == 2 and "'rate=lots' has no usable value" in garbage.stderr
    wrong = run_plem("ethercat", "inject", "drive-fault", "drive=17", "code=0x7121", f"--index={INDEX}")
    assert wrong.returncode == 1 and "refused drive_fault" in wrong.stderr


# -- drives as they are --------------------------------------------------------------------------------------------
def test_drives_without_rated_torque_run_in_per_mille_said_once(home: Path, tmp_path: Path):
    network = Network(["robot_type:=indy7_v2", "master_index:=44", "--missing-object", "0x6076",
                       "--missing-object", "0x60FD"], home)
    try:
        robot_id = new_robot_id()
        with launched(["bus:=ethercat", f"eth_interface:={network.interface}", f"robot_id:={robot_id}",
                       "robot_type:=indy7_v2", "master_index:=44", "bridge:=false", "record:=false"], [robot_id],
                      tmp_path, clean_environment(home)) as launch, connect(robot_id) as client:
            said = launch.output + launch.errors
            assert said.count("is in per mille of each drive's rated torque") == 1, launch.describe()
            assert "effort of joint0, joint1, joint2, joint3, joint4, joint5" in said
            assert "0x6076:0 (Rated torque)" in said and "SDO abort 0x06020000" in said
            assert '<param name="rated_torque">' in said
            client.set_mode("hold")
            target = [0.1, -0.2, 0.2, 0.0, 0.1, 0.0]
            client.move_joints(target).wait(30)
            assert np.allclose(client.state().position, target, atol=2e-4)
            # joint1 holds the arm against gravity: its reading is the drive's own, thousandths of its rated torque
            assert faults(client) == []
            assert 0 < abs(client.state().effort[1]) <= 32767
            # free drive holds the arm up with a gravity torque these drives cannot be sent: refused, arm held
            with pytest.raises(CommandRejected) as refused:
                client.set_mode("free_drive")
            assert "free drive needs each drive's rated torque" in str(refused.value)
            assert "rated_torque" in refused.value.how
            assert client.state().mode.name == "HOLD" and network.control.state()["torque_offsets"] == [0] * 6
            # nor do they map their digital inputs: a comparison on one is never true, not even == 0 (which a
            # drive reporting its inputs would make true at once)
            reaction = client.on(Measure.digital_input(5, 16) == 0, Record())
            since = client.state().cycle
            assert wait_until(lambda: client.state().cycle > since + 500, 10)
            assert not [e for e in client.events(timeout=0, from_oldest=True) if e.kind is EventKind.REACTION]
            reaction.remove()
            assert launch.stop() == 0, launch.describe()
        assert (launch.output + launch.errors).count("per mille") == 1
    finally:
        network.close()


@pytest.fixture(scope="module")
def slaveinfo(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """SOEM's own slaveinfo tool, compiled from the vendored sources as SOEM builds its test programs."""
    soem = Path(__file__).resolve().parents[2] / "third_party" / "soem"
    program = tmp_path_factory.mktemp("soem") / "slaveinfo"
    sources = [*soem.glob("soem/*.c"), soem / "osal/linux/osal.c", *soem.glob("oshw/linux/*.c")]
    includes = [f"-I{soem / d}" for d in ("soem", "osal", "osal/linux", "oshw/linux")]
    subprocess.run(["gcc", "-O1", "-w", *includes, str(soem / "test/linux/slaveinfo/slaveinfo.c"), *map(str, sources),
                    "-lpthread", "-lrt", "-o", str(program)], check=True)
    return program


def test_soems_slaveinfo_lists_the_object_dictionary(network: Network, slaveinfo: Path):
    done = subprocess.run([str(slaveinfo), network.interface, "-sdo"], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    out = done.stdout
    assert out.count("CoE Object Description found") == 6, out[-3000:]
    assert "Index: 6076 Datatype: 0007 Objectcode: 07 Name: Rated torque" in out
    assert "Index: 1018 Datatype: 0023 Objectcode: 09 Name: Identity object" in out
    assert "Name: Vendor ID" in out and "Name: Torque actual value" in out
    assert "MBX slave:" not in out and "SDO slave:" not in out, out[-3000:]   # no mailbox or SDO Information errors

