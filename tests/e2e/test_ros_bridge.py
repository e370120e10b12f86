"""The ROS 2 bridge of `plem launch`, reached over DDS from another process (this one): topics, actions, its death.

The launch and this test process share a random ROS_DOMAIN_ID (150-230) with discovery limited to
localhost. Everything checked through DDS goes through plem's own node (`RosPeer`); shared memory is
read only to confirm what the RT driver did (its mode, whether it still runs).
"""

from __future__ import annotations

import json
import os
import re
import signal
import time
from collections.abc import Iterator
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from plem.bridge import connect
from plem.bridge.client import RobotClient
from plem.control.events import EventKind
from plem.control.modes import Mode
from plem.middleware.action import ABORTED, CANCEL_NONE, CANCELED, SUCCEEDED
from plem.middleware.discovery import DiscoverySettings
from plem.middleware.node_graph import ROSOUT_QOS
from tests.e2e.launched import (
    Launch,
    join_domain,
    launched,
    launched_robot,
    new_robot_id,
    process_gone,
    python_client,
    ros_environment,
    wait_until,
)
from tests.e2e.ros_peer import JOINT_NAMES, TRAJECTORY, RosPeer, shifted, wait_for

ARRIVED = 1e-3
LOOP_HZ = 1000.0
JOINT_STATE_HZ = 100.0
STATS_HZ = 10.0
QUEUES = {"rt_raw", "events", "commands", "dds:rt_raw"}
ROOT = Path(__file__).resolve().parents[2]
MODE_CLIENT = """
    import json, sys
    from tests.e2e.ros_peer import RosPeer
    peer = RosPeer(sys.argv[1])
    assert peer.wait_for_servers(10)
    status, result = peer.change_mode("hold")
    print(json.dumps({"status": status, "success": result.success}), flush=True)
    peer.close()  # leave at once, as rclpy's shutdown does: peers see the endpoints go
"""
_BRIDGE_LINE = re.compile(r"^  bridge +running, pid (\d+), topics and actions under (\S+) \((.*)\)$", re.MULTILINE)


# -- fixtures ----------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def robot(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Launch]:
    with launched_robot(tmp_path_factory, ros=True) as running:
        yield running


@pytest.fixture(autouse=True)
def same_domain(isolated_environment: Path, monkeypatch: pytest.MonkeyPatch, robot: Launch) -> None:
    join_domain(monkeypatch, robot)


@pytest.fixture(scope="module")
def peer(robot: Launch) -> Iterator[RosPeer]:
    ros = RosPeer(robot.robot_id, DiscoverySettings.from_environment(robot.env))
    try:
        assert ros.wait_for_servers(10), "the bridge's actions and trajectory topic were not discovered"
        yield ros
    finally:
        ros.close()


@pytest.fixture
def holding(robot: Launch, peer: RosPeer) -> RosPeer:
    """The peer, with the arm at rest in HOLD (drives on)."""
    assert robot.process.poll() is None, robot.describe()
    status, result = peer.change_mode("hold")
    assert (status, result.success, result.mode) == (SUCCEEDED, True, "hold"), result
    return peer


# -- helpers -----------------------------------------------------------------------------------------
def toward_middle(position: list[float], joint: int, distance: float) -> list[float]:
    """`position` with one joint moved by `distance` rad towards 0, so repeated moves stay in range."""
    return shifted(position, joint, -distance if position[joint] > 0 else distance)


def collect(take, seconds: float, period: float = 0.005) -> tuple[list[Any], float]:
    """Everything `take()` returns over `seconds`, and the time that really passed."""
    messages: list[Any] = []
    started = time.monotonic()
    while time.monotonic() - started < seconds:
        messages += take()
        time.sleep(period)
    messages += take()
    return messages, time.monotonic() - started


def stamp_s(message: Any) -> float:
    return message.header.stamp.sec + message.header.stamp.nanosec * 1e-9


def wait_moving(peer: RosPeer, start: list[float], joint: int, timeout: float = 3.0) -> None:
    assert wait_for(lambda: abs(peer.position()[joint] - start[joint]) > 0.005, timeout), "the arm did not move"


def at_rest(client: RobotClient) -> bool:
    """In HOLD with the stop ramp done (a stop runs in HOLD) and the arm settled on the command."""
    state = client.state()
    return (state.mode is Mode.HOLD and bool(np.all(abs(state.command_velocity) < 1e-9))
            and bool(np.all(abs(state.velocity) < 1e-4)))


