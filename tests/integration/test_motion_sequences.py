"""Straight, circular and blended motions planned on the built-in Indy7 (pinocchio, coal, the real planner), read
back exactly as the RT driver runs them, cycle by cycle: the tool stays on its line or arc, corners with a blend
radius are passed without stopping and sooner than stopping at them, every joint limit and the tool's speed limits
hold, and what cannot be followed is refused naming the item and pose."""

from __future__ import annotations

import time

import numpy as np
import pinocchio as pin
import pytest

from plem.control.limits import ArmLimits
from plem.description.validate import validate_package
from plem.errors import MoveItCode, PlanningError
from plem.planning.goals import Plan, PlanOptions
from plem.planning.planner import Planner, placement_of
from plem.planning.poses import Pose
from plem.planning.retiming import fit_to_limits
from plem.planning.scene import Box, SceneObject
from plem.planning.sequence import Circular, Joint, Linear, ToolLimits
from tests.integration.robot_fixtures import simulated_robot

CYCLE_S = 0.001
DOWN = (0.0, 1.0, 0.0, 0.0)  # the tool pointing down
#: A square of corners 15 cm apart below the Indy7's home, and back up.
CORNERS = [(0.35, -0.2, 0.45), (0.5, -0.2, 0.45), (0.5, -0.05, 0.45), (0.35, -0.05, 0.45), (0.35, -0.05, 0.6)]


class Arm:
    """The Indy7's planner, limits and tool."""

    def __init__(self) -> None:
        report = validate_package("indy7_v2_description")
        assert report.urdf is not None
        self.joint_names = tuple(joint.name for joint in report.urdf.actuated_joints)
        self.limits = ArmLimits.from_joint_limits(report.limits, self.joint_names)
        self.planner = Planner.for_package(report, self.joint_names, self.limits, CYCLE_S)
        self.home = self.planner.named_states["home"]
        self.tip = self.planner.group().tip_link

    def tool(self, positions: np.ndarray) -> pin.SE3:
        return placement_of(self.planner.fk(positions, [self.tip])[self.tip])


@pytest.fixture(scope="module")
def indy7() -> Arm:
    return Arm()


def run(arm: Arm, plan: Plan) -> np.ndarray:
    """(cycles, 3, dof): what the RT driver commands for the plan, every cycle; it runs as sent, never re-timed."""
    start = np.array(plan.trajectory.points[0].positions)
    rest = np.zeros(len(start))
    timed = fit_to_limits(plan.trajectory, arm.limits, (start, rest, rest), CYCLE_S)
    assert timed.change == "", timed.note()
    times = np.arange(0.0, timed.motion.duration + CYCLE_S, CYCLE_S)
    return np.array([np.stack(timed.motion.state_at(float(t))) for t in times])


def assert_within_joint_limits(arm: Arm, commands: np.ndarray) -> None:
    """Every cycle within the position, velocity, acceleration and (per cycle) jerk limits."""
    limits = arm.limits
    position, velocity, acceleration = commands[:, 0], commands[:, 1], commands[:, 2]
    assert np.all(position >= limits.min_position) and np.all(position <= limits.max_position)
    assert np.all(np.abs(velocity) <= limits.max_velocity), np.abs(velocity).max(axis=0)
    assert np.all(np.abs(acceleration) <= limits.max_acceleration), np.abs(acceleration).max(axis=0)
    jerk = np.abs(np.diff(acceleration, axis=0)) / CYCLE_S
    assert np.all(jerk <= limits.max_jerk * (1 + 1e-6)), jerk.max(axis=0)


def tool_positions(arm: Arm, commands: np.ndarray) -> np.ndarray:
    return np.array([arm.tool(q).translation for q in commands[:, 0]])


def tool_speed(positions: np.ndarray) -> np.ndarray:
    return np.linalg.norm(np.diff(positions, axis=0), axis=1) / CYCLE_S


def moved(arm: Arm, offset: tuple[float, float, float], turn: float = 0.0) -> Pose:
    """The home tool pose moved by `offset` and turned by `turn` rad about the base's z."""
    home = arm.tool(arm.home)
    rotation = pin.utils.rpyToMatrix(0.0, 0.0, turn) @ home.rotation
    x, y, z, w = pin.Quaternion(rotation).coeffs()
    return Pose(tuple(home.translation + np.array(offset)), (x, y, z, w))


