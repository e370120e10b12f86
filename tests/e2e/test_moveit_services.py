"""MoveIt's services and execute_trajectory on a robot brought up by `plem launch`, called as a MoveIt user calls them.

The caller is a DDS participant of the test process, on the launch's domain, built from the moveit_msgs
definitions (whose bytes and type hashes test_moveit_types checks against rosbags and rosidl). It computes FK and
IK, plans to joint and pose goals, edits and reads the planning scene, is refused what plem does not do, and runs
plans with execute_trajectory; shared memory is read only to confirm what the arm did.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from plem.bridge.client import RobotClient, connect
from plem.control.modes import Mode
from plem.control.trajectory import JointTrajectory
from plem.errors import MoveItCode
from plem.middleware.action import ABORTED, CANCELED, SUCCEEDED, ActionClient
from plem.middleware.discovery import DiscoverySettings
from plem.middleware.node import Node
from plem.middleware.node_graph import ROSOUT_QOS
from plem.planning.retiming import fit_to_limits
from tests.e2e import planner_launch
from tests.e2e.launched import Launch, launched_robot, wait_for

launch = planner_launch.launch              # the module's launch, and each test in its domain
same_domain = planner_launch.same_domain

JOINTS = tuple(f"joint{index}" for index in range(6))
#: The SRDF's home state of the built-in Indy7.
HOME = (0.0, 0.0, -math.pi / 2, 0.0, -math.pi / 2, 0.0)
GOAL = (0.4, -0.3, -1.2, 0.2, -1.0, 0.3)
SERVICES = {"compute_fk": "GetPositionFK", "compute_ik": "GetPositionIK", "plan_kinematic_path": "GetMotionPlan",
            "compute_cartesian_path": "GetCartesianPath", "apply_planning_scene": "ApplyPlanningScene",
            "get_planning_scene": "GetPlanningScene"}
DISCOVERY_S = 20.0
CALL_S = 20.0
ARRIVED = 1e-3
BOX, REMOVE = 1, 1   # shape_msgs/SolidPrimitive.BOX, moveit_msgs/CollisionObject.REMOVE
WORLD_GEOMETRY, ATTACHED_OBJECTS = 16, 4   # moveit_msgs/PlanningSceneComponents


class MoveIt:
    """MoveIt's services and action of one robot, as a ROS 2 node on the robot's domain reaches them."""

    def __init__(self, launch: Launch) -> None:
        self.node = Node(DiscoverySettings.from_environment(launch.env))
        self.new = self.node.library.new
        ns = f"/{launch.robot_id}"
        self.clients = {name: self.node.client(f"{ns}/{name}", f"moveit_msgs/srv/{kind}")
                        for name, kind in SERVICES.items()}
        self.execute = ActionClient(self.node, f"{ns}/execute_trajectory", "moveit_msgs/action/ExecuteTrajectory")
        self.rosout = self.node.subscription("/rosout", "rcl_interfaces/msg/Log", ROSOUT_QOS)
        assert wait_for(lambda: all(client.ready for client in self.clients.values()), DISCOVERY_S), \
            "MoveIt's services were not discovered\n" + launch.describe()
        assert self.execute.wait_for_server(DISCOVERY_S), "execute_trajectory was not discovered"

    def call(self, service: str, **fields: Any) -> Any:
        return self.clients[service].call(CALL_S, **fields)

    # -- messages --------------------------------------------------------------------------------------
    def state(self, positions: tuple[float, ...] | list[float]) -> Any:
        joints = self.new("sensor_msgs/msg/JointState", name=list(JOINTS), position=list(positions))
        return self.new("moveit_msgs/msg/RobotState", joint_state=joints)

    def pose(self, position: tuple[float, float, float], orientation: tuple[float, ...] = (0, 0, 0, 1)) -> Any:
        x, y, z = position
        qx, qy, qz, qw = orientation
        return self.new("geometry_msgs/msg/Pose", position=self.new("geometry_msgs/msg/Point", x=x, y=y, z=z),
                        orientation=self.new("geometry_msgs/msg/Quaternion", x=qx, y=qy, z=qz, w=qw))

    def joint_goal(self, positions: tuple[float, ...]) -> Any:
        return self.new("moveit_msgs/msg/Constraints", joint_constraints=[
            self.new("moveit_msgs/msg/JointConstraint", joint_name=name, position=value, tolerance_above=1e-4,
                     tolerance_below=1e-4, weight=1.0) for name, value in zip(JOINTS, positions, strict=True)])

    def pose_goal(self, stamped: Any, link: str) -> Any:
        """Constraints as MoveGroupInterface makes them for a pose target: a small sphere and an orientation."""
        region = self.new("moveit_msgs/msg/BoundingVolume", primitives=[
            self.new("shape_msgs/msg/SolidPrimitive", type=2, dimensions=[1e-4])], primitive_poses=[stamped.pose])
        position = self.new("moveit_msgs/msg/PositionConstraint", header=stamped.header, link_name=link,
                            constraint_region=region, weight=1.0)
        orientation = self.new("moveit_msgs/msg/OrientationConstraint", header=stamped.header, link_name=link,
                               orientation=stamped.pose.orientation, absolute_x_axis_tolerance=1e-3,
                               absolute_y_axis_tolerance=1e-3, absolute_z_axis_tolerance=1e-3, weight=1.0)
        return self.new("moveit_msgs/msg/Constraints", position_constraints=[position],
                        orientation_constraints=[orientation])

    def plan(self, goal: Any, **fields: Any) -> Any:
        request = self.new("moveit_msgs/msg/MotionPlanRequest", goal_constraints=[goal], group_name="arm",
                           allowed_planning_time=5.0, **fields)
        return self.call("plan_kinematic_path", motion_plan_request=request).motion_plan_response

    def fk(self, positions: tuple[float, ...] | list[float], link: str = "tcp") -> Any:
        reply = self.call("compute_fk", fk_link_names=[link], robot_state=self.state(positions))
        assert reply.error_code.val == MoveItCode.SUCCESS, reply.error_code.message
        return reply.pose_stamped[0]

    def scene(self, *objects: Any, attached: tuple[Any, ...] = ()) -> bool:
        """apply_planning_scene of a diff adding (or removing) `objects` and attaching `attached`."""
        scene = self.new("moveit_msgs/msg/PlanningScene", is_diff=True,
                         world=self.new("moveit_msgs/msg/PlanningSceneWorld", collision_objects=list(objects)),
                         robot_state=self.new("moveit_msgs/msg/RobotState", is_diff=True,
                                              attached_collision_objects=list(attached)))
        return bool(self.call("apply_planning_scene", scene=scene).success)

    def read_scene(self, components: int = WORLD_GEOMETRY | ATTACHED_OBJECTS) -> Any:
        request = self.new("moveit_msgs/msg/PlanningSceneComponents", components=components)
        return self.call("get_planning_scene", components=request).scene

    def box(self, name: str, frame: str, position: tuple[float, float, float], size: float) -> Any:
        return self.new("moveit_msgs/msg/CollisionObject", header=self.new("std_msgs/msg/Header", frame_id=frame),
                        id=name, pose=self.pose(position), operation=0, primitives=[
                            self.new("shape_msgs/msg/SolidPrimitive", type=BOX, dimensions=[size] * 3)])

    def close(self) -> None:
        self.node.close()


# -- fixtures ----------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def moveit(launch: Launch) -> Iterator[MoveIt]:
    caller = MoveIt(launch)
    try:
        yield caller
    finally:
        caller.close()


@pytest.fixture(scope="module")
def client(launch: Launch) -> Iterator[RobotClient]:
    with connect(launch.robot_id) as connected:
        yield connected


# -- reading results -------------------------------------------------------------------------------
def read_back(robot_trajectory: Any) -> JointTrajectory:
    """A plan's moveit_msgs/RobotTrajectory as plem reads a ROS trajectory: times from the nanoseconds on the wire."""
    joints = robot_trajectory.joint_trajectory
    assert tuple(joints.joint_names) == JOINTS
    assert (joints.header.stamp.sec, joints.header.stamp.nanosec) == (0, 0), "a plan starts on receipt"
    return JointTrajectory.from_lists(list(joints.joint_names), [
        {"positions": list(p.positions), "velocities": list(p.velocities), "accelerations": list(p.accelerations),
         "time_from_start": p.time_from_start.sec + p.time_from_start.nanosec * 1e-9} for p in joints.points])


