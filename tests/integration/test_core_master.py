"""The core's EtherCAT master (SOEM compiled into plem.control._core) on the virtual network: an in-process robot
whose real-time thread exchanges the process data, and the master's refusals.

The virtual network is a `plem ethercat simulate` of its own (its emulated drives in another process, behind a
veth pair into a namespace). Conditions are awaited with deadlines; nothing asserts on timing.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from plem.control.compiled import core
from plem.control.core_thread import CoreThread
from plem.control.events import EventKind
from plem.control.modes import Mode
from plem.control.trajectory import TrajectoryOutcome
from plem.fieldbus.ethercat.bringup import PREOP_STATE
from plem.fieldbus.ethercat.master import EtherCATBus
from plem.fieldbus.ethercat.virtual.emulator import Control
from plem.robot import Indy7V2, Robot
from tests.e2e.cli import plem_executable
from tests.e2e.launched import clean_environment, read_line, wait_until

pytestmark = pytest.mark.skipif(os.geteuid() != 0, reason="the virtual EtherCAT network needs root "
                                                          "(network namespaces and raw sockets)")

#: A network index of this worker's own (pytest-xdist runs modules' tests in two processes).
INDEX = 70 + int(os.environ.get("PYTEST_XDIST_WORKER", "gw0").removeprefix("gw") or 0)
NO_SUCH_OBJECT = 0x06020000


@pytest.fixture(scope="module")
def interface(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    home = tmp_path_factory.mktemp("core_master_home")
    process = subprocess.Popen([plem_executable(), "ethercat", "simulate", "robot_type:=indy7_v2",
                                f"master_index:={INDEX}"], stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True, env=clean_environment(Path(home)))
    lines: list[str] = []
    while not any("behind" in line for line in lines):
        line = read_line(process, 60)
        if not line:
            process.kill()
            raise AssertionError("no virtual network:\n" + "".join(lines) + process.stderr.read())
        lines.append(line)
    try:
        yield re.search(r"behind (\S+)", "".join(lines)).group(1)
    finally:
        process.send_signal(signal.SIGINT)
        try:
            process.wait(30)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()


def ethercat_robot(interface: str) -> Robot:
    config = Indy7V2()
    config.network_interface, config.master_index = interface, INDEX
    return Robot.builder(config).build()


def test_the_core_thread_exchanges_with_the_drives_and_moves_them(interface: str):
    robot = ethercat_robot(interface)
    assert isinstance(robot.loop, CoreThread) and isinstance(robot.bus, EtherCATBus)
    master = robot.bus.core_master
    with robot:
        robot.set_mode(Mode.HOLD)
        with pytest.raises(RuntimeError, match="exchanges process data"):
            master.sdo_read(1, 0x1000, 0, 4)            # the cycle owns the master while it runs
        target = np.array([0.2, -0.15, 0.1, 0.3, -0.2, 0.25])
        result = robot.move_joints(target, speed_scale=0.5).wait(30)
        assert result.outcome is TrajectoryOutcome.SUCCEEDED, result.message
        assert wait_until(lambda: np.max(np.abs(robot.state().velocity)) < 1e-4, 10)
        true = np.array(Control(INDEX).state()["positions"])
        assert np.allclose(robot.state().position, target, atol=2e-4)
        assert np.allclose(true, robot.state().position, atol=1e-5), true
        status = robot.bus.status
        assert status.communication_ok and status.working_counter == status.expected_working_counter > 0
        exchanges = robot.bus.exchange
        assert exchanges is not None and exchanges.count >= robot.state().cycle // 2
        assert not [e for e in robot.events.recent() if e.kind is EventKind.FAULT]
    assert not master.is_open
    statuswords = Control(INDEX).state()["statuswords"]
    assert all(word & 0x4F == 0x40 for word in statuswords), [hex(word) for word in statuswords]


def test_the_master_refuses_what_it_cannot_do_in_words(interface: str):
    master = core.Master()
    with pytest.raises(RuntimeError, match="not open"):
        master.config_init()
    with pytest.raises(ConnectionError, match="plem_no_such0"):
        master.open("plem_no_such0")
    master.open(interface)
    try:
        assert master.config_init() == 6
        assert master.state_check(PREOP_STATE, 2_000_000) == PREOP_STATE
        with pytest.raises(core.SdoError) as refused:
            master.sdo_read(1, 0x2FFF, 0, 4)
        assert refused.value.args[0] == NO_SUCH_OBJECT and "not exist" in refused.value.args[1].lower()
        with pytest.raises(IndexError, match="slaves 1..6"):
            master.sdo_read(7, 0x1000, 0, 4)
        with pytest.raises(ValueError, match="prepare"):
            master.prepare([1.0] * 6, 10, 100)            # nothing mapped yet
        assert master.slaves()[0]["coe"] and master.slaves()[0]["name"]
    finally:
        master.close()
    assert not master.is_open


def test_closing_after_the_core_stops_switches_enabled_drives_off_where_they_stand(interface: str):
    robot = ethercat_robot(interface)
    robot.start()
    try:
        robot.set_mode(Mode.HOLD)
        result = robot.move_joints(np.array([0.1, 0.1, -0.1, 0.1, 0.1, 0.1]), speed_scale=0.5).wait(30)
        assert result.outcome is TrajectoryOutcome.SUCCEEDED, result.message
        assert wait_until(lambda: np.max(np.abs(robot.state().velocity)) < 1e-4, 10)
        before = np.array(Control(INDEX).state()["positions"])
        assert robot.mode is Mode.HOLD                     # the drives are enabled, holding
        robot.loop.stop()                                  # the core's thread ends without disabling them,
        robot.bus.close()                                  # well within the drives' 100 ms watchdog
        after = Control(INDEX).state()
        assert all(word & 0x4F == 0x40 for word in after["statuswords"]), [hex(w) for w in after["statuswords"]]
        assert np.allclose(after["positions"], before, atol=1e-4), (after["positions"], before)
    finally:
        if robot.bus.core_master is None:   # closed above: only the core's buffers are left to release
            robot.runtime.close()
        else:
            robot.shutdown()
