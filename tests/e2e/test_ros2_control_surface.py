"""The ros2_control surface of `plem launch`, reached by a peer built only from public ROS 2 definitions.

`PublicPeer` knows nothing of plem's DDS code: its types are written from the ROS 2 Jazzy interface
definitions, its names and QoS follow rmw_cyclonedds. Through it this test lists and switches controllers,
drives the hardware component's lifecycle, runs FollowJointTrajectory goals, reads joint_states, /tf and
/tf_static, and matches the nodes announced on ros_discovery_info with the endpoints DDS discovery reports.
Shared memory is read only to confirm what the RT driver did.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path

import pytest

from plem.bridge import connect
from plem.control.modes import Mode
from tests.e2e.launched import Launch, join_domain, launched_robot
from tests.e2e.public_peer import (
    PRIMARY_STATE_ACTIVE,
    PRIMARY_STATE_INACTIVE,
    STATUS_ABORTED,
    STATUS_SUCCEEDED,
    STRICT,
    TF,
    TF_STATIC,
    ControllerManager,
    FollowJointTrajectoryClient,
    JointState,
    JointTrajectory,
    PublicPeer,
    TFMessage,
    gid_bytes,
    point,
    take,
    trajectory,
    wait_for,
)
from tests.integration.packages import copy_builtin

JOINT_NAMES = tuple(f"joint{index}" for index in range(6))
ARRIVED = 1e-3
DISCOVERY_S = 20.0
GOAL_S = 20.0
#: The built-in arms' controllers, as the configuration reference's controllers.yaml gives them.
TRAJECTORY = "joint_trajectory_controller"
CONTROLLER_TYPES = {"joint_state_broadcaster": "joint_state_broadcaster/JointStateBroadcaster",
                    TRAJECTORY: "joint_trajectory_controller/JointTrajectoryController",
                    "free_drive_controller": "wim_controller/FreeDriveController"}
UPDATE_RATE = 500
NODES = {"controller_manager", "joint_state_broadcaster", TRAJECTORY, "robot_state_publisher", "wim_rt_driver"}


class Robot:
    """One launched robot as a ROS 2 user reaches it: its controller manager, its trajectory action, its topics."""

    def __init__(self, launch: Launch, trajectory_controller: str = TRAJECTORY) -> None:
        self.launch = launch
        self.robot_id = launch.robot_id
        self.peer = PublicPeer(launch.env)
        ns = f"/{self.robot_id}"
        self.manager = ControllerManager(self.peer, f"{ns}/controller_manager")
        self.follow = FollowJointTrajectoryClient(self.peer, f"{ns}/{trajectory_controller}/follow_joint_trajectory")
        self.trajectory_topic = f"{ns}/{trajectory_controller}/joint_trajectory"
        self.joint_states = self.peer.subscription(f"{ns}/joint_states", JointState)
        self.tf = self.peer.subscription("/tf", TFMessage, TF)

    def unmatched(self) -> list[str]:
        """The endpoints of this peer that no endpoint of the robot matches (yet)."""
        missing = []
        for service in (*self.manager.services, *self.follow.services):
            if not service.requests_matched:
                missing.append(f"{service.service} (request)")
            if not service.replies_matched:
                missing.append(f"{service.service} (reply)")
        if not self.joint_states.get_subscription_matched_status().current_count:
            missing.append("joint_states")
        return missing

    def ready(self, timeout: float = DISCOVERY_S) -> None:
        """Wait until the robot's services, action and joint_states match this peer's endpoints."""
        wait_for(lambda: not self.unmatched(), timeout)
        assert not self.unmatched(), f"not matched within {timeout} s: {', '.join(self.unmatched())}"

    def joint_state(self, timeout: float = 5.0) -> JointState:
        """A JointState published after this call."""
        take(self.joint_states, 10_000)
        message = wait_for(lambda: take(self.joint_states, 10_000), timeout)
        assert message, f"no joint_states within {timeout} s"
        return message[-1]

    def position(self) -> list[float]:
        state = self.joint_state()
        assert tuple(state.name) == JOINT_NAMES, state.name
        return list(state.position)

    def run(self, goal, timeout: float = GOAL_S):
        """Send a FollowJointTrajectory goal, which must be accepted, and wait for its end: (status, result)."""
        goal_id, accepted = self.follow.send_goal(goal)
        assert accepted, "the FollowJointTrajectory goal was not accepted"
        return self.follow.result(goal_id, timeout)

    def publish_and_follow(self, joint: int, distance: float) -> None:
        """Publish a one-point JointTrajectory moving `joint` by `distance` rad on the trajectory controller's topic,
        as `ros2 topic pub` does, and wait until joint_states read the goal."""
        writer = self.peer.publisher(self.trajectory_topic, JointTrajectory)
        assert wait_for(lambda: writer.get_publication_matched_status().current_count, DISCOVERY_S), \
            f"nothing subscribes to {self.trajectory_topic}"
        target, _ = toward_middle(self.position(), joint, distance)
        writer.write(trajectory(JOINT_NAMES, [point(target, 1.5)]))

        def arrived() -> bool:
            return all(abs(a - b) < ARRIVED for a, b in zip(self.position(), target, strict=True))

        assert wait_for(arrived, GOAL_S), (self.position(), target)

    def close(self) -> None:
        self.peer.close()


# -- fixtures ----------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def launch(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Launch]:
    with launched_robot(tmp_path_factory, ros=True) as running:
        yield running


@pytest.fixture(autouse=True)
def same_domain(isolated_environment: Path, monkeypatch: pytest.MonkeyPatch, launch: Launch) -> None:
    join_domain(monkeypatch, launch)


@pytest.fixture(scope="module")
def robot(launch: Launch) -> Iterator[Robot]:
    ros = Robot(launch)
    try:
        yield ros
    finally:
        ros.close()


# -- helpers -----------------------------------------------------------------------------------------
def toward_middle(position: list[float], joint: int, distance: float) -> tuple[list[float], float]:
    """`position` with one joint moved by `distance` rad towards 0, and the direction (+1 or -1)."""
    direction = -1.0 if position[joint] > 0 else 1.0
    moved = list(position)
    moved[joint] += direction * distance
    return moved, direction


def trapezoid(start: list[float], joint: int, direction: float, acceleration: float = 0.5, ramp: float = 0.5,
              cruise: float = 1.0, step: float = 0.1):
    """Points every `step` s of a trapezoidal velocity profile on one joint (the others still): accelerate for
    `ramp` s, cruise, decelerate for `ramp` s to rest. Each point carries positions, velocities and accelerations."""
    speed = acceleration * ramp
    total = 2 * ramp + cruise
    points = []
    for index in range(round(total / step) + 1):
        t = index * step
        if t < ramp - 1e-9:
            s, v, a = 0.5 * acceleration * t * t, acceleration * t, acceleration
        elif t < ramp + cruise - 1e-9:
            s, v, a = 0.5 * acceleration * ramp * ramp + speed * (t - ramp), speed, 0.0
        else:
            d = min(t, total) - ramp - cruise
            s = 0.5 * acceleration * ramp * ramp + speed * cruise + speed * d - 0.5 * acceleration * d * d
            v, a = speed - acceleration * d, -acceleration
        if index == round(total / step):
            v, a = 0.0, 0.0        # the last point at rest
        positions, velocities, accelerations = list(start), [0.0] * len(start), [0.0] * len(start)
        positions[joint] += direction * s
        velocities[joint] = direction * v
        accelerations[joint] = direction * a
        points.append(point(positions, t, velocities, accelerations))
    return points


def transforms_by_child(messages: list[TFMessage]) -> dict[str, object]:
    """The newest transform of each child frame in `messages`."""
    return {transform.child_frame_id: transform for message in messages for transform in message.transforms}


def same_rotation(quaternion, expected: tuple[float, float, float, float], atol: float) -> bool:
    """Whether a geometry_msgs/Quaternion is `expected` (x, y, z, w), up to the sign of the whole quaternion."""
    got = (quaternion.x, quaternion.y, quaternion.z, quaternion.w)
    return any(all(abs(sign * g - e) <= atol for g, e in zip(got, expected, strict=True)) for sign in (1.0, -1.0))


# -- tests -------------------------------------------------------------------------------------------
def test_a_ros2_control_user_switches_controllers_drives_the_hardware_and_moves_the_arm(robot: Robot):
    robot.ready()
    manager, robot_id = robot.manager, robot.robot_id

    # The controllers, their types and their states at start: the arm holds under the trajectory controller.
    controllers = manager.list_controllers()
    assert set(CONTROLLER_TYPES) <= set(controllers), set(controllers)
    assert {name: controllers[name].type for name in CONTROLLER_TYPES} == CONTROLLER_TYPES
    assert {name: controllers[name].state for name in CONTROLLER_TYPES} == {
        "joint_state_broadcaster": "active", TRAJECTORY: "active", "free_drive_controller": "inactive"}

    with connect(robot_id) as client:
        # Free drive and back, each in one request that swaps the two controllers.
        reply = manager.switch_controller(activate=["free_drive_controller"], deactivate=[TRAJECTORY])
        assert reply.ok, reply.message
        states = manager.states()
        assert (states[TRAJECTORY], states["free_drive_controller"]) == ("inactive", "active"), states
        assert client.state().mode is Mode.FREE_DRIVE
        reply = manager.switch_controller(activate=[TRAJECTORY], deactivate=["free_drive_controller"])
        assert reply.ok, reply.message
        states = manager.states()
        assert (states[TRAJECTORY], states["free_drive_controller"]) == ("active", "inactive"), states
        assert client.state().mode is Mode.HOLD

        # The hardware component: inactive disables the drives, and a goal sent then is aborted naming the fix.
        components = manager.list_hardware_components()
        assert len(components) == 1, [component.name for component in components]
        hardware = components[0].name
        assert components[0].state.id == PRIMARY_STATE_ACTIVE, components[0].state
        reply = manager.set_hardware_component_state(hardware, PRIMARY_STATE_INACTIVE, "inactive")
        assert (reply.ok, reply.state.id) == (True, PRIMARY_STATE_INACTIVE), reply
        assert manager.list_hardware_components()[0].state.id == PRIMARY_STATE_INACTIVE
        assert client.state().mode is Mode.IDLE and not client.state().drives_enabled
        start = robot.position()
        target, _ = toward_middle(start, 2, 0.1)
        status, result = robot.run(trajectory(JOINT_NAMES, [point(target, 1.5)]))
        assert status == STATUS_ABORTED, (status, result)
        assert "set_hardware_component_state" in result.error_string, result.error_string
        assert all(abs(a - b) < 1e-4 for a, b in zip(robot.position(), start, strict=True)), "the arm moved"

        reply = manager.set_hardware_component_state(hardware, PRIMARY_STATE_ACTIVE, "active")
        assert (reply.ok, reply.state.id) == (True, PRIMARY_STATE_ACTIVE), reply
        assert manager.list_hardware_components()[0].state.id == PRIMARY_STATE_ACTIVE
        assert manager.states()[TRAJECTORY] == "active"
        assert client.state().mode is Mode.HOLD and client.state().drives_enabled

    # A one-point, positions-only goal, as `ros2 action send_goal` users write it.
    status, result = robot.run(trajectory(JOINT_NAMES, [point(target, 1.5)]))
    assert (status, result.error_code) == (STATUS_SUCCEEDED, 0), (status, result.error_string)
    arrived = robot.position()
    assert all(abs(a - b) < ARRIVED for a, b in zip(arrived, target, strict=True)), (arrived, target)

    # A time-parameterised trajectory as MoveIt sends one: a trapezoidal velocity profile sampled every 0.1 s with
    # positions, velocities and accelerations, its first point the current state from joint_states at time 0.
    start = robot.position()
    end, direction = toward_middle(start, 1, 0.375)
    points = trapezoid(start, 1, direction)
    assert len(points) == 21 and abs(points[-1].positions[1] - end[1]) < 1e-12
    status, result = robot.run(trajectory(JOINT_NAMES, points))
    assert (status, result.error_code) == (STATUS_SUCCEEDED, 0), (status, result.error_string)
    arrived = robot.position()
    assert all(abs(a - b) < ARRIVED for a, b in zip(arrived, end, strict=True)), (arrived, end, result.error_string)

    # /tf: the moving joints' transforms, frames prefixed with the robot id.
    seen: list[TFMessage] = []
    moving = {f"{robot_id}/link{index}": f"{robot_id}/link{index - 1}" for index in range(1, 7)}

    def all_moving() -> bool:
        seen.extend(take(robot.tf, 1000))
        return set(moving) <= set(transforms_by_child(seen))

    take(robot.tf, 10_000)
    assert wait_for(all_moving, 5), sorted(transforms_by_child(seen))
    frames = transforms_by_child(seen)
    assert {child: frames[child].header.frame_id for child in moving} == moving
    q0 = robot.position()[0]
    link1 = frames[f"{robot_id}/link1"].transform   # joint0: 0.0775 m up, turning about z
    assert (link1.translation.x, link1.translation.y) == pytest.approx((0.0, 0.0), abs=1e-9)
    assert link1.translation.z == pytest.approx(0.0775, abs=1e-9)
    assert same_rotation(link1.rotation, (0.0, 0.0, math.sin(q0 / 2), math.cos(q0 / 2)), 1e-5), (link1.rotation, q0)

    # /tf_static: the fixed transforms, still there for a reader that starts now.
    static = robot.peer.subscription("/tf_static", TFMessage, TF_STATIC)
    latched = wait_for(lambda: take(static), 5)
    assert latched, "no /tf_static for a late reader"
    fixed = transforms_by_child(latched)
    assert f"{robot_id}/tcp" in fixed, sorted(fixed)
    tcp = fixed[f"{robot_id}/tcp"]
    assert tcp.header.frame_id == f"{robot_id}/link6"
    assert (tcp.transform.translation.x, tcp.transform.translation.y, tcp.transform.translation.z) == \
        pytest.approx((0.0, 0.0, 0.06), abs=1e-9)
    assert not set(moving) & set(fixed), "moving frames on /tf_static"


def test_list_controllers_shows_the_configuration_references_three_controllers(robot: Robot):
    """The built-in arm's controllers, their rate and interfaces, as its controllers.yaml (the spec's) gives them."""
    robot.ready()
    controllers = robot.manager.list_controllers()
    assert {name: controller.type for name, controller in controllers.items()} == CONTROLLER_TYPES
    assert {controller.update_rate for controller in controllers.values()} == {UPDATE_RATE}
    trajectory_controller = controllers[TRAJECTORY]
    commands = [f"{joint}/{interface}" for joint in JOINT_NAMES
                for interface in ("position", "velocity", "acceleration")]
    assert list(trajectory_controller.required_command_interfaces) == commands
    assert list(trajectory_controller.claimed_interfaces) == commands           # active: it claims them
    assert list(trajectory_controller.required_state_interfaces) == \
        [f"{joint}/{interface}" for joint in JOINT_NAMES for interface in ("position", "velocity")]
    [hardware] = robot.manager.list_hardware_components()
    claimed = {interface.name for interface in hardware.command_interfaces if interface.is_claimed}
    assert claimed == set(commands), sorted(claimed)


def test_a_trajectory_published_on_the_spec_controllers_topic_moves_the_built_in_arm(robot: Robot):
    """`/{robot}/joint_trajectory_controller/joint_trajectory`, as a ROS 2 user who reads the spec publishes it."""
    robot.ready()
    assert robot.manager.states()[TRAJECTORY] == "active"
    robot.publish_and_follow(joint=3, distance=0.2)


def test_an_external_package_keeps_the_generated_arm_controller(tmp_path_factory: pytest.TempPathFactory):
    """A package without controllers.yaml runs the Description Package Protocol's generated `arm_controller`."""
    package = copy_builtin("indy7_v2", tmp_path_factory.mktemp("external"))
    (package / "config" / "controllers.yaml").unlink()
    with launched_robot(tmp_path_factory, f"description_package:={package}", ros=True) as launch:
        external = Robot(launch, trajectory_controller="arm_controller")
        try:
            external.ready()
            controllers = external.manager.list_controllers()
            generated = {name if name != TRAJECTORY else "arm_controller": kind
                         for name, kind in CONTROLLER_TYPES.items()}
            assert {name: controller.type for name, controller in controllers.items()} == generated
            assert {controller.update_rate for controller in controllers.values()} == {1000}   # the loop's rate
            external.publish_and_follow(joint=3, distance=0.2)
        finally:
            external.close()