def assert_within_limits(trajectory: JointTrajectory, client: RobotClient) -> None:
    """plem's own check: the trajectory runs from rest at its first point as sent, not re-timed."""
    start = np.array(trajectory.points[0].positions)
    timed = fit_to_limits(trajectory, client.limits, (start, np.zeros(6), np.zeros(6)), client.cycle_time_s)
    assert timed.change == "", timed.note()


def distance(a: Any, b: Any) -> tuple[float, float]:
    """Position (m) and rotation (rad) between two geometry_msgs/Pose."""
    pa, pb = a.position, b.position
    qa, qb = a.orientation, b.orientation
    dot = abs(qa.x * qb.x + qa.y * qb.y + qa.z * qb.z + qa.w * qb.w)
    return math.dist((pa.x, pa.y, pa.z), (pb.x, pb.y, pb.z)), 2 * math.acos(min(dot, 1.0))


def at_rest(client: RobotClient) -> bool:
    """Whether the arm holds, its commanded velocity zero."""
    state = client.live_state()
    return state.mode is Mode.HOLD and np.abs(state.command_velocity).max() < 1e-9


def logged(moveit: MoveIt, robot_id: str, text: str) -> bool:
    """Whether move_group's /rosout log has a line holding `text` (waits for it)."""
    seen: list[Any] = []

    def found() -> bool:
        seen.extend(moveit.rosout.take())
        return any(log.name == f"{robot_id}.move_group" and text in log.msg for log in seen)

    return bool(wait_for(found, 5.0))


