"""`plem launch bridge_commands:=false`: the robot's topics on ROS 2, and no way to command it over DDS.

The launch and this test process share a domain of the run's pool with discovery limited to localhost.
What the bridge offers is checked through DDS (plem's own node, as any ROS 2 node would see it); shared
memory is read only to confirm that the arm did not move.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from cyclonedds.builtin import BuiltinDataReader, BuiltinTopicDcpsPublication, BuiltinTopicDcpsSubscription

from plem.bridge.client import RobotClient
from plem.control.events import EventKind
from plem.control.modes import Mode
from plem.middleware.discovery import DiscoverySettings
from plem.middleware.qos import DEFAULT
from plem.middleware.servo import JOINT_JOG, SPEED_SLIDER
from tests.conftest import fresh_domain
from tests.e2e.launched import Launch, clean_environment, launched, new_robot_id, wait_until
from tests.e2e.ros_peer import TRAJECTORY, RosPeer, shifted, wait_for

#: How long an absent server or subscriber is waited for; long enough for discovery on a busy host.
ABSENCE_WAIT_S = 5.0
_BRIDGE_LINE = re.compile(r"^  bridge +running, pid \d+, read-only \(bridge_commands:=false\), topics only under "
                          r"(\S+) \((.*)\)$", re.MULTILINE)
PUBLISHED = ("joint_states", "robot_description", "rt_raw", "rt_events", "rt_monitor_stats")


@pytest.fixture(scope="module")
def robot(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Launch]:
    directory = tmp_path_factory.mktemp("read_only_bridge")
    robot_id = new_robot_id()
    env = clean_environment(directory / "plem_home", ROS_DOMAIN_ID=str(fresh_domain()))
    with launched(["bus:=mock", f"robot_id:={robot_id}", "bridge_commands:=false", "record:=false"], [robot_id],
                  directory, env) as launch:
        yield launch


@pytest.fixture(scope="module")
def peer(robot: Launch) -> Iterator[RosPeer]:
    ros = RosPeer(robot.robot_id, DiscoverySettings.from_environment(robot.env))
    try:
        yield ros
    finally:
        ros.close()


class Endpoints:
    """Every DDS writer and reader this process has discovered, by participant."""

    def __init__(self, peer: RosPeer) -> None:
        participant = peer.node.participant
        self._readers = {True: BuiltinDataReader(participant, BuiltinTopicDcpsPublication),
                         False: BuiltinDataReader(participant, BuiltinTopicDcpsSubscription)}
        self._seen: dict[Any, tuple[Any, str, bool]] = {}

    def of_participant_writing(self, topic: str) -> tuple[set[str], set[str]] | None:
        """(DDS topics written, DDS topics read) by the participant that writes `topic`; None before it is seen."""
        for writer, reader in self._readers.items():
            for sample in reader.take(N=1024):
                if sample.sample_info.valid_data:
                    self._seen[sample.key] = (sample.participant_key, sample.topic_name, writer)
        owners = {owner for owner, name, writer in self._seen.values() if writer and name == topic}
        if not owners:
            return None
        (owner,) = owners
        endpoints = [(name, writer) for participant, name, writer in self._seen.values() if participant == owner]
        return {name for name, writer in endpoints if writer}, {name for name, writer in endpoints if not writer}


def test_launch_summary_says_read_only(robot: Launch) -> None:
    match = _BRIDGE_LINE.search(robot.output)
    assert match, robot.describe()
    assert match[1] == f"/{robot.robot_id}/"
    assert match[2].startswith(f"ROS_DOMAIN_ID={robot.env['ROS_DOMAIN_ID']}, discovery localhost")


def test_topics_are_published(peer: RosPeer) -> None:
    assert peer.joint_state(timeout=10).name
    description = peer.robot_description()
    message = wait_for(lambda: description.take(), 10)
    assert message and "<robot" in message[0].data


def test_no_command_endpoints_exist(robot: Launch, peer: RosPeer) -> None:
    """No action server answers, nothing subscribes the trajectory topic, and the bridge has no reader at all."""
    ns = f"rt/{robot.robot_id}"
    endpoints = Endpoints(peer)
    assert wait_for(lambda: endpoints.of_participant_writing(f"{ns}/joint_states"), 10), "the bridge was not seen"
    assert not peer.set_mode.wait_for_server(ABSENCE_WAIT_S)
    assert not peer.follow.wait_for_server(1.0)
    assert peer.trajectories.subscribers == 0
    written, read = endpoints.of_participant_writing(f"{ns}/joint_states")
    assert {f"{ns}/{name}" for name in PUBLISHED} <= written
    assert read == set(), f"the read-only bridge reads {sorted(read)}"
    assert not [name for name in written if "_action" in name or name.startswith("rr/")]
    # The same count does see a subscription of the trajectory topic once there is one (here, our own).
    own = peer.subscribe(f"{TRAJECTORY}/joint_trajectory", "trajectory_msgs/msg/JointTrajectory", DEFAULT)
    assert wait_for(lambda: peer.trajectories.subscribers == 1, 10) and own.publishers == 1


def test_commands_find_no_server_and_nothing_moves(robot: Launch, peer: RosPeer, client: RobotClient) -> None:
    """With the drives on (so a command that got through would move the arm): a goal times out, a trajectory
    on the topic goes nowhere, and the arm stays where it was."""
    assert client.set_mode("hold") is Mode.HOLD   # through shared memory: the bridge offers no way
    assert wait_until(lambda: bool(np.all(abs(client.state().velocity) < 1e-4)), 5), client.state()
    events = client.events(timeout=0)
    start = client.state().position.copy()
    target = shifted(start.tolist(), 0, 0.2 if start[0] < 0 else -0.2)
    trajectory = peer.trajectory([(target, 1.0)])
    with pytest.raises(TimeoutError):
        peer.follow.send_goal(2.0, trajectory=trajectory)
    with pytest.raises(TimeoutError):
        peer.set_mode.send_goal(2.0, mode="free_drive")
    peer.trajectories.publish(trajectory)
    assert not wait_until(lambda: not np.allclose(client.state().position, start, atol=1e-4), 2.0), "the arm moved"
    kinds = {event.kind for event in events}
    assert EventKind.MOTION_STARTED not in kinds and EventKind.COMMAND_REJECTED not in kinds
    assert client.state().mode is Mode.HOLD



def test_speed_scaling_is_published_and_jogging_and_the_speed_slider_are_not_served(
        robot: Launch, peer: RosPeer, client: RobotClient) -> None:
    """The speed override in force is state, so it is published; the jog topic and the speed slider are commands."""
    ns = f"/{robot.robot_id}"
    scaling = peer.subscribe("speed_scaling_state_broadcaster/speed_scaling", "std_msgs/msg/Float64")
    assert wait_for(lambda: any(m.data == 100.0 for m in scaling.take()), 10)
    slider = peer.node.client(f"{ns}/io_and_status_controller/set_speed_slider", SPEED_SLIDER)
    jog = peer.node.publisher(f"{ns}/servo_node/delta_joint_cmds", JOINT_JOG, DEFAULT)
    assert not wait_for(lambda: slider.ready or jog.subscribers > 0, ABSENCE_WAIT_S)
    assert client.set_mode("hold") is Mode.HOLD
    start = client.state().position.copy()
    with pytest.raises(TimeoutError):
        slider.call(1.0, speed_slider_fraction=0.2)
    jog.publish(peer.library.new(JOINT_JOG, joint_names=["joint0"], velocities=[0.3]))
    assert not wait_until(lambda: not np.allclose(client.state().position, start, atol=1e-4), 1.0), "the arm moved"
    assert client.stream_status().override_target == 1.0