def test_a_linear_move_keeps_the_tool_on_the_line_within_every_limit(indy7: Arm) -> None:
    goal = moved(indy7, (0.1, 0.15, -0.15), turn=0.5)
    plan = indy7.planner.sequence(indy7.home, [Linear(goal)])
    assert plan.planner == "LIN"
    commands = run(indy7, plan)
    assert_within_joint_limits(indy7, commands)
    begin, end = indy7.tool(indy7.home), placement_of(goal)
    placements = [indy7.tool(q) for q in commands[:, 0]]
    points = np.array([p.translation for p in placements])
    line = end.translation - begin.translation
    share = np.clip((points - begin.translation) @ line / (line @ line), 0.0, 1.0)
    deviation = np.linalg.norm(points - begin.translation - share[:, None] * line, axis=1)
    assert deviation.max() < 1e-4, deviation.max()  # on the line within 0.1 mm, every cycle
    turned = max(float(np.linalg.norm(pin.log3(pin.SE3.Interpolate(begin, end, s).rotation.T @ p.rotation)))
                 for s, p in zip(share, placements, strict=True))
    assert turned < 1e-3  # the orientation is the slerp's at that share of the way
    np.testing.assert_allclose(points[-1], goal.position, atol=1e-5)
    speed = tool_speed(points)
    assert speed.max() <= ToolLimits().max_trans_vel * 1.01, speed.max()
    assert speed.max() > ToolLimits().max_trans_vel * 0.9  # and it uses that speed


def test_the_tool_speed_limits_can_be_set_per_call_and_are_scaled(indy7: Arm) -> None:
    goal = moved(indy7, (0.0, 0.2, 0.0))
    slow = indy7.planner.sequence(indy7.home, [Linear(goal)], tool_limits=ToolLimits(max_trans_vel=0.1))
    assert tool_speed(tool_positions(indy7, run(indy7, slow))).max() <= 0.1 * 1.01
    scaled = indy7.planner.sequence(indy7.home, [Linear(goal)], options=PlanOptions(velocity_scale=0.2,
                                                                                    acceleration_scale=0.2))
    assert tool_speed(tool_positions(indy7, run(indy7, scaled))).max() <= 0.2 * ToolLimits().max_trans_vel * 1.01


@pytest.mark.parametrize("kind", ["via", "center"])
def test_a_circular_move_keeps_the_tool_on_the_arc(indy7: Arm, kind: str) -> None:
    begin = indy7.tool(indy7.home).translation
    center = begin + np.array([0.0, 0.1, 0.0])
    end = center + np.array([0.1, 0.0, 0.0])  # a quarter turn in the horizontal plane
    via = center + 0.1 * np.array([np.sin(np.pi / 4), -np.cos(np.pi / 4), 0.0])
    radius_vector = begin - center
    item = (Circular(Pose(tuple(end), DOWN), via=tuple(via)) if kind == "via"
            else Circular(Pose(tuple(end), DOWN), center=tuple(center)))
    plan = indy7.planner.sequence(indy7.home, [item])
    assert plan.planner == "CIRC"
    commands = run(indy7, plan)
    assert_within_joint_limits(indy7, commands)
    points = tool_positions(indy7, commands)
    radius = np.linalg.norm(points - center, axis=1)
    assert np.abs(radius - np.linalg.norm(radius_vector)).max() < 1e-4
    normal = np.cross(radius_vector, end - center)
    assert np.abs((points - center) @ normal / np.linalg.norm(normal)).max() < 1e-4  # in the arc's plane
    np.testing.assert_allclose(points[-1], end, atol=1e-5)
    assert np.linalg.norm(points - via, axis=1).min() < 1e-3  # through the via point


def square(blend: float) -> list[Linear]:
    """The CORNERS as straight moves, each corner but the last with `blend`."""
    return [Linear(Pose(corner, DOWN), blend=blend if k < len(CORNERS) - 1 else 0.0)
            for k, corner in enumerate(CORNERS)]