def wait_held(client: RobotClient, timeout: float = 5.0) -> np.ndarray:
    """Once the arm rests in HOLD: its position, checked to stay put."""
    assert wait_until(lambda: at_rest(client), timeout), client.state()
    held = client.state().position.copy()
    time.sleep(0.3)
    assert np.allclose(client.state().position, held, atol=1e-4), "the arm still moves in HOLD"
    return held


# -- the launch --------------------------------------------------------------------------------------
def test_launch_summary_reports_the_running_bridge(robot: Launch):
    match = _BRIDGE_LINE.search(robot.output)
    assert match, robot.describe()
    assert match[2] == f"/{robot.robot_id}/"
    assert match[3] == f"ROS_DOMAIN_ID={robot.env['ROS_DOMAIN_ID']}, discovery localhost, joint_states 100 Hz"
    assert not process_gone(int(match[1]))


# -- topics ------------------------------------------------------------------------------------------
def test_robot_description_reaches_a_late_subscriber(peer: RosPeer):
    description = peer.robot_description()     # the bridge published it once, seconds ago
    messages = wait_for(description.take, 5)
    assert messages, "no robot_description for a late subscriber"
    urdf = messages[-1].data
    assert "<robot" in urdf and "</robot>" in urdf
    assert all(f'name="{joint}"' in urdf for joint in JOINT_NAMES)


def test_robot_description_semantic_reaches_a_late_subscriber(peer: RosPeer):
    """The package has an SRDF: it is latched on robot_description_semantic, as MoveIt's nodes read it."""
    semantic = peer.robot_description("robot_description_semantic")
    messages = wait_for(semantic.take, 5)
    assert messages, "no robot_description_semantic for a late subscriber"
    srdf = messages[-1].data
    assert "<robot" in srdf and "<group " in srdf and 'group_state name="home"' in srdf


def test_joint_states_at_the_default_rate_with_the_robot_joints(peer: RosPeer):
    peer.joint_state()
    messages, _ = collect(peer.joint_states.take, 2.0, period=0.02)
    assert len(messages) > JOINT_STATE_HZ, len(messages)          # the rate itself: from the stamps below
    for message in messages:
        assert tuple(message.name) == JOINT_NAMES
        assert len(message.position) == len(message.velocity) == len(message.effort) == len(JOINT_NAMES)
    stamps = np.array([stamp_s(message) for message in messages])
    assert np.all(np.diff(stamps) > 0)
    assert 0.8 / JOINT_STATE_HZ < np.median(np.diff(stamps)) < 1.25 / JOINT_STATE_HZ
    assert abs(stamps[-1] - time.time()) < 1.0, "joint_states are not stamped with the wall clock"


def test_rt_raw_carries_every_cycle(peer: RosPeer, client: RobotClient):
    raw = peer.rt_raw()
    take = partial(raw.take, 5000)
    try:
        assert wait_for(take, 5), "no rt_raw"
        messages, _ = collect(take, 2.0)
        newest = client.state().cycle
        cycles = np.array([message.cycle for message in messages])
        gaps = np.flatnonzero(np.diff(cycles) != 1)
        assert gaps.size == 0, f"{gaps.size} gaps, e.g. after cycle {cycles[gaps[0]]}: {cycles[gaps[0]:gaps[0] + 3]}"
        assert cycles[-1] - cycles[0] >= 1.5 * LOOP_HZ, "rt_raw kept coming for the 2 s"
        assert 0 <= newest - cycles[-1] < 0.5 * LOOP_HZ, "rt_raw lags the loop"
        times = np.diff([message.monotonic_ns for message in messages])
        assert 0.9e9 / LOOP_HZ < np.median(times) < 1.1e9 / LOOP_HZ
        last = messages[-1]
        assert len(last.position) == len(last.command_acceleration) == len(JOINT_NAMES)
        assert abs(stamp_s(last) - time.time()) < 1.0
    finally:
        del raw, take  # stop taking 1000 samples a second into this process (also after a failure)


