"""Straight, circular and blended motions on a robot brought up by `plem launch bus:=mock`: through plem's process
client (move_linear, move_circular, move_sequence), and as a MoveIt user asks for them (plan_kinematic_path with
Pilz's planner ids, plan_sequence_path). The arm's states are read from shared memory while it moves, and the tool's
pose at each from the planner's FK."""

from __future__ import annotations

import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from plem.bridge.client import RobotClient, connect
from plem.control.state import JointState
from plem.errors import MoveItCode, PlanningError
from plem.planning.poses import Pose
from plem.planning.sequence import Joint, Linear, ToolLimits
from tests.e2e import planner_launch
from tests.e2e.cli import run_plem
from tests.e2e.launched import Launch, wait_for
from tests.e2e.test_moveit_services import MoveIt, assert_within_limits, read_back

launch = planner_launch.launch              # the module's launch, and each test in its domain
same_domain = planner_launch.same_domain

DOWN = (0.0, 1.0, 0.0, 0.0)
MOTION_S = 30.0


@pytest.fixture(scope="module")
def client(launch: Launch) -> Iterator[RobotClient]:
    with connect(launch.robot_id) as connected:
        connected.set_mode("hold")
        yield connected


@pytest.fixture
def at_home(client: RobotClient) -> RobotClient:
    assert client.move_to("home").wait(MOTION_S).succeeded
    return client


def recorded(client: RobotClient, handle: Any) -> list[JointState]:
    """The arm's state, read every 2 ms from shared memory until the motion ends (it succeeds)."""
    states = []
    while not handle.done:
        states.append(client.live_state())
        time.sleep(0.002)
    result = handle.wait(MOTION_S)
    assert result.succeeded, result.message
    return states


def tool(client: RobotClient, states: list[JointState], field: str = "position") -> np.ndarray:
    return np.array([client.compute_fk(list(getattr(state, field)), ["tcp"])["tcp"].position for state in states])


def off_line(points: np.ndarray, begin: np.ndarray, end: np.ndarray) -> np.ndarray:
    line = end - begin
    share = np.clip((points - begin) @ line / (line @ line), 0.0, 1.0)
    return np.linalg.norm(points - begin - share[:, None] * line, axis=1)


def within_limits(client: RobotClient, states: list[JointState]) -> None:
    limits = client.limits
    velocity = np.array([state.command_velocity for state in states])
    acceleration = np.array([state.command_acceleration for state in states])
    assert np.all(np.abs(velocity) <= limits.max_velocity) and np.all(np.abs(acceleration) <= limits.max_acceleration)


def test_a_linear_move_keeps_the_tool_on_the_line(at_home: RobotClient) -> None:
    client = at_home
    begin = np.array(client.compute_fk(links=["tcp"])["tcp"].position)
    goal = Pose(tuple(begin + np.array([0.1, 0.1, -0.12])), DOWN)
    states = recorded(client, client.move_linear(goal))
    within_limits(client, states)
    commanded = tool(client, states[::4], "command_position")
    measured = tool(client, states[::4])
    assert off_line(commanded, begin, np.array(goal.position)).max() < 1e-4  # 0.1 mm
    assert off_line(measured, begin, np.array(goal.position)).max() < 1e-3  # 1 mm, following error included
    cycles = np.diff([s.cycle for s in states[::4]]) * client.cycle_time_s   # the loop's own clock, not its wake-ups
    speed = np.linalg.norm(np.diff(commanded, axis=0), axis=1) / cycles
    assert speed.max() <= ToolLimits().max_trans_vel * 1.05
    np.testing.assert_allclose(client.compute_fk(links=["tcp"])["tcp"].position, goal.position, atol=1e-3)


def test_a_circular_move_keeps_the_tool_on_the_arc(at_home: RobotClient) -> None:
    client = at_home
    begin = np.array(client.compute_fk(links=["tcp"])["tcp"].position)
    center = begin + np.array([0.0, 0.1, 0.0])
    end = center + np.array([0.1, 0.0, 0.0])
    via = center + 0.1 * np.array([np.sqrt(0.5), -np.sqrt(0.5), 0.0])
    states = recorded(client, client.move_circular(tuple(via), Pose(tuple(end), DOWN)))
    within_limits(client, states)
    commanded = tool(client, states[::4], "command_position")
    assert np.abs(np.linalg.norm(commanded - center, axis=1) - 0.1).max() < 1e-4
    assert np.abs(commanded[:, 2] - begin[2]).max() < 1e-4