def udp_sockets(pid: int) -> int:
    """How many UDP sockets (DDS's transport) process `pid` holds."""
    inodes = {line.split()[9] for table in ("udp", "udp6") for line in Path(f"/proc/net/{table}").read_text()
              .splitlines()[1:]}
    links = [os.readlink(f"/proc/{pid}/fd/{fd}") for fd in os.listdir(f"/proc/{pid}/fd")]
    return sum(link.startswith("socket:[") and link[8:-1] in inodes for link in links)


# -- tests -------------------------------------------------------------------------------------------
def test_ik_of_the_pose_fk_gives_for_home_reaches_that_pose(moveit: MoveIt):
    tool = moveit.fk(HOME)
    assert tool.header.frame_id.endswith("/link0"), tool.header.frame_id

    near_home = moveit.state([value + 0.05 for value in HOME])
    request = moveit.new("moveit_msgs/msg/PositionIKRequest", group_name="arm", robot_state=near_home,
                         pose_stamped=tool, ik_link_name="tcp", avoid_collisions=True)
    reply = moveit.call("compute_ik", ik_request=request)
    assert reply.error_code.val == MoveItCode.SUCCESS, reply.error_code.message
    assert tuple(reply.solution.joint_state.name) == JOINTS
    solution = list(reply.solution.joint_state.position)
    assert np.allclose(solution, HOME, atol=1e-3), solution
    assert max(distance(moveit.fk(solution).pose, tool.pose)) < 1e-5

    # From the arm's current state as seed (an empty robot_state), any solution must reach the same pose.
    request.robot_state = moveit.new("moveit_msgs/msg/RobotState", is_diff=True)
    reply = moveit.call("compute_ik", ik_request=request)
    assert reply.error_code.val == MoveItCode.SUCCESS, reply.error_code.message
    assert max(distance(moveit.fk(list(reply.solution.joint_state.position)).pose, tool.pose)) < 1e-5

    # Out of reach: NO_IK_SOLUTION, saying how close it came.
    request.pose_stamped.pose = moveit.pose((3.0, 0.0, 0.5))
    reply = moveit.call("compute_ik", ik_request=request)
    assert reply.error_code.val == MoveItCode.NO_IK_SOLUTION, reply.error_code
    assert "closest came within" in reply.error_code.message, reply.error_code.message