def test_rt_monitor_stats_at_10_hz_with_queue_counters(peer: RosPeer):
    stats = peer.rt_monitor_stats()
    assert wait_for(stats.take, 5), "no rt_monitor_stats"
    messages, _ = collect(stats.take, 2.0, period=0.02)
    stamped = stamp_s(messages[-1]) - stamp_s(messages[0])   # the driver's clock: delivery delays do not count
    assert 0.7 * STATS_HZ < (len(messages) - 1) / stamped < 1.2 * STATS_HZ, (len(messages), stamped)
    cycles = np.diff([message.cycles for message in messages])
    assert np.all(cycles > 0) and np.all(cycles < 3 * LOOP_HZ / STATS_HZ), cycles
    for message in messages:
        assert message.period_ns == 1_000_000
        assert message.mode in ("idle", "hold", "trajectory", "free_drive") and message.fault_reason == ""
        assert message.latency.samples > 0 and message.latency.max_us >= message.latency.p50_us
        queues = {queue.name: queue for queue in message.queues}
        assert set(queues) >= QUEUES, set(queues)
        # The driver's rings never drop here; a bridge starved of CPU may drop DDS samples, and counts them.
        dropped = {q.name: q.dropped for q in message.queues if q.dropped and not q.name.startswith("dds:")}
        assert not dropped, dropped
        assert queues["rt_raw"].capacity > 0 and queues["rt_raw"].fill <= queues["rt_raw"].capacity
    first, last = ({q.name: q for q in message.queues} for message in (messages[0], messages[-1]))
    assert last["dds:rt_raw"].written > first["dds:rt_raw"].written
    assert last["rt_raw"].written - first["rt_raw"].written == pytest.approx(
        messages[-1].cycles - messages[0].cycles, abs=0.1 * LOOP_HZ)


def test_set_mode_action_changes_the_mode_and_reports_it_on_rt_events(peer: RosPeer):
    events = peer.rt_events()
    assert wait_for(lambda: events.publishers, 5)
    time.sleep(0.2)
    events.take(1000)  # the history a late subscriber gets
    for mode in ("hold", "idle", "hold"):
        status, result = peer.change_mode(mode)
        assert (status, result.success, result.mode, result.message) == (SUCCEEDED, True, mode, ""), result
    seen: list[Any] = []

    def changes() -> list[tuple[str, str]]:
        seen.extend(events.take())
        return [(event.previous_mode, event.mode) for event in seen if event.kind == "mode_changed"]

    assert wait_for(lambda: ("idle", "hold") in changes(), 3), changes()
    assert changes()[-2:] == [("hold", "idle"), ("idle", "hold")]
    hold = [event for event in seen if event.kind == "mode_changed"][-1]
    assert hold.cycle > 0 and abs(stamp_s(hold) - time.time()) < 5 and hold.reason

    # transient local, depth 100: a subscriber that starts now still gets both changes
    time.sleep(1.0)  # until the first subscriber acknowledged them: only the writer's durable history remains
    late = peer.rt_events()
    history = wait_for(lambda: late.take(1000), 5) or []
    time.sleep(0.2)
    history += late.take(1000)
    cycles = [event.cycle for event in history]
    assert len(history) >= 2 and hold.cycle in cycles, [(e.kind, e.cycle) for e in history]
    assert [e.mode for e in history if e.kind == "mode_changed"][-2:] == ["idle", "hold"]


# -- FollowJointTrajectory ---------------------------------------------------------------------------
def test_follow_joint_trajectory_moves_the_arm_with_feedback(holding: RosPeer):
    peer = holding
    start = peer.position()
    target = toward_middle(start, 1, 0.2)
    middle = toward_middle(start, 1, 0.1)
    goal_id = peer.send_trajectory(peer.trajectory([(middle, 1.2), (target, 2.4)]))
    status, result, feedback = peer.follow_goal(goal_id, 10)
    assert (status, result.error_code) == (SUCCEEDED, 0), result.error_string
    assert len(feedback) >= 20, f"{len(feedback)} feedback messages over 2.4 s"  # 20 Hz
    assert all(tuple(message.feedback.joint_names) == JOINT_NAMES for message in feedback)
    travelled = [message.feedback.actual.positions[1] for message in feedback]
    assert min(start[1], target[1]) - ARRIVED <= min(travelled) < max(travelled) <= max(start[1], target[1]) + ARRIVED
    assert np.allclose(peer.position(), target, atol=ARRIVED), (peer.position(), target)


def test_a_one_point_positions_only_goal_is_smoothed_and_runs_in_the_time_asked(holding: RosPeer):
    peer = holding
    target = toward_middle(peer.position(), 2, 0.15)
    goal_id = peer.send_trajectory(peer.trajectory([(target, 1.5)], at_rest=False))
    status, result, _ = peer.follow_goal(goal_id, 10)
    assert (status, result.error_code) == (SUCCEEDED, 0), result.error_string
    assert "smoothed at the points" in result.error_string and "1.500 s as asked" in result.error_string
    assert np.allclose(peer.position(), target, atol=ARRIVED), (peer.position(), target)