def test_a_blended_sequence_never_stops_between_its_start_and_end(at_home: RobotClient) -> None:
    client = at_home
    begin = np.array(client.compute_fk(links=["tcp"])["tcp"].position)
    corners = [begin + np.array(offset) for offset in ((0.0, 0.0, -0.12), (0.12, 0.0, -0.12), (0.12, 0.12, -0.12))]
    items = [*(Linear(Pose(tuple(corner), DOWN), blend=0.04) for corner in corners), Joint("home")]
    states = recorded(client, client.move_sequence(items))
    within_limits(client, states)
    speed = np.array([np.linalg.norm(state.command_velocity) for state in states])
    moving = np.flatnonzero(speed > 1e-2)  # from its first start to its last stop, the joints never stop
    assert speed[moving[0]:moving[-1]].min() > 1e-3, "the arm stopped at a corner"
    commanded = tool(client, states[::4], "command_position")
    for corner in corners:  # each corner is passed inside its blend radius, never reached
        assert 1e-3 < np.linalg.norm(commanded - corner, axis=1).min() < 0.04


def test_refusals_through_the_client_name_the_item_and_pose(at_home: RobotClient) -> None:
    with pytest.raises(PlanningError) as far:
        at_home.plan_sequence([Linear(Pose((0.4, -0.2, 0.5), DOWN)), Linear(Pose((1.6, 0.0, 0.5), DOWN))])
    assert far.value.code == MoveItCode.NO_IK_SOLUTION and "item 1" in far.value.summary
    assert "(1.600, 0.000, 0.500)" in far.value.why
    wrist = [0.3, -0.2, -1.2, 0.0, -0.3, 0.0]
    beyond = at_home.compute_fk([0.3, -0.2, -1.2, 0.0, 0.3, 0.0], ["tcp"])["tcp"]
    with pytest.raises(PlanningError) as singular:
        at_home.plan_sequence([Linear(beyond)], start=wrist)
    assert "item 0 passes a singularity" in singular.value.summary and "tool pose position" in singular.value.why


class Pilz(MoveIt):
    """MoveIt's services with pilz_industrial_motion_planner's plan_sequence_path."""

    def __init__(self, launch: Launch) -> None:
        super().__init__(launch)
        self.clients["plan_sequence_path"] = self.node.client(f"/{launch.robot_id}/plan_sequence_path",
                                                              "moveit_msgs/srv/GetMotionSequence")
        assert wait_for(lambda: self.clients["plan_sequence_path"].ready, 20.0), "plan_sequence_path was not found"

    def request(self, planner_id: str, goal: Any, **fields: Any) -> Any:
        return self.new("moveit_msgs/msg/MotionPlanRequest", goal_constraints=[goal], group_name="arm",
                        planner_id=planner_id, pipeline_id="pilz_industrial_motion_planner",
                        max_velocity_scaling_factor=0.5, max_acceleration_scaling_factor=0.5, **fields)


@pytest.fixture(scope="module")
def pilz(launch: Launch) -> Iterator[Pilz]:
    caller = Pilz(launch)
    try:
        yield caller
    finally:
        caller.close()