def test_an_update_rate_above_the_loops_is_reported_as_the_loops_with_a_warning(
        tmp_path_factory: pytest.TempPathFactory):
    """update_rate: 2000 on a 1000 µs loop: list_controllers says 1000 Hz, and the launch says why and how to fix it."""
    package = copy_builtin("indy7_v2", tmp_path_factory.mktemp("fast"))
    controllers = package / "config" / "controllers.yaml"
    controllers.write_text(controllers.read_text().replace("update_rate: 500", "update_rate: 2000"))
    with launched_robot(tmp_path_factory, f"description_package:={package}", "cycle_time:=1000", ros=True) as launch:
        fast = Robot(launch)
        try:
            fast.ready()
            assert {controller.update_rate for controller in fast.manager.list_controllers().values()} == {1000}
            warning = "update_rate 2000 Hz is above the loop's 1000 Hz"
            assert wait_for(lambda: warning in launch.output + launch.errors, 10), launch.describe()
            assert "HOW: set update_rate: 1000 (or less)" in launch.output + launch.errors
        finally:
            fast.close()


def test_a_strict_switch_naming_an_unknown_controller_is_refused_and_changes_nothing(robot: Robot):
    robot.ready()
    manager = robot.manager
    before = manager.states()
    assert (before[TRAJECTORY], before["free_drive_controller"]) == ("active", "inactive"), before
    reply = manager.switch_controller(activate=["free_drive_controller", "no_such_controller"],
                                      deactivate=[TRAJECTORY], strictness=STRICT)
    assert not reply.ok
    assert "no_such_controller" in reply.message, reply.message
    assert manager.states() == before
    with connect(robot.robot_id) as client:
        assert client.state().mode is Mode.HOLD


