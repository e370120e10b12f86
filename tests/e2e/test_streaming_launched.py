"""Streaming and the speed override through the process client, against `plem launch bus:=mock`; limits are judged
from the rt_raw records the RT driver wrote, cycle by cycle."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator

import numpy as np
import pytest

from plem.bridge.client import RobotClient
from plem.control.modes import Mode
from plem.errors import CommandRejected
from plem.ipc.records import RawSample
from tests.e2e.launched import Launch, launched_robot, wait_for

SAMPLE_PERIOD_S = 0.004   # 250 Hz


@pytest.fixture(scope="module")
def robot(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Launch]:
    with launched_robot(tmp_path_factory, "bridge:=false", "record:=false") as launch:
        yield launch


class Recorder:
    """Every rt_raw sample the driver writes while it runs, read on a thread of its own."""

    def __init__(self, client: RobotClient) -> None:
        self.samples: list[RawSample] = []
        self._stop = threading.Event()
        self._stream = client.stream(timeout=0.5)
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        for sample in self._stream:
            self.samples.append(sample)
            if self._stop.is_set():
                return

    def stop(self) -> np.ndarray:
        """The commanded rows (cycles, 3, dof) recorded, consecutive cycles only (none lost)."""
        self._stop.set()
        self._thread.join(5.0)
        cycles = np.array([s.cycle for s in self.samples])
        assert self._stream.dropped == 0 and np.all(np.diff(cycles) == 1)
        return np.array([[s.command_position, s.command_velocity, s.command_acceleration] for s in self.samples])


def within_limits(client: RobotClient, commands: np.ndarray) -> None:
    limits, slack = client.limits, 1.0 + 1e-6
    assert np.all(np.abs(commands[:, 1]) <= limits.maximum("velocity") * slack)
    assert np.all(np.abs(commands[:, 2]) <= limits.maximum("acceleration") * slack)
    jerk = np.abs(np.diff(commands[:, 2], axis=0)) / client.cycle_time_s
    assert np.all(jerk <= limits.maximum("jerk") * slack)


def test_a_streamed_target_with_drops_and_jumps_is_followed_within_every_limit(client: RobotClient) -> None:
    client.set_mode("hold")
    recorder = Recorder(client)
    start = client.live_state().command_position.copy()
    target = start.copy()
    began = time.monotonic()
    for k in range(400):
        target = start.copy()
        target[0] += 0.2 * np.sin(k * 0.01)
        if k >= 150:
            target[1] += 0.3                                 # a jump
        if not 200 <= k < 210 and k % 9:                     # a gap and lost samples
            client.servo_joints(target, timeout=0.2)
        time.sleep(max(0.0, began + (k + 1) * SAMPLE_PERIOD_S - time.monotonic()))
    status = client.stream_status()
    assert status.state == "following" and status.latency_ns > 0
    assert wait_for(lambda: client.live_state().mode is Mode.HOLD, 10.0)   # the stream ended after its timeout
    commands = recorder.stop()
    within_limits(client, commands)
    assert client.last_fault() is None


def test_the_speed_override_pauses_and_resumes_a_motion_on_its_path(client: RobotClient) -> None:
    client.set_mode("hold")
    start = client.live_state().command_position.copy()
    goal = start + np.where(start > 0, -1.5, 1.5)
    recorder = Recorder(client)
    move = client.move_joints(goal, speed_scale=0.5)
    time.sleep(0.3)
    for factor in (0.3, 0.0):
        client.set_speed_override(factor)
        assert wait_for(lambda f=factor: client.speed_override == f, 10.0)
        assert client.live_state().mode is Mode.TRAJECTORY
    paused = client.live_state()
    time.sleep(0.2)
    assert np.array_equal(client.live_state().command_position, paused.command_position)
    client.set_speed_override(1.0)
    result = move.wait(30.0)
    assert result.outcome.value == "succeeded"
    commands = recorder.stop()
    within_limits(client, commands)
    assert np.allclose(client.live_state().command_position, goal, atol=1e-9)


def test_a_planned_motion_waits_for_a_stream_to_end_and_bad_values_are_refused(client: RobotClient) -> None:
    client.set_mode("hold")
    start = client.live_state().command_position.copy()
    for _ in range(50):
        client.jog(0, 0.2 if start[0] < 0 else -0.2)
        time.sleep(SAMPLE_PERIOD_S)
    client.move_joints(start).wait(30.0)   # planned once the stream came to rest and ended
    assert np.allclose(client.live_state().command_position, start, atol=1e-9)
    with pytest.raises(CommandRejected, match="speed override"):
        client.set_speed_override(1.5)
    with pytest.raises(CommandRejected, match="stream timeout"):
        client.servo_joints(start, timeout=0.0)