def test_moveit_plans_pilz_ptp_lin_and_circ_and_sequences(pilz: Pilz, client: RobotClient) -> None:
    home = [0.0, 0.0, -np.pi / 2, 0.0, -np.pi / 2, 0.0]
    start = pilz.fk(home)
    target = pilz.new("geometry_msgs/msg/PoseStamped", header=start.header,
                      pose=pilz.pose((start.pose.position.x + 0.1, start.pose.position.y, start.pose.position.z - 0.1),
                                     DOWN))
    line = pilz.call("plan_kinematic_path", motion_plan_request=pilz.request(
        "LIN", pilz.pose_goal(target, "tcp"), start_state=pilz.state(home))).motion_plan_response
    assert line.error_code.val == MoveItCode.SUCCESS, line.error_code.message
    trajectory = read_back(line.trajectory)
    assert_within_limits(trajectory, client)
    begin = np.array([start.pose.position.x, start.pose.position.y, start.pose.position.z])
    end = begin + np.array([0.1, 0.0, -0.1])
    points = np.array([client.compute_fk(list(p.positions), ["tcp"])["tcp"].position for p in trajectory.points])
    assert off_line(points, begin, end).max() < 1e-4

    ptp = pilz.call("plan_kinematic_path", motion_plan_request=pilz.request(
        "PTP", pilz.joint_goal((0.3, 0.0, -1.5, 0.0, -1.5, 0.0)), start_state=pilz.state(home))).motion_plan_response
    assert ptp.error_code.val == MoveItCode.SUCCESS, ptp.error_code.message
    assert read_back(ptp.trajectory).points[-1].positions == pytest.approx((0.3, 0.0, -1.5, 0.0, -1.5, 0.0), abs=1e-9)

    center = begin + np.array([0.0, 0.05, 0.0])
    via = center + 0.05 * np.array([np.sqrt(0.5), -np.sqrt(0.5), 0.0])
    interim = pilz.new("moveit_msgs/msg/Constraints", name="interim", position_constraints=[
        pilz.new("moveit_msgs/msg/PositionConstraint", header=start.header, link_name="tcp",
                 constraint_region=pilz.new("moveit_msgs/msg/BoundingVolume",
                                            primitive_poses=[pilz.pose(tuple(via))]))])
    arc_end = pilz.new("geometry_msgs/msg/PoseStamped", header=start.header,
                       pose=pilz.pose(tuple(center + np.array([0.05, 0.0, 0.0])), DOWN))
    arc = pilz.call("plan_kinematic_path", motion_plan_request=pilz.request(
        "CIRC", pilz.pose_goal(arc_end, "tcp"), start_state=pilz.state(home),
        path_constraints=interim)).motion_plan_response
    assert arc.error_code.val == MoveItCode.SUCCESS, arc.error_code.message
    points = np.array([client.compute_fk(list(p.positions), ["tcp"])["tcp"].position
                       for p in read_back(arc.trajectory).points])
    assert np.abs(np.linalg.norm(points - center, axis=1) - 0.05).max() < 1e-4

    items = [pilz.new("moveit_msgs/msg/MotionSequenceItem", blend_radius=0.03, req=pilz.request(
                 "LIN", pilz.pose_goal(target, "tcp"), start_state=pilz.state(home))),
             pilz.new("moveit_msgs/msg/MotionSequenceItem", blend_radius=0.0, req=pilz.request(
                 "PTP", pilz.joint_goal((0.3, 0.0, -1.5, 0.0, -1.5, 0.0))))]
    sequence = pilz.call("plan_sequence_path", request=pilz.new("moveit_msgs/msg/MotionSequenceRequest",
                                                                 items=items)).response
    assert sequence.error_code.val == MoveItCode.SUCCESS, sequence.error_code.message
    assert len(sequence.planned_trajectories) == 1
    blended = read_back(sequence.planned_trajectories[0])
    assert_within_limits(blended, client)
    velocities = np.array([np.linalg.norm(p.velocities) for p in blended.points])
    assert velocities[1:-1].min() > 0.0  # through the corner without stopping

    items[-1].blend_radius = 0.02
    refused = pilz.call("plan_sequence_path", request=pilz.new("moveit_msgs/msg/MotionSequenceRequest",
                                                                items=items)).response
    assert refused.error_code.val == MoveItCode.INVALID_MOTION_PLAN
    assert "the last item has a blend radius" in refused.error_code.message


def test_plem_move_linear_moves_the_tool_straight_or_says_why_not(at_home: RobotClient, launch: Launch) -> None:
    robot = ("--robot-id", launch.robot_id)
    begin = np.array(at_home.compute_fk(links=["tcp"])["tcp"].position)
    goal = begin + np.array([0.05, 0.05, -0.1])
    moved = run_plem("move", "--to-pose", *map(str, goal), "0", "1", "0", "0", "--linear", *robot, env=launch.env)
    assert moved.returncode == 0, moved.stderr
    assert "LIN:" in moved.stdout and "every limit kept" in moved.stdout
    np.testing.assert_allclose(at_home.compute_fk(links=["tcp"])["tcp"].position, goal, atol=1e-3)
    both = run_plem("move", "--to-pose", *map(str, goal), "0", "1", "0", "0", "--linear", "--cartesian", *robot,
                    env=launch.env)
    assert both.returncode == 2 and "exclude each other" in both.stderr
    far = run_plem("move", "--to-pose", "1.6", "0", "0.5", "0", "1", "0", "0", "--linear", *robot, env=launch.env)
    assert far.returncode == 1 and "Traceback" not in far.stderr
    assert "outside the arm's workspace" in far.stderr and "HOW:" in far.stderr
