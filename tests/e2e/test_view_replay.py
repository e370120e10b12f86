"""`plem view --bag` on bags the real recorder wrote of a simulated arm that moved and then faulted, in a real
headless Chromium: the arm is drawn, the timeline marks the fault, and the page opens in the seconds before it."""

from __future__ import annotations

import re
import signal
import subprocess
import threading
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from plem.bridge import connect
from plem.launch.plan import plan_robot
from plem.launch.recorder import record
from plem.launch.rt_driver import driving
from plem.recording.archive import read_event_log
from plem.recording.summary import find_bags
from plem.view.replay import Replay
from tests.e2e.browser import arm_pixels, page_of, wait_for_image, wait_for_text
from tests.e2e.cli import plem_executable, run_plem
from tests.e2e.launched import new_robot_id, wait_until
from tests.local_servers import free_port

TARGET = np.radians([35.0, -25.0, 50.0, 0.0, 30.0, 0.0])


@pytest.fixture(scope="module")
def bags(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Path, str]]:
    """Bags of an arm that moved to TARGET, held there, then faulted on joint 2's drive (0x7121), as the recorder
    wrote them."""
    robot_id = new_robot_id()
    directory = tmp_path_factory.mktemp("bags")
    arguments = {"bus": "mock", "robot_id": robot_id, "bag_dir": str(directory), "bag_segment_seconds": "2",
                 "flight_recorder_seconds": "2"}
    plan = plan_robot({"bus": "mock", "robot_id": robot_id}, generate=False)
    stop = threading.Event()
    with driving(plan) as driver:
        recorder = threading.Thread(target=record, args=(arguments, stop))
        recorder.start()
        try:
            with connect(robot_id) as client:
                client.set_mode("hold")
                client.move_joints(TARGET, speed_scale=0.5).wait(60)
                held = client.live_state().cycle + 2500     # 2.5 s of holding (the loop's clock) before the fault
                assert client.wait_for_state(timeout=30, after_cycle=held) is not None
                driver.robot.bus.inject_drive_fault(2, 0x7121)
                assert wait_until(lambda: client.state().faulted, 5)
                assert wait_until(lambda: any(entry["kind"] == "fault"
                                              for entry in read_event_log(directory / robot_id)), 5)
        finally:
            stop.set()
            driver.robot.shutdown()
            recorder.join(15)
    yield directory, robot_id


def test_the_replay_opens_before_the_fault_with_its_marker(bags: tuple[Path, str]) -> None:
    directory, robot_id = bags
    replay = Replay.of_bags(directory, fault=1)
    [fault] = replay.timeline.faults()
    assert "0x7121" in fault.label and replay.timeline.time_ns[0] < fault.time_ns <= replay.timeline.time_ns[-1]
    view = subprocess.Popen([plem_executable(), "view", "--bag", str(directory), "--fault", "1",
                             "--port", str(free_port())], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert view.stdout is not None
        line = view.stdout.readline()
        url = re.search(r"at (http://\S+)", line)
        assert url is not None, (line, view.stderr.read() if view.poll() is not None else "")  # type: ignore[union-attr]
        with page_of(url.group(1)) as page:
            text = wait_for_text(page, lambda t: "time" in t and "joints" in t)
            assert re.search(r"fault 1: .*0x7121", text), text
            assert "fault" in page.inner_text(".mantine-Slider-root"), "the timeline marks the fault"
            assert "mode hold" in text, "the window opens 2 s before the fault, the arm holding at TARGET"
            opening = [float(v) for v in re.findall(r"(-?\d+\.\d)°", text.split("joints", 1)[1])][:6]
            np.testing.assert_allclose(opening, np.degrees(TARGET), atol=0.11)
            wait_for_image(page, lambda image: arm_pixels(image).sum() > 2000)
    finally:
        view.send_signal(signal.SIGINT)
        assert view.wait(30) == 0


def test_a_fault_number_beyond_the_recorded_ones_says_how_many(bags: tuple[Path, str]) -> None:
    directory, _ = bags
    result = run_plem("view", "--bag", str(directory), "--fault", "5")
    assert result.returncode == 1 and "there is no fault 5" in result.stderr, result.stderr
    assert "1 faults recorded" in result.stderr and "plem bag info" in result.stderr
    assert [bags.robot_id for bags in find_bags(directory)] == [bags[1]]
