"""`plem view --ros`'s feed: a launched simulated arm (another process) seen over DDS only, as from another host.

The launch and this test process share a DDS domain of their own with discovery on this host only; the arm is
moved through its shared memory (`connect`), and what RosFeed shows is compared with what the arm does.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from plem.bridge.client import RobotClient
from plem.middleware.node import Node
from plem.middleware.qos import LATCHED
from plem.view.feed import READOUTS, Snapshot
from plem.view.ros_feed import RosFeed
from plem.view.server import ViewError
from tests.e2e.browser import page_of, wait_for_text
from tests.e2e.launched import Launch, join_domain, launched_robot, new_robot_id, wait_for, wait_until
from tests.e2e.ros_peer import JOINT_NAMES
from tests.e2e.test_view_live import View

#: Generous deadlines: the launch, the bridge and this process share a busy 2-core machine.
DISCOVERY_S = 30.0
MOTION_S = 30.0
#: How close the feed's positions must come to the target (the mock arm settles on it).
ARRIVED = 1e-3


@pytest.fixture(scope="module")
def robot(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Launch]:
    with launched_robot(tmp_path_factory, ros=True) as running:
        yield running


@pytest.fixture(autouse=True)
def same_domain(isolated_environment: Path, monkeypatch: pytest.MonkeyPatch, robot: Launch) -> None:
    join_domain(monkeypatch, robot)


@pytest.fixture
def feed(robot: Launch) -> Iterator[RosFeed]:
    ros = RosFeed(robot.robot_id, timeout_s=DISCOVERY_S)
    try:
        yield ros
    finally:
        ros.close()


def published_description(robot_id: str) -> str:
    """robot_description as a separate subscriber of the robot's latched topic receives it."""
    node = Node()
    try:
        subscription = node.subscription(f"/{robot_id}/robot_description", "std_msgs/msg/String", LATCHED)
        messages = wait_for(subscription.take, DISCOVERY_S)
        assert messages, "no robot_description"
        return str(messages[-1].data)
    finally:
        node.close()


def snapshot(feed: RosFeed, readouts: bool = False) -> Snapshot:
    taken = feed.snapshot(readouts)
    assert taken is not None
    return taken


def stats_reported(readouts: dict[str, str]) -> bool:
    """rt_monitor_stats has arrived with an interval's latency and the recorder's queue (the launch records)."""
    return readouts["latency"].startswith("p99 ") and readouts["recorder"].startswith("recording — ")


def test_the_feed_shows_the_published_description_and_the_arm_joints(feed: RosFeed, client: RobotClient):
    assert feed.urdf == published_description(feed.robot_id)
    assert "<robot" in feed.urdf and all(f'name="{joint}"' in feed.urdf for joint in JOINT_NAMES)
    assert feed.joint_names == JOINT_NAMES == tuple(client.joint_names)
    assert feed.packages == {}
    first = snapshot(feed)
    assert first.position.shape == (len(JOINT_NAMES),)
    assert wait_until(lambda: snapshot(feed).command_position is not None, DISCOVERY_S), "no rt_raw"
    assert snapshot(feed).command_position.shape == (len(JOINT_NAMES),)


def test_positions_follow_a_motion(feed: RosFeed, client: RobotClient):
    client.set_mode("hold")
    start = client.state().position.copy()
    target = start.copy()
    target[1] += -0.2 if start[1] > 0 else 0.2           # towards the middle of the range, so reruns stay in it
    client.move_joints(target.tolist())
    assert wait_until(lambda: abs(snapshot(feed).position[1] - start[1]) > 0.01, MOTION_S), "no motion seen"
    assert wait_until(lambda: np.allclose(snapshot(feed).position, target, atol=ARRIVED), MOTION_S), (
        snapshot(feed).position, target)
    assert wait_until(lambda: np.allclose(snapshot(feed).command_position, target, atol=ARRIVED), MOTION_S), (
        snapshot(feed).command_position, target)
    assert np.allclose(snapshot(feed).position, client.state().position, atol=ARRIVED)


def test_readouts_report_the_mode_drives_faults_and_latency(feed: RosFeed, client: RobotClient):
    client.set_mode("hold")
    assert wait_until(lambda: snapshot(feed, readouts=True).readouts.get("mode") == "hold", DISCOVERY_S), (
        feed.snapshot(True))
    assert wait_until(lambda: stats_reported(snapshot(feed, readouts=True).readouts), DISCOVERY_S), (
        feed.snapshot(True))
    readouts = snapshot(feed, readouts=True).readouts
    assert tuple(readouts) == READOUTS
    assert readouts["drives"] == "enabled"
    assert readouts["fault"] == "none"
    assert snapshot(feed).readouts == readouts, "a snapshot without readouts keeps the last ones"
    client.set_mode("idle")
    assert wait_until(lambda: snapshot(feed, readouts=True).readouts["mode"] == "idle", DISCOVERY_S), (
        feed.snapshot(True))
    assert wait_until(lambda: snapshot(feed, readouts=True).readouts["drives"] == "disabled", DISCOVERY_S), (
        feed.snapshot(True))


def test_a_robot_nobody_publishes_is_an_error_naming_the_topic(robot: Launch):
    robot_id = new_robot_id()
    with pytest.raises(ViewError) as raised:
        RosFeed(robot_id, timeout_s=0.5)
    error = raised.value
    assert f"no publisher of /{robot_id}/robot_description" in error.why
    assert f"ROS_DOMAIN_ID={robot.env['ROS_DOMAIN_ID']}" in error.why
    assert "bridge:=true" in error.how and "plem topic list" in error.how


def test_the_page_over_dds_offers_no_teach_folder(robot: Launch):
    """docs/view.md: over --ros the teach panel is not offered; the page has no Teach folder at all."""
    view = View(robot, "--ros")
    try:
        with page_of(view.url) as page:
            text = wait_for_text(page, lambda shown: "joints" in shown and "°" in shown)
            assert "Teach" not in text and "teach" not in text.lower()
    finally:
        assert view.stop() == 0
