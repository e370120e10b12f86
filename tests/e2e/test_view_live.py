"""`plem view` on a launched simulated arm, in a real headless Chromium: the arm is drawn and follows a motion, the
readouts follow it, the planner's objects and plans appear, the teach panel moves the arm only on a click, and
neither killing the view nor a browser that stops reading disturbs the arm."""

from __future__ import annotations

import os
import re
import signal
import subprocess
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from plem.bridge.client import RobotClient, connect
from plem.control.modes import Mode
from plem.planning import Box, Pose, SceneObject
from tests.e2e.browser import arm_pixels, coloured, page_of, screenshot, wait_for_image, wait_for_text
from tests.e2e.cli import plem_executable
from tests.e2e.launched import Launch, launched_robot, process_gone
from tests.local_servers import free_port

#: The view's colours of scene objects and of the planned path (plem.view.scene), as the page draws them lit.
OBJECT_RGB, PATH_RGB = (217, 115, 51), (26, 179, 77)
ARM_PIXELS = 2000
URL = re.compile(r"at (http://\S+)")


class View:
    """`plem view ROBOT_ID` as a user starts it; its URL from what it prints."""

    def __init__(self, launch: Launch, *args: str) -> None:
        self.process = subprocess.Popen([plem_executable(), "view", launch.robot_id, "--port", str(free_port()),
                                         *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                        env=launch.env)
        assert self.process.stdout is not None
        line = self.process.stdout.readline()
        match = URL.search(line)
        if match is None:
            self.process.kill()
            raise AssertionError(f"plem view printed {line!r}; stderr: {self.process.stderr.read()}")  # type: ignore[union-attr]
        self.url = match.group(1)

    def stop(self) -> int:
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
        return self.process.wait(30)


@pytest.fixture(scope="module")
def launch(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Launch]:
    with launched_robot(tmp_path_factory, "record:=false", "planner:=true", "bridge:=false") as running:
        yield running


@pytest.fixture(scope="module")
def page(launch: Launch) -> Iterator[Any]:
    """One `plem view` and one browser on its page for the tests that look at the page; the view must stop cleanly."""
    view = View(launch)
    try:
        with page_of(view.url) as opened:
            yield opened
    finally:
        assert view.stop() == 0


@pytest.fixture
def client(launch: Launch) -> Iterator[RobotClient]:
    with connect(launch.robot_id) as robot:
        robot.set_mode(Mode.HOLD)
        robot.move_joints([0.0] * robot.dof).wait(60)
        yield robot
        robot.clear_scene()


def _degrees(text: str) -> np.ndarray:
    """The joint positions the page's `joints` readout shows, in degrees."""
    line = next(line for line in text.splitlines() if line.startswith("joints"))
    return np.array([float(value) for value in re.findall(r"(-?\d+\.\d)°", line)])


def test_the_page_draws_the_arm_and_follows_a_motion(page: Any, client: RobotClient) -> None:
    text = wait_for_text(page, lambda t: "joints" in t and "planner running" in t)
    assert "mode hold" in text and "drives enabled" in text and "fault none" in text
    before = wait_for_image(page, lambda image: arm_pixels(image).sum() > ARM_PIXELS)
    target = np.radians([40.0, -30.0, 60.0, 0.0, 45.0, 20.0])
    motion = client.move_joints(target, speed_scale=0.3)
    wait_for_text(page, lambda t: "mode trajectory" in t)
    motion.wait(60)
    wait_for_text(page, lambda t: np.allclose(_degrees(t), np.degrees(target), atol=0.11))
    after = wait_for_image(page, lambda image: (arm_pixels(image) ^ arm_pixels(before)).sum() > ARM_PIXELS)
    assert arm_pixels(after).sum() > ARM_PIXELS

    objects = coloured(screenshot(page), OBJECT_RGB).sum()
    client.add_objects(SceneObject("crate", Box((0.3, 0.3, 0.3)), Pose((0.6, 0.0, 0.15))))
    wait_for_text(page, lambda t: "planner running — 1 objects" in t)
    wait_for_image(page, lambda image: coloured(image, OBJECT_RGB).sum() > objects + 500)

    path = coloured(screenshot(page), PATH_RGB, 50).sum()
    plans = int(re.search(r"(\d+) plans", wait_for_text(page, lambda t: "plans" in t)).group(1))  # type: ignore[union-attr]
    client.plan("home")
    wait_for_text(page, lambda t: f"{plans + 1} plans" in t)
    wait_for_image(page, lambda image: coloured(image, PATH_RGB, 50).sum() > path + 200)


def test_teach_moves_the_arm_only_on_a_click(page: Any, client: RobotClient) -> None:
    wait_for_text(page, lambda t: "joints" in t)
    page.get_by_text("Teach", exact=True).click()
    page.get_by_label("teach").check()
    wait_for_text(page, lambda t: "nothing moves until you click" in t)
    for index, value in ((0, "1"), (1, "0.5")):      # the speed scale, then joint0
        box = page.get_by_role("textbox").nth(index)
        box.fill(value)
        box.press("Enter")
    page.wait_for_timeout(500)
    cycle = client.live_state().cycle
    assert client.wait_for_state(after_cycle=cycle + 200, timeout=10) is not None
    assert abs(client.live_state().position[0]) < 1e-6, "the arm moved before the click"
    page.get_by_text("move to the sliders").click()
    wait_for_text(page, lambda t: "done" in t.splitlines())
    assert client.live_state().position[0] == pytest.approx(0.5, abs=1e-3)


def test_killing_the_view_or_a_stalled_browser_never_disturbs_the_arm(launch: Launch, client: RobotClient) -> None:
    import viser
    from websockets.sync.client import connect as websocket
    from websockets.typing import Subprotocol

    view = View(launch)
    faults = len(client.faults())
    stalled = websocket(view.url.replace("http", "ws"), max_size=None, close_timeout=1,  # a client the view accepts,
                        subprotocols=[Subprotocol(f"viser-v{viser.__version__}")])   # which then never reads
    assert stalled.recv(timeout=30), "the view serves the stalled client"
    try:
        for target in (np.radians([-30.0, 20.0, 40.0, 10.0, -20.0, 30.0]), np.zeros(client.dof)):
            motion = client.move_joints(target, speed_scale=1.0)
            if not target.any():                           # the second motion: the view is killed during it
                os.kill(view.process.pid, signal.SIGKILL)
            motion.wait(60)
            np.testing.assert_allclose(client.live_state().position, target, atol=1e-3)
    finally:
        stalled.close()
    assert len(client.faults()) == faults and client.live_state().mode is Mode.HOLD
    assert view.process.wait(10) == -signal.SIGKILL and process_gone(view.process.pid)