def test_goal_with_wrong_joint_names_is_aborted_as_invalid_joints(holding: RosPeer):
    peer = holding
    start = peer.position()
    wrong = [f"joint{index + 1}" for index in range(len(JOINT_NAMES))]
    goal_id = peer.send_trajectory(peer.trajectory([(toward_middle(start, 0, 0.2), 2.0)], wrong))
    status, result, feedback = peer.follow_goal(goal_id, 5)
    assert (status, result.error_code) == (ABORTED, -2)  # INVALID_JOINTS
    assert "WHAT:" in result.error_string and "joint6" in result.error_string, result.error_string
    assert not feedback
    assert np.allclose(peer.position(), start, atol=1e-4)


def test_goal_outside_the_position_limits_is_aborted_as_invalid_goal(holding: RosPeer):
    peer = holding
    start = peer.position()
    goal_id = peer.send_trajectory(peer.trajectory([(shifted(start, 0, 10.0), 3.0)]))
    status, result, _ = peer.follow_goal(goal_id, 5)
    assert (status, result.error_code) == (ABORTED, -1), result.error_string  # INVALID_GOAL
    assert "position limits" in result.error_string and "WHAT:" in result.error_string, result.error_string
    assert np.allclose(peer.position(), start, atol=1e-4)


def test_a_refused_goal_reaches_rosout_and_rt_events(holding: RosPeer):
    peer = holding
    events = peer.rt_events()
    rosout = peer.node.subscription("/rosout", "rcl_interfaces/msg/Log", ROSOUT_QOS)
    goal_id = peer.send_trajectory(peer.trajectory([(shifted(peer.position(), 0, 10.0), 3.0)]))
    assert peer.follow_goal(goal_id, 5)[0] == ABORTED
    logger = f"{peer.robot_id}.{TRAJECTORY}"
    logged = wait_for(lambda: [m for m in rosout.take() if m.name == logger and "position limits" in m.msg], 10)
    assert logged and logged[0].level == 30 and "follow_joint_trajectory refused" in logged[0].msg
    rejected = wait_for(lambda: [e for e in events.take() if e.kind == "command_rejected"
                                 and e.cause == "follow_joint_trajectory"], 10)
    assert rejected and "position limits" in rejected[-1].reason


def test_canceled_goal_stops_the_arm_which_then_holds(holding: RosPeer, client: RobotClient):
    peer = holding
    start = peer.position()
    target = toward_middle(start, 0, 0.3)
    goal_id = peer.send_trajectory(peer.trajectory([(target, 3.0)]))
    wait_moving(peer, start, 0)
    assert peer.follow.cancel(goal_id) == CANCEL_NONE
    status, result, _ = peer.follow_goal(goal_id, 5)
    assert status == CANCELED, (status, result.error_string)
    held = wait_held(client)
    assert abs(held[0] - target[0]) > 0.1, "the arm went on to the target"
    assert np.allclose(peer.position(), held, atol=1e-4)


# -- the joint_trajectory topic ----------------------------------------------------------------------
def test_trajectory_on_the_topic_moves_the_arm(holding: RosPeer, client: RobotClient):
    peer = holding
    target = toward_middle(peer.position(), 2, 0.2)
    peer.trajectories.publish(peer.trajectory([(target, 1.5)]))
    assert wait_for(lambda: np.allclose(peer.position(), target, atol=ARRIVED), 6), (peer.position(), target)
    wait_held(client)
    assert np.allclose(peer.position(), target, atol=ARRIVED)


def test_empty_trajectory_on_the_topic_stops_a_running_motion(holding: RosPeer, client: RobotClient):
    peer = holding
    start = peer.position()
    target = toward_middle(start, 0, 0.3)
    peer.trajectories.publish(peer.trajectory([(target, 3.0)]))
    wait_moving(peer, start, 0)
    peer.trajectories.publish(peer.trajectory([]))
    held = wait_held(client, timeout=2.5)  # well before the 3 s motion would have ended
    assert abs(held[0] - target[0]) > 0.1, "the arm went on to the target"
    assert np.allclose(peer.position(), held, atol=1e-4)


# -- SetMode -----------------------------------------------------------------------------------------
def test_unknown_mode_is_aborted_with_a_message(holding: RosPeer, client: RobotClient):
    status, result = holding.change_mode("warp")
    assert (status, result.success, result.mode) == (ABORTED, False, "hold")
    assert "'warp'" in result.message and "WHAT:" in result.message, result.message
    assert client.state().mode is Mode.HOLD