def test_a_blended_sequence_passes_its_corners_without_stopping_and_sooner(indy7: Arm) -> None:
    blended = indy7.planner.sequence(indy7.home, square(0.04))
    stopping = indy7.planner.sequence(indy7.home, square(0.0))
    assert blended.planner == "sequence"
    commands = run(indy7, blended)
    assert_within_joint_limits(indy7, commands)
    points = tool_positions(indy7, commands)
    speed = tool_speed(points)
    assert speed.max() <= ToolLimits().max_trans_vel * 1.01
    # between the first corner's blend and the end of the square, the tool and the joints never stop
    first = CORNERS[0]
    inside = (np.linalg.norm(points[1:] - np.array(first), axis=1) < 0.04).nonzero()[0]
    last = (np.linalg.norm(points[1:] - np.array(CORNERS[-1]), axis=1) > 1e-3).nonzero()[0][-1]
    assert speed[inside[0]:last].min() > 0.02, speed[inside[0]:last].min()
    assert np.linalg.norm(commands[inside[0]:last, 1], axis=1).min() > 0.01
    for corner in CORNERS[:-1]:  # each corner is cut, within its blend radius
        nearest = np.linalg.norm(points - np.array(corner), axis=1).min()
        assert 1e-3 < nearest < 0.04, (corner, nearest)
    stopped = tool_positions(indy7, run(indy7, stopping))
    for corner in CORNERS:  # without blends the tool reaches each corner
        assert np.linalg.norm(stopped - np.array(corner), axis=1).min() < 1e-5
    assert blended.duration_s < 0.85 * stopping.duration_s, (blended.duration_s, stopping.duration_s)


def test_joint_and_cartesian_moves_blend_into_each_other(indy7: Arm) -> None:
    above = moved(indy7, (0.1, 0.1, -0.1))
    items = [Linear(above, blend=0.05), Joint("home", blend=0.05), Linear(moved(indy7, (0.0, 0.0, -0.15)))]
    plan = indy7.planner.sequence(indy7.home, items)
    commands = run(indy7, plan)
    assert_within_joint_limits(indy7, commands)
    velocity = np.linalg.norm(commands[:, 1], axis=1)
    moving = np.flatnonzero(velocity > 1e-6)
    assert velocity[moving[0] + 100:moving[-1] - 100].min() > 1e-3  # one motion, no stop at the corners
    np.testing.assert_allclose(tool_positions(indy7, commands[-1:])[0], moved(indy7, (0.0, 0.0, -0.15)).position,
                               atol=1e-5)


def refusal(arm: Arm, items: list, start: np.ndarray | None = None) -> PlanningError:
    with pytest.raises(PlanningError) as caught:
        arm.planner.sequence(arm.home if start is None else start, items)
    return caught.value


def test_an_unreachable_point_is_refused_naming_the_item_and_its_pose(indy7: Arm) -> None:
    error = refusal(indy7, [Linear(Pose(CORNERS[0], DOWN)), Linear(Pose((1.5, 0.0, 0.5), DOWN))])
    assert error.code == MoveItCode.NO_IK_SOLUTION
    assert "item 1" in error.summary and "workspace" in error.summary
    assert "position (1.500, 0.000, 0.500) m" in error.why and error.how


def test_a_path_through_a_singularity_is_refused_naming_where(indy7: Arm) -> None:
    # the wrist is singular where joint4 is 0: a straight line between two poses on either side passes it
    start = np.array([0.3, -0.2, -1.2, 0.0, -0.3, 0.0])
    beyond = indy7.planner.fk(np.array([0.3, -0.2, -1.2, 0.0, 0.3, 0.0]), [indy7.tip])[indy7.tip]
    error = refusal(indy7, [Linear(beyond)], start)
    assert error.code == MoveItCode.INVALID_MOTION_PLAN
    assert "item 0 passes a singularity" in error.summary
    assert "of the way along item 0, tool pose position (" in error.why