def test_ros_discovery_info_names_the_nodes_and_their_endpoints(robot: Robot):
    """Each announced node's GIDs are the GUIDs of the DDS endpoints that DDS discovery reports for it."""
    ns = f"/{robot.robot_id}"
    graph = robot.peer.graph()
    announced: dict[bytes, object] = {}

    def names(info) -> set[str]:
        return {node.node_name for node in info.node_entities_info_seq if node.node_namespace == ns}

    def robot_participant():
        for info in take(graph):
            announced[gid_bytes(info.gid)] = info
        return next((info for info in announced.values() if names(info) >= NODES), None)

    info = wait_for(robot_participant, DISCOVERY_S, period=0.05)
    assert info is not None, {gid.hex(): [(n.node_namespace, n.node_name) for n in i.node_entities_info_seq]
                              for gid, i in announced.items()}
    participant = gid_bytes(info.gid)
    nodes = {node.node_name: node for node in info.node_entities_info_seq if node.node_namespace == ns}

    def endpoints(publications: bool, dds_topic: str) -> set[bytes]:
        """GUIDs of the robot participant's writers (readers) on `dds_topic`, as DDS discovery reports them."""
        return {key.bytes for key, sample in robot.peer.discovered(publications).items()
                if sample.topic_name == dds_topic and sample.participant_key.bytes == participant}

    joint_states = f"rt{ns}/joint_states"
    send_goal = f"rq{ns}/{TRAJECTORY}/follow_joint_trajectory/_action/send_goalRequest"
    list_controllers = f"rq{ns}/controller_manager/list_controllersRequest"
    wanted = {"joint_state_broadcaster": (True, joint_states), TRAJECTORY: (False, send_goal),
              "controller_manager": (False, list_controllers), "robot_state_publisher": (True, "rt/tf")}
    assert wait_for(lambda: all(endpoints(*endpoint) for endpoint in wanted.values()), DISCOVERY_S), \
        {name: len(endpoints(*endpoint)) for name, endpoint in wanted.items()}

    def gids(name: str, writers: bool) -> set[bytes]:
        node = nodes[name]
        return {gid_bytes(gid) for gid in (node.writer_gid_seq if writers else node.reader_gid_seq)}

    for name, (publications, dds_topic) in wanted.items():
        assert endpoints(publications, dds_topic) <= gids(name, publications), (name, dds_topic)

    # Every GID a node names is an endpoint of the announcing participant that DDS discovery knows.
    named = {gid for name in nodes for writers in (True, False) for gid in gids(name, writers)}

    def unknown() -> set[bytes]:
        known = {key.bytes for publications in (True, False)
                 for key, sample in robot.peer.discovered(publications).items()
                 if sample.participant_key.bytes == participant}
        return named - known

    assert wait_for(lambda: not unknown(), DISCOVERY_S), f"{len(unknown())} of {len(named)} announced GIDs are no " \
        "endpoint of the participant"
