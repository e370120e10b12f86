"""The planner on real arms: plans around obstacles that a dense, independent re-check finds clean, and the
WHAT/WHY/HOW of every way a request can fail.

Arms: the built-in 6- and 7-axis Indys (primitives), a scaffolded 7-axis arm, UR5 and Panda from
example-robot-data (meshes). The re-check samples the trajectory as the RT driver runs it (read back through
plem's own trajectory path, every cycle) against a collision checker of its own.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from plem.control.limits import ArmLimits
from plem.control.trajectory import JointTrajectory, TrajectoryPoint
from plem.description.scaffold import create_package
from plem.description.validate import ValidationReport, validate_package
from plem.errors import MoveItCode, PlanningError
from plem.planning.collision import CollisionChecker
from plem.planning.goals import JointGoal, NamedGoal, Plan, PlanOptions, PoseGoal
from plem.planning.planner import Planner, placement_of
from plem.planning.poses import Pose
from plem.planning.retiming import fit_to_limits
from plem.planning.scene import Box, PlanningScene, SceneObject
from tests.integration.robot_fixtures import simulated_robot
from tests.third_party import ARMS, wrap

CYCLE_S = 0.001
#: Franka's ready pose: the wrapped Panda's home (every joint at 0, within limits) folds it into itself.
PANDA_READY = (0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785)


class Arm:
    """A planner of a validated package and what the checks need."""

    def __init__(self, report: ValidationReport) -> None:
        assert report.urdf is not None
        self.report = report
        self.joint_names = tuple(joint.name for joint in report.urdf.actuated_joints)
        self.limits = ArmLimits.from_joint_limits(report.limits, self.joint_names)
        self.planner = Planner.for_package(report, self.joint_names, self.limits, CYCLE_S)
        self.home = np.array(PANDA_READY) if report.files.name == "panda_description" else \
            self.planner.named_states["home"]

    def tool(self, positions: np.ndarray) -> Pose:
        group = self.planner.group()
        return self.planner.fk(positions, [group.tip_link])[group.tip_link]


def _package(request: pytest.FixtureRequest, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> str:
    name = request.param
    if name in ("ur5", "panda"):
        return wrap(next(spec for spec in ARMS if spec.name == name), tmp_path, monkeypatch).spec.package
    if name == "scaffolded":
        create_package(tmp_path / "packages", "scaffolded_arm", 7, with_moveit=True)
        monkeypatch.setenv("PLEM_PACKAGE_PATH", str(tmp_path / "packages"))
        return "scaffolded_arm_description"
    return name


@pytest.fixture(params=["indy7_v2_description", "indyrp2_v2_description", "scaffolded", "ur5", "panda"])
def arm(request: pytest.FixtureRequest, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Arm:
    return Arm(validate_package(_package(request, tmp_path, monkeypatch)))


@pytest.fixture(scope="module")
def indy7() -> Arm:
    return Arm(validate_package("indy7_v2_description"))


def run_as_driver(arm: Arm, plan: Plan, start: np.ndarray) -> np.ndarray:
    """The positions the RT driver commands, cycle by cycle, for the plan read back as sent (and not re-timed)."""
    timed = fit_to_limits(plan.trajectory, arm.limits, (start, np.zeros(len(start)), np.zeros(len(start))), CYCLE_S)
    assert timed.change == "", timed.note()
    times = np.arange(0.0, timed.motion.duration + CYCLE_S, CYCLE_S)
    return np.array([timed.motion.state_at(float(t))[0] for t in times])


def assert_clean(arm: Arm, plan: Plan, start: np.ndarray, goal: np.ndarray | None, scene: PlanningScene) -> None:
    """Every cycle of the plan free of collisions (by a checker of the test's own) and within the position limits;
    it starts at `start` and ends at `goal`."""
    checker = CollisionChecker(arm.planner.arm.model, arm.report.urdf_xml or "",
                               [(a, b) for a, b, _ in arm.report.srdf.disabled_collisions] if arm.report.srdf else [])
    checker.set_scene(scene)
    positions = run_as_driver(arm, plan, start)
    np.testing.assert_allclose(positions[0], start, atol=1e-9)
    if goal is not None:
        np.testing.assert_allclose(positions[-1], goal, atol=1e-6)
    assert np.all(positions >= arm.limits.min_position - 1e-9) and np.all(positions <= arm.limits.max_position + 1e-9)
    hits = [k for k, q in enumerate(positions) if not checker.is_free(arm.planner.arm.to_model_order(q))]
    assert not hits, f"{len(hits)} of {len(positions)} cycles collide, first at {hits[0] * CYCLE_S:.3f} s"


def obstacle_between(arm: Arm, start: np.ndarray, goal: np.ndarray) -> SceneObject:
    """A box where the tool passes halfway along the straight joint-space line from start to goal."""
    middle = arm.tool((start + goal) / 2).position
    return SceneObject("obstacle", Box((0.12, 0.12, 0.12)), Pose(middle))


def test_plans_go_around_an_obstacle_the_straight_line_hits(arm: Arm) -> None:
    start = arm.home
    goal = start.copy()
    goal[0] = np.clip(start[0] + 1.4, arm.limits.min_position[0], arm.limits.max_position[0])
    box = obstacle_between(arm, start, goal)
    arm.planner.scene.add(box)
    line = [start + (goal - start) * s for s in np.linspace(0, 1, 200)]
    assert any(arm.planner.contacts(q) for q in line), "the obstacle must block the straight line"
    assert not arm.planner.contacts(start) and not arm.planner.contacts(goal)

    plan = arm.planner.plan(start, JointGoal(dict(zip(arm.joint_names, goal, strict=True))))
    assert plan.planner == "RRTConnect" and plan.path_states >= 3
    assert_clean(arm, plan, start, goal, arm.planner.scene)

    target = arm.tool(goal)
    by_pose = arm.planner.plan(start, PoseGoal(target))
    assert_clean(arm, by_pose, start, None, arm.planner.scene)
    reached = arm.tool(np.array(by_pose.trajectory.points[-1].positions))
    np.testing.assert_allclose(reached.position, target.position, atol=1e-4)


def test_ik_round_trips_fk(indy7: Arm) -> None:
    rng = np.random.default_rng(7)
    for _ in range(20):
        q = rng.uniform(indy7.limits.min_position, indy7.limits.max_position)
        target = indy7.tool(q)
        solution = indy7.planner.ik(target, indy7.home, avoid_collisions=False)
        assert np.all(solution >= indy7.limits.min_position) and np.all(solution <= indy7.limits.max_position)
        found = indy7.tool(solution)
        np.testing.assert_allclose(found.position, target.position, atol=1e-5)
        assert abs(abs(np.dot(found.orientation, target.orientation)) - 1.0) < 1e-8


def test_a_plan_read_back_from_ros_messages_still_runs_as_sent(indy7: Arm) -> None:
    """Times in a ROS message are whole nanoseconds; plans keep enough margin to run as sent after rounding."""
    plan = indy7.planner.plan(np.zeros(6), NamedGoal("home"))
    rounded = JointTrajectory(plan.trajectory.joint_names, tuple(
        TrajectoryPoint(p.positions, round(p.time_from_start * 1e9) / 1e9, p.velocities, p.accelerations)
        for p in plan.trajectory.points))
    assert fit_to_limits(rounded, indy7.limits, (np.zeros(6), np.zeros(6), np.zeros(6)), CYCLE_S).change == ""


def test_cartesian_path_stops_where_an_obstacle_blocks_it(indy7: Arm) -> None:
    planner = indy7.planner
    tool = indy7.tool(indy7.home)
    down = Pose((tool.position[0], tool.position[1], tool.position[2] - 0.3), tool.orientation)
    free = planner.cartesian(indy7.home, [down])
    assert free.fraction == 1.0
    end = indy7.tool(np.array(free.trajectory.points[-1].positions))
    np.testing.assert_allclose(end.position, down.position, atol=1e-4)
    planner.scene.add(SceneObject("shelf", Box((0.3, 0.3, 0.02)),
                                  Pose((tool.position[0], tool.position[1], tool.position[2] - 0.2))))
    try:
        blocked = planner.cartesian(indy7.home, [down])
        assert 0.2 < blocked.fraction < 0.7
        assert_clean(indy7, blocked, indy7.home, None, planner.scene)
    finally:
        planner.scene.remove("shelf")


def failure(call: object) -> PlanningError:
    with pytest.raises(PlanningError) as caught:
        call()  # type: ignore[operator]
    error = caught.value
    assert error.what and error.why and error.how and "Traceback" not in error.render()
    return error


def test_every_failure_says_what_why_and_how(indy7: Arm) -> None:
    planner, home = indy7.planner, indy7.home
    planner.scene.add(SceneObject("pillar", Box((0.1, 0.1, 0.1)), indy7.tool(home)))
    try:
        error = failure(lambda: planner.plan(home, NamedGoal("zero")))
        assert error.code == MoveItCode.START_STATE_IN_COLLISION and "pillar" in error.why
        error = failure(lambda: planner.plan(np.zeros(6), NamedGoal("home")))
        assert error.code == MoveItCode.GOAL_IN_COLLISION and "pillar" in error.why
        error = failure(lambda: planner.ik(indy7.tool(home), np.zeros(6)))
        assert error.code == MoveItCode.NO_IK_SOLUTION and "collision" in error.why and "pillar" in error.why
    finally:
        planner.scene.remove("pillar")
    beyond = home.copy()
    beyond[1] = indy7.limits.max_position[1] + 0.1
    error = failure(lambda: planner.plan(home, JointGoal(dict(zip(indy7.joint_names, beyond, strict=True)))))
    assert error.code == MoveItCode.INVALID_GOAL_CONSTRAINTS and "joint1" in error.why
    error = failure(lambda: planner.plan(home, NamedGoal("nowhere")))
    assert "home" in error.what and "zero" in error.what
    error = failure(lambda: planner.plan(home, JointGoal({"elbow": 1.0})))
    assert "elbow" in error.why
    error = failure(lambda: planner.plan(home, NamedGoal("home"), PlanOptions(group="legs")))
    assert error.code == MoveItCode.INVALID_GROUP_NAME and "arm" in error.what
    error = failure(lambda: planner.plan(home, PoseGoal(Pose((0.3, 0, 0.5)), frame="flange")))
    assert error.code == MoveItCode.INVALID_LINK_NAME and "tcp" in error.what
    error = failure(lambda: planner.ik(Pose((5.0, 0.0, 0.0)), home))
    assert error.code == MoveItCode.NO_IK_SOLUTION and "seeds tried" in error.why and "closest came within" in error.why
    error = failure(lambda: Pose((float("nan"), 0.0, 0.0)))
    assert error.code == MoveItCode.INVALID_GOAL_CONSTRAINTS
    error = failure(lambda: planner.plan(home, NamedGoal("home"), PlanOptions(planner_id="Dijkstra")))
    assert "RRTConnect" in error.what


def test_a_plan_that_needs_more_time_than_allowed_times_out(indy7: Arm) -> None:
    """Going around an obstacle takes hundreds of collision checks: far more than 0.1 ms allows."""
    planner, home = indy7.planner, indy7.home
    goal = home.copy()
    goal[0] += 1.4
    planner.scene.add(obstacle_between(indy7, home, goal))
    try:
        error = failure(lambda: planner.plan(home, JointGoal(dict(zip(indy7.joint_names, goal, strict=True))),
                                             PlanOptions(timeout_s=1e-4)))
        assert error.code == MoveItCode.TIMED_OUT and "allowed_planning_time" in error.how
    finally:
        planner.scene.remove("obstacle")


def test_pose_goals_are_in_the_frame_given(indy7: Arm) -> None:
    planner, home = indy7.planner, indy7.home
    in_link0 = planner.fk(home, ["tcp"], frame="link0")["tcp"]
    in_link3 = planner.fk(home, ["tcp"], frame="link3")["tcp"]
    q = planner.ik(in_link3, home, frame="link3", avoid_collisions=False)
    np.testing.assert_allclose(indy7.tool(q).position, in_link0.position, atol=1e-5)
    np.testing.assert_allclose(placement_of(in_link0).translation, in_link0.position)


def test_the_in_process_robot_plans_with_the_same_calls() -> None:
    """`Robot` answers plan/move_to/compute_ik/compute_fk/scene calls with a planner of its own process."""
    with simulated_robot() as robot:
        robot.set_mode("hold")
        plan = robot.plan("home")
        assert plan.planner == "RRTConnect" and plan.trajectory.points
        assert robot.execute_trajectory(plan.trajectory).wait(30).succeeded
        np.testing.assert_allclose(robot.live_state().position, plan.trajectory.points[-1].positions, atol=1e-3)
        tool = robot.compute_fk(links=["tcp"])["tcp"]
        lower = Pose((tool.position[0], tool.position[1], tool.position[2] - 0.1), tool.orientation)
        robot.add_objects(SceneObject("shelf", Box((0.3, 0.3, 0.02)), Pose((tool.position[0], tool.position[1],
                                                                             tool.position[2] - 0.3))))
        assert [item.name for item in robot.planning_scene().objects()] == ["shelf"]
        assert robot.move_to(lower).wait(30).succeeded
        np.testing.assert_allclose(robot.compute_fk(links=["tcp"])["tcp"].position, lower.position, atol=1e-3)
        with pytest.raises(PlanningError) as caught:
            robot.plan(Pose((tool.position[0], tool.position[1], tool.position[2] - 0.3), tool.orientation))
        assert caught.value.code == MoveItCode.NO_IK_SOLUTION and "shelf" in caught.value.why