def test_plans_to_joint_and_pose_goals_start_at_the_start_state_and_keep_the_limits(moveit: MoveIt,
                                                                                  client: RobotClient):
    response = moveit.plan(moveit.joint_goal(GOAL), start_state=moveit.state(HOME), num_planning_attempts=2,
                           max_velocity_scaling_factor=0.5)
    assert response.error_code.val == MoveItCode.SUCCESS, response.error_code.message
    assert response.group_name == "arm" and response.planning_time > 0.0
    assert list(response.trajectory_start.joint_state.position) == pytest.approx(HOME)
    trajectory = read_back(response.trajectory)
    assert trajectory.points[0].positions == pytest.approx(HOME, abs=1e-9)
    assert trajectory.points[-1].positions == pytest.approx(GOAL, abs=1e-9)
    assert_within_limits(trajectory, client)
    fastest = max(np.abs(np.array(p.velocities) / client.limits.max_velocity).max() for p in trajectory.points)
    assert fastest <= 0.5 + 1e-9, fastest

    target = moveit.fk(GOAL)
    response = moveit.plan(moveit.pose_goal(target, "tcp"), start_state=moveit.state(HOME))
    assert response.error_code.val == MoveItCode.SUCCESS, response.error_code.message
    trajectory = read_back(response.trajectory)
    assert trajectory.points[0].positions == pytest.approx(HOME, abs=1e-9)
    assert max(distance(moveit.fk(list(trajectory.points[-1].positions)).pose, target.pose)) < 1e-4
    assert_within_limits(trajectory, client)

    path = moveit.call("compute_cartesian_path", start_state=moveit.state(GOAL), group_name="arm", link_name="tcp",
                       header=target.header, max_step=0.01, avoid_collisions=True, waypoints=[
                           moveit.pose((target.pose.position.x, target.pose.position.y,
                                        target.pose.position.z - 0.1), (target.pose.orientation.x,
                                                                        target.pose.orientation.y,
                                                                        target.pose.orientation.z,
                                                                        target.pose.orientation.w))])
    assert path.error_code.val == MoveItCode.SUCCESS and path.fraction == 1.0, path.error_code.message
    end = moveit.fk(list(path.solution.joint_trajectory.points[-1].positions))
    assert end.pose.position.z == pytest.approx(target.pose.position.z - 0.1, abs=1e-4)
    assert_within_limits(read_back(path.solution), client)


def test_a_box_added_to_the_scene_is_listed_and_a_goal_inside_it_is_refused(moveit: MoveIt, launch: Launch):
    tool = moveit.fk(GOAL)
    p = tool.pose.position
    assert moveit.scene(moveit.box("crate", tool.header.frame_id, (p.x, p.y, p.z), 0.15))
    mesh = moveit.new("shape_msgs/msg/Mesh", vertices=[
        moveit.new("geometry_msgs/msg/Point", x=x, y=y, z=z) for x, y, z in ((0, 0, 0), (0.1, 0, 0), (0, 0.1, 0),
                                                                           (0, 0, 0.1))], triangles=[
        moveit.new("shape_msgs/msg/MeshTriangle", vertex_indices=t) for t in ((0, 1, 2), (0, 1, 3), (0, 2, 3),
                                                                              (1, 2, 3))])
    corner = moveit.new("moveit_msgs/msg/CollisionObject", header=moveit.new("std_msgs/msg/Header", frame_id="world"),
                        id="corner", pose=moveit.pose((-0.6, -0.6, 0.0)), meshes=[mesh], operation=0)
    held = moveit.new("moveit_msgs/msg/AttachedCollisionObject", link_name="tcp", touch_links=["link6"],
                      object=moveit.box("probe", "tcp", (0.0, 0.0, 0.03), 0.02))
    assert moveit.scene(corner, attached=(held,))

    scene = moveit.read_scene()
    world = {obj.id: obj for obj in scene.world.collision_objects}
    assert set(world) == {"crate", "corner"}
    crate = world["crate"]
    assert crate.header.frame_id == f"{launch.robot_id}/link0"
    assert (crate.primitives[0].type, list(crate.primitives[0].dimensions)) == (BOX, [0.15] * 3)
    assert distance(crate.pose, tool.pose)[0] < 1e-9
    assert len(world["corner"].meshes[0].triangles) == 4 and len(world["corner"].meshes[0].vertices) == 4
    [attached] = scene.robot_state.attached_collision_objects
    assert (attached.link_name, attached.object.id, list(attached.touch_links)) == ("tcp", "probe", ["link6"])
    assert attached.object.pose.position.z == pytest.approx(0.03)

    response = moveit.plan(moveit.joint_goal(GOAL), start_state=moveit.state(HOME))
    assert response.error_code.val == MoveItCode.GOAL_IN_COLLISION, response.error_code
    assert "crate" in response.error_code.message and "HOW:" in response.error_code.message
    assert not response.trajectory.joint_trajectory.points

    # A change that fails part way changes nothing: the first object is not removed.
    missing = moveit.new("moveit_msgs/msg/CollisionObject", id="nothing_here", operation=REMOVE)
    assert not moveit.scene(moveit.new("moveit_msgs/msg/CollisionObject", id="crate", operation=REMOVE), missing)
    assert {obj.id for obj in moveit.read_scene().world.collision_objects} == {"crate", "corner"}

    # A whole scene (no diff) replaces everything.
    assert moveit.call("apply_planning_scene", scene=moveit.new("moveit_msgs/msg/PlanningScene", name="clear",
                                                                is_diff=False)).success
    scene = moveit.read_scene(WORLD_GEOMETRY | ATTACHED_OBJECTS | 1)
    assert (scene.name, scene.world.collision_objects, scene.robot_state.attached_collision_objects) == ("clear", [],
                                                                                                       [])
    response = moveit.plan(moveit.joint_goal(GOAL), start_state=moveit.state(HOME))
    assert response.error_code.val == MoveItCode.SUCCESS, response.error_code.message