def test_commands_are_still_served_after_a_client_process_leaves(robot: Launch, tmp_path: Path):
    """A client that leaves disposes of its endpoints; the bridge gets invalid samples and must skip them.

    A robot of its own, so that these clients are its only ones (another client's writer would keep the
    request topic alive and hide the disposal).
    """
    robot_id = new_robot_id()
    env = ros_environment(tmp_path / "plem_home", int(robot.env["ROS_DOMAIN_ID"]))
    with launched(["bus:=mock", f"robot_id:={robot_id}"], [robot_id], tmp_path, env) as launch:
        for _ in range(2):
            other = python_client(MODE_CLIENT, robot_id, env={**env, "PYTHONPATH": str(ROOT)})
            output, errors = other.communicate(timeout=60)
            assert other.returncode == 0, errors + launch.describe()
            assert json.loads(output) == {"status": SUCCEEDED, "success": True}
        assert "Traceback" not in launch.errors, launch.errors


# -- the bridge's death ------------------------------------------------------------------------------
def test_killing_the_bridge_mid_motion_leaves_the_arm_and_the_launch_running(robot: Launch, peer: RosPeer,
                                                                             tmp_path: Path):
    """A second robot on the same domain, so that the shared one keeps its bridge."""
    robot_id = new_robot_id()
    env = ros_environment(tmp_path / "plem_home", int(robot.env["ROS_DOMAIN_ID"]))
    with launched(["bus:=mock", f"robot_id:={robot_id}"], [robot_id], tmp_path, env) as launch, \
            connect(robot_id) as client:
        pid, driver = launch.component_pid("bridge"), launch.driver_pids()[robot_id]
        ros = RosPeer(robot_id, node=peer.node)
        assert ros.wait_for_servers(10)
        status, result = ros.change_mode("hold")
        assert status == SUCCEEDED, result
        start = ros.position()
        target = shifted(start, 0, 0.3)
        ros.send_trajectory(ros.trajectory([(target, 2.5)]))
        assert wait_until(lambda: client.state().mode is Mode.TRAJECTORY, 2)
        events = client.events(timeout=0)

        os.kill(pid, signal.SIGKILL)
        assert wait_until(lambda: process_gone(pid), 5)
        assert client.state().mode is Mode.TRAJECTORY, "the bridge was not killed in the middle of the motion"
        launch.wait_for(f"[{robot_id}/bridge] killed by SIGKILL", 5)

        assert wait_until(lambda: client.state().mode is Mode.HOLD, 5), (client.state().mode,
                                                                          (client.stats() or {}).get("fault_reason"))
        state = client.state()
        assert np.allclose(state.position, target, atol=ARRIVED), (state.position, target)
        assert not state.faulted and state.drives_enabled
        finished = [event for event in events if event.kind is EventKind.MOTION_FINISHED]
        assert [event.cause for event in finished] == ["succeeded"], finished
        # the loop goes on: judged by its own cycles, not by a wall-clock rate a busy machine may not give it
        assert client.wait_for_state(timeout=10, after_cycle=state.cycle + int(0.5 * LOOP_HZ)) is not None
        assert not process_gone(driver)
        assert launch.process.poll() is None, launch.describe()
        assert "stopping everything" not in launch.output
        assert launch.stop() == 0, launch.describe()


# -- parameters --------------------------------------------------------------------------------------
def test_parameters_answer_as_ros2_param_asks(peer: RosPeer):
    ns = f"/{peer.robot_id}"

    def call(node: str, service: str, kind: str, **fields: Any) -> Any:
        client = peer.node.client(f"{ns}/{node}/{service}", f"rcl_interfaces/srv/{kind}")
        assert wait_for(lambda: client.ready, 10), f"{node}/{service} not found"
        return client.call(10, **fields)

    [rate] = call("controller_manager", "get_parameters", "GetParameters", names=["update_rate"]).values
    assert (rate.type, rate.integer_value) == (2, 500)   # the built-in controllers.yaml's
    [joints] = call(TRAJECTORY, "get_parameters", "GetParameters", names=["joints"]).values
    assert joints.type == 9 and list(joints.string_array_value) == list(JOINT_NAMES)
    listed = call("controller_manager", "list_parameters", "ListParameters", prefixes=[], depth=0).result
    assert {"update_rate", f"{TRAJECTORY}.type"} <= set(listed.names)
    [missing] = call("robot_state_publisher", "get_parameters", "GetParameters", names=["no_such"]).values
    assert missing.type == 0
    new = peer.library.new
    parameter = new("rcl_interfaces/msg/Parameter", name="update_rate",
                    value=new("rcl_interfaces/msg/ParameterValue", type=2, integer_value=10))
    [result] = call("controller_manager", "set_parameters", "SetParameters", parameters=[parameter]).results
    assert not result.successful and "read-only" in result.reason and "plem launch" in result.reason