def test_blends_that_do_not_fit_and_a_blend_at_the_end_are_refused(indy7: Arm) -> None:
    short = [Linear(Pose(CORNERS[0], DOWN), blend=0.1), Linear(Pose(CORNERS[1], DOWN), blend=0.1),
             Linear(Pose(CORNERS[2], DOWN))]
    assert "overlap" in refusal(indy7, short).summary
    assert "last item has a blend radius" in refusal(indy7, [Linear(Pose(CORNERS[0], DOWN), blend=0.01)]).summary
    back = [Linear(Pose(CORNERS[0], DOWN), blend=0.02), Linear(Pose(CORNERS[1], DOWN), blend=0.02),
            Linear(Pose(CORNERS[0], DOWN))]
    turned = refusal(indy7, back)
    assert "item 1 turns back on itself" in turned.summary and turned.how == "set blend=0 on item 1"
    collinear = Circular(Pose(CORNERS[1], DOWN), via=((CORNERS[0][0] + CORNERS[1][0]) / 2, CORNERS[0][1], 0.45))
    assert "spans no arc" in refusal(indy7, [Linear(Pose(CORNERS[0], DOWN)), collinear]).summary


def test_an_obstacle_on_the_path_is_refused_naming_the_item(indy7: Arm) -> None:
    indy7.planner.scene.add(SceneObject("post", Box((0.04, 0.04, 0.4)), Pose((0.5, -0.125, 0.45))))
    try:
        error = refusal(indy7, square(0.0))
    finally:
        indy7.planner.scene.remove("post")
    assert "item 1" in error.summary and "collision" in error.summary and "post" in error.why


def test_the_in_process_robot_moves_the_tool_along_a_line() -> None:
    with simulated_robot() as robot:
        robot.set_mode("hold")
        assert robot.move_to("home").wait(30).succeeded
        tool = robot.compute_fk(links=["tcp"])["tcp"]
        goal = Pose((tool.position[0] + 0.1, tool.position[1], tool.position[2] - 0.1), tool.orientation)
        samples = []
        handle = robot.move_linear(goal)
        while not handle.done:
            samples.append(robot.live_state().command_position)
            time.sleep(0.005)
        assert handle.wait(30).succeeded
        points = np.array([robot.compute_fk(q, ["tcp"])["tcp"].position for q in samples[::10]])
        line = np.array(goal.position) - np.array(tool.position)
        share = np.clip((points - tool.position) @ line / (line @ line), 0.0, 1.0)
        assert np.linalg.norm(points - tool.position - share[:, None] * line, axis=1).max() < 1e-4
        np.testing.assert_allclose(robot.compute_fk(links=["tcp"])["tcp"].position, goal.position, atol=1e-3)


def test_a_cartesian_path_that_turns_the_tool_keeps_it_on_the_line(indy7: Arm) -> None:
    """compute_cartesian_path's steps lie on the straight line even when the orientation turns (they once followed
    pinocchio's SE3 interpolation, a screw 11 mm off the line for this half-radian turn)."""
    goal = moved(indy7, (0.1, 0.15, -0.15), turn=0.5)
    plan = indy7.planner.cartesian(indy7.home, [goal], max_step=0.005)
    assert plan.fraction == 1.0
    begin = indy7.tool(indy7.home).translation
    points = np.array([indy7.tool(np.array(point.positions)).translation for point in plan.trajectory.points])
    line = np.array(goal.position) - begin
    share = np.clip((points - begin) @ line / (line @ line), 0.0, 1.0)
    assert np.linalg.norm(points - begin - share[:, None] * line, axis=1).max() < 1e-4


def test_a_sequence_to_where_the_arm_is_is_a_plan_that_stays(indy7: Arm) -> None:
    """As a plan to the start state: at rest, for the shortest step a plan has (it once failed on an empty path)."""
    for items in ([Joint("home")], [Linear(moved(indy7, (0.0, 0.0, 0.0)))]):
        plan = indy7.planner.sequence(indy7.home, items)
        assert plan.duration_s < 0.01
        assert all(point.positions == pytest.approx(tuple(indy7.home)) for point in plan.trajectory.points)


def test_a_long_sequence_is_bounded_by_its_planning_time(indy7: Arm) -> None:
    """Joint moves are cheap per step but many of them are not: the planning time bounds them too."""
    swings = [Joint([0.0, 0.0, -1.5, 0.0, -1.5, 0.0]), Joint([2.5, 0.0, -1.5, 0.0, -1.5, 0.0])] * 200
    began = time.perf_counter()
    with pytest.raises(PlanningError) as caught:
        indy7.planner.sequence(indy7.home, swings, options=PlanOptions(timeout_s=0.2))
    assert caught.value.code == MoveItCode.TIMED_OUT
    assert time.perf_counter() - began < 2.0
