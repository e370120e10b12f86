"""`plem state --watch` into a pipe, and clients of a driver that stops or dies, against `plem launch`."""

from __future__ import annotations

import json
import os
import re
import shlex
import signal
import subprocess
from collections.abc import Callable, Iterator

import pytest

from plem.bridge import DriverGone, connect
from tests.e2e.cli import plem_executable, run_plem
from tests.e2e.launched import Launch, launched_robot, process_gone, wait_until

FRAME = re.compile(r"^(\S+): (\w+), cycle (\d+), drives (enabled|disabled), position rad( [+-]\d+\.\d{4}){6}$")


@pytest.fixture(scope="module")
def robot(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Launch]:
    with launched_robot(tmp_path_factory, "bridge:=false", "record:=false") as launch:
        yield launch


def watch_into_head(launch: Launch, lines: int, *options: str) -> subprocess.CompletedProcess[str]:
    """`plem state --watch ... | head -n LINES` in a shell, failing when either side fails (pipefail)."""
    command = shlex.join([plem_executable(), "state", "--watch", "--robot-id", launch.robot_id, *options])
    return subprocess.run(["bash", "-o", "pipefail", "-c", f"{command} | head -n {lines}"], capture_output=True,
                          text=True, timeout=120, env={**os.environ, **launch.env})


def test_watch_into_a_pipe_prints_a_plain_line_per_frame_and_ends_quietly_when_the_reader_leaves(robot: Launch):
    result = watch_into_head(robot, 3)
    assert result.returncode == 0 and result.stderr == "", result.stderr
    frames = [FRAME.match(line) for line in result.stdout.splitlines()]
    assert len(frames) == 3 and all(frames), result.stdout
    assert {frame.group(1) for frame in frames if frame} == {robot.robot_id}
    cycles = [int(frame.group(3)) for frame in frames if frame]
    assert cycles == sorted(set(cycles)), "each line is a newer frame"
    assert "\x1b" not in result.stdout


def test_watch_as_json_prints_one_object_per_line(robot: Launch):
    result = watch_into_head(robot, 2, "--format", "json")
    assert result.returncode == 0 and result.stderr == "", result.stderr
    first, second = (json.loads(line) for line in result.stdout.splitlines())
    assert first["robot_id"] == robot.robot_id and first["cycle"] < second["cycle"]
    assert first["last_fault"] is None and len(first["position"]) == 6


def raises_driver_gone(read: Callable[[], object]) -> bool:
    try:
        read()
    except DriverGone:
        return True
    return False


def test_state_and_stats_raise_driver_gone_once_the_driver_stops_or_dies(tmp_path_factory: pytest.TempPathFactory):
    with launched_robot(tmp_path_factory, "bridge:=false", "record:=false") as launch, \
            connect(launch.robot_id) as client:
        pid = launch.driver_pids()[launch.robot_id]
        assert wait_until(lambda: client.stats() is not None, 10)
        os.kill(pid, signal.SIGSTOP)                            # alive, but its heartbeat stops
        try:
            assert wait_until(lambda: raises_driver_gone(client.state), 30)
            with pytest.raises(DriverGone) as stale:
                client.stats()
            assert stale.value.why.startswith("its last cycle was")
        finally:
            os.kill(pid, signal.SIGCONT)
        assert wait_until(lambda: not raises_driver_gone(client.state), 30), "a resumed driver is live again"

        os.kill(pid, signal.SIGKILL)
        assert wait_until(lambda: process_gone(pid), 30)
        for read in (client.state, client.stats, client.live_state, client.wait_for_state,
                     lambda: next(client.stream())):             # no timeout: it would otherwise wait forever
            with pytest.raises(DriverGone) as gone:
                read()
            assert gone.value.why == f"its process {pid} has ended"
        assert client.last_fault() is None, "the fault history stays readable"
        shown = run_plem("state", "--robot-id", launch.robot_id)
        assert shown.returncode == 1 and "Traceback" not in shown.stderr
        assert f"ERROR: the RT driver of robot '{launch.robot_id}' is not running" in shown.stderr