def test_what_plem_does_not_support_is_refused_with_a_code_and_a_message(moveit: MoveIt, launch: Launch):
    response = moveit.plan(moveit.joint_goal(GOAL), path_constraints=moveit.joint_goal(HOME))
    assert response.error_code.val == MoveItCode.FAILURE, response.error_code
    assert "path_constraints is not supported" in response.error_code.message
    assert logged(moveit, launch.robot_id, "path_constraints is not supported")

    two = moveit.new("moveit_msgs/msg/PositionIKRequest", ik_link_names=["tcp", "link3"],
                     pose_stamped_vector=[moveit.fk(HOME), moveit.fk(HOME, "link3")])
    reply = moveit.call("compute_ik", ik_request=two)
    assert reply.error_code.val == MoveItCode.INVALID_LINK_NAME and "ik_link_names" in reply.error_code.message

    unknown = moveit.plan(moveit.joint_goal(GOAL), start_state=moveit.new("moveit_msgs/msg/RobotState", joint_state=(
        moveit.new("sensor_msgs/msg/JointState", name=["elbow"], position=[0.0]))))
    assert unknown.error_code.val == MoveItCode.INVALID_ROBOT_STATE and "elbow" in unknown.error_code.message

    cone = moveit.new("moveit_msgs/msg/CollisionObject", id="cone", operation=0, primitives=[
        moveit.new("shape_msgs/msg/SolidPrimitive", type=4, dimensions=[0.1, 0.05])])
    assert not moveit.scene(cone)
    assert logged(moveit, launch.robot_id, "CONE")


def test_execute_trajectory_moves_the_arm_to_the_goal_and_a_cancel_stops_it(moveit: MoveIt, client: RobotClient):
    response = moveit.plan(moveit.joint_goal(GOAL))
    assert response.error_code.val == MoveItCode.SUCCESS, response.error_code.message
    goal_id, accepted = moveit.execute.send_goal(trajectory=response.trajectory)
    assert accepted
    status, result = moveit.execute.result(goal_id, CALL_S)
    assert (status, result.error_code.val) == (SUCCEEDED, MoveItCode.SUCCESS), result.error_code.message
    assert np.allclose(client.live_state().position, GOAL, atol=ARRIVED), client.live_state().position

    slow = moveit.plan(moveit.joint_goal(HOME), max_velocity_scaling_factor=0.1)
    goal_id, accepted = moveit.execute.send_goal(trajectory=slow.trajectory)
    assert accepted
    assert wait_for(lambda: np.abs(np.array(client.live_state().position) - GOAL).max() > 0.02, 5.0), \
        "the arm did not start moving"
    moveit.execute.cancel(goal_id)
    status, result = moveit.execute.result(goal_id, CALL_S)
    assert (status, result.error_code.val) == (CANCELED, MoveItCode.PREEMPTED), result.error_code.message
    assert wait_for(lambda: at_rest(client), 5.0), f"the arm did not stop: {client.live_state()}"
    stopped = np.array(client.live_state().position)
    assert np.abs(stopped - HOME).max() > 0.1, stopped

    # A trajectory the robot refuses fails with CONTROL_FAILED and the reason; the arm stays where it is.
    refused = slow.trajectory
    refused.joint_trajectory.joint_names[0] = "elbow"
    goal_id, accepted = moveit.execute.send_goal(trajectory=refused)
    status, result = moveit.execute.result(goal_id, CALL_S)
    assert (status, result.error_code.val) == (ABORTED, MoveItCode.CONTROL_FAILED), result.error_code
    assert "elbow" in result.error_code.message and "HOW:" in result.error_code.message
    assert np.allclose(client.live_state().position, stopped, atol=1e-6)


def test_without_dds_the_planner_serves_plem_clients_alone(tmp_path_factory: pytest.TempPathFactory):
    with launched_robot(tmp_path_factory, "record:=false", "planner:=true", "bridge:=false", ros=True) as running, \
            connect(running.robot_id) as robot:
        assert robot.plan("zero").trajectory.points, "the planner does not answer plem's clients"
        assert udp_sockets(running.component_pid("planner")) == 0
