"""Arms in the shapes real description packages have: continuous joints (run unwrapped, planned, drawn), a range
that excludes 0 (the simulated arm starts inside it), and an arm outside a range (never trapped there)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from plem.control.events import EventKind
from plem.control.kinematics import ArmDynamics
from plem.control.trajectory import JointTrajectory, TrajectoryOutcome
from plem.description.validate import validate_package
from plem.errors import CommandRejected, ConfigError, MultipleErrors
from plem.fieldbus.ethercat.virtual.emulator import ClockedDrives
from plem.fieldbus.mock import MockBus
from plem.launch.ethercat_sim import arm_of_plan
from plem.launch.plan import plan_robot
from plem.robot import Robot
from plem.robot.resolution import LAUNCH_DEFAULTS, resolve_arm_config
from plem.view.model import ViewModel

from .arm_shapes import FR3_JOINT4, JOINTS, continuous_wrist, generated, narrowed, zero_outside_joint4

TIMEOUT_S = 60


def built(root: Path, bus: MockBus | None = None) -> Robot:
    """The package's arm on the simulated arm, built as `plem launch bus:=mock` builds it; stepped in simulated time
    (waiting on a motion runs its cycles)."""
    config = resolve_arm_config(launch_args={}, launch_defaults=LAUNCH_DEFAULTS, dof=6).config
    return Robot.builder(config).with_bus(bus or MockBus(6)).with_description(str(root)).build()


def faults(robot: Robot) -> list[str]:
    return [event.message for event in robot.events.recent({EventKind.FAULT})]


def moved(robot: Robot, target: list[float]) -> None:
    result = robot.move_joints(target).wait(TIMEOUT_S)
    assert result.outcome is TrajectoryOutcome.SUCCEEDED, result
    assert np.allclose(robot.state().position, target, atol=1e-3), robot.state().position


@pytest.fixture(scope="module")
def spin(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return continuous_wrist(tmp_path_factory.mktemp("spin"))


@pytest.fixture(scope="module")
def spinning(spin: Path) -> Iterator[Robot]:
    robot = built(spin)
    robot.set_mode("hold")
    yield robot
    robot.shutdown()


# -- continuous joints --------------------------------------------------------------------------------------------

def test_a_continuous_joint_has_no_position_limits_and_keeps_its_others(spin: Path, spinning: Robot):
    limits = spinning.limits
    assert (limits.min_position[5], limits.max_position[5]) == (-np.inf, np.inf)
    assert limits.max_velocity[5] == 3.0 and limits.max_effort[5] == 30.0
    assert (spinning.bus.effort_limits[5]) == 30.0


def test_a_continuous_joint_turns_past_half_a_turn_unwrapped(spinning: Robot):
    moved(spinning, [0.2, 0.3, 0.4, 0.1, 0.2, 4.0])
    assert spinning.bus.true_positions[5] == pytest.approx(4.0, abs=1e-3)     # not 4 - 2π
    moved(spinning, [0.2, 0.3, 0.4, 0.1, 0.2, -4.5])
    moved(spinning, [0.2, 0.3, 0.4, 0.1, 0.2, 7.0])
    assert not faults(spinning)


def test_a_continuous_joint_plans_with_ik_and_ompl(spinning: Robot):
    moved(spinning, [0.2, 0.3, 0.4, 0.1, 0.2, 7.0])
    pose = spinning.compute_fk([0.3, 0.5, 0.6, 0.1, 0.4, 0.5])["tool0"]
    solution = spinning.compute_ik(pose)
    assert solution[5] == pytest.approx(0.5 + 2 * np.pi, abs=1e-3)     # the turn nearest the arm's 7 rad
    plan = spinning.plan(pose)
    assert plan.planner == "RRTConnect" and plan.trajectory.points[-1].positions[5] == pytest.approx(solution[5],
                                                                                                     abs=1e-3)
    far = spinning.plan([0.2, 0.3, 0.4, 0.1, 0.2, 7.0 + 9.0])           # more than a turn away
    assert far.trajectory.points[-1].positions[5] == pytest.approx(16.0)
    result = spinning.move_to(pose).wait(TIMEOUT_S)
    assert result.outcome is TrajectoryOutcome.SUCCEEDED and not faults(spinning)


def test_the_view_draws_a_continuous_joint_where_pinocchio_puts_it(spin: Path):
    report = validate_package(spin)
    assert report.urdf_xml is not None
    view, arm = ViewModel(report.urdf_xml, JOINTS), ArmDynamics(report.urdf_xml, JOINTS)
    positions = np.array([0.3, 0.5, 0.6, 0.1, 0.4, 7.5])
    drawn = view.load()
    drawn.update_cfg(view.configuration(positions))
    expected = arm.frame_placement(positions, arm.model.getFrameId("tool0")).homogeneous
    assert np.allclose(drawn.get_transform("tool0", "base_link"), expected, atol=1e-9)


# -- a range that excludes 0 --------------------------------------------------------------------------------------

@pytest.mark.parametrize(("home", "start"), [(-1.5, -1.5), (None, sum(FR3_JOINT4) / 2)])
def test_the_simulated_arm_starts_inside_a_range_excluding_zero_and_moves(tmp_path: Path, home: float | None,
                                                                          start: float):
    """At the SRDF's home when it is inside every range, else at the middle of each range: never on a limit."""
    robot = built(zero_outside_joint4(tmp_path, home=home))
    try:
        expected = [0.0, 0.5, 1.0, start, 1.0, 0.0] if home is not None else [0.0, 0.0, 0.0, start, 0.0, 0.0]
        assert np.allclose(robot.bus.true_positions, expected, atol=1e-6)
        robot.set_mode("hold")
        moved(robot, [0.1, 0.2, 0.3, -1.0, 0.2, 0.1])
        assert not faults(robot)
    finally:
        robot.shutdown()


def test_the_simulated_arm_starts_inside_the_limits_joint_limits_yaml_narrows(tmp_path: Path):
    """Zero is inside the URDF's range of joint2 but not inside joint_limits.yaml's [0.3, 1.5]: the arm starts at
    the SRDF's home, inside both."""
    root, _, _ = generated(tmp_path, "low")
    robot = built(narrowed(root, "joint2", 0.3, 1.5))
    try:
        assert np.allclose(robot.bus.true_positions, [0.0, 0.5, 1.0, 0.0, 1.0, 0.0], atol=1e-6)
        robot.set_mode("hold")
        robot.step(200)
        assert not faults(robot)
    finally:
        robot.shutdown()


# -- an arm outside a range ---------------------------------------------------------------------------------------

def test_an_arm_outside_a_range_holds_and_is_brought_back_never_farther_out(tmp_path: Path):
    """joint2 sits at 0.1 rad, below its range [0.3, 1.5]: holding is no fault, a motion farther out is refused with
    how to come back, a motion back into the range runs, in Python's checks and in the core alike."""
    root, _, _ = generated(tmp_path, "low")
    start = [0.0, 0.1, 0.0, 0.0, 0.0, 0.0]
    robot = built(narrowed(root, "joint2", 0.3, 1.5), MockBus(6, initial_positions=start))
    try:
        assert robot.set_mode("hold").name == "HOLD"
        robot.step(500)
        assert not faults(robot) and robot.mode.name == "HOLD"
        with pytest.raises(CommandRejected) as refused:
            robot.move_joints([0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
        assert "takes joint2 farther outside its position limits" in refused.value.summary
        assert "brings joint2 back into [0.3, 1.5] rad" in refused.value.how
        moved(robot, [0.0, 0.2, 0.0, 0.0, 0.0, 0.0])              # closer, still outside
        back = JointTrajectory.from_lists(JOINTS, [
            {"positions": [0.0, 0.2, 0.0, 0.0, 0.0, 0.0], "time_from_start": 0.5},
            {"positions": [0.0, 0.6, 0.1, 0.0, 0.0, 0.0], "time_from_start": 2.0}])
        result = robot.execute_trajectory(back).wait(TIMEOUT_S)
        assert result.outcome is TrajectoryOutcome.SUCCEEDED, result
        assert robot.state().position[1] == pytest.approx(0.6, abs=1e-3) and not faults(robot)
        with pytest.raises(CommandRejected, match="outside the position limits of joint2"):
            robot.move_joints([0.0, 0.2, 0.0, 0.0, 0.0, 0.0])    # inside now: the range is the range again
    finally:
        robot.shutdown()


# -- initial_positions:= ------------------------------------------------------------------------------------------

def test_initial_positions_are_taken_on_the_simulated_arm(tmp_path: Path):
    root = zero_outside_joint4(tmp_path)
    plan = plan_robot({"bus": "mock", "description_package": str(root),
                       "initial_positions": "0, 0.5,-0.25,-1.2, 0.0,+1"}, generate=False)
    assert plan.initial_positions == (0.0, 0.5, -0.25, -1.2, 0.0, 1.0)
    assert plan_robot({"bus": "mock", "description_package": str(root)}, generate=False).initial_positions is None


def test_the_virtual_networks_arm_starts_at_initial_positions_inside_the_enforced_limits(tmp_path: Path):
    """bus:=ethercat_sim's emulated drives start where initial_positions:= says, else inside joint_limits.yaml."""
    root = zero_outside_joint4(tmp_path)
    given = plan_robot({"bus": "ethercat_sim", "description_package": str(root),
                        "initial_positions": "0,0.5,0,-1.2,0,1"}, generate=False)
    drives = ClockedDrives(arm_of_plan(given, start=given.initial_positions))
    np.testing.assert_allclose(drives.arm.true_positions, [0.0, 0.5, 0.0, -1.2, 0.0, 1.0], atol=1e-9)
    own = plan_robot({"bus": "ethercat_sim", "description_package": str(root)}, generate=False)
    limits = own.limits()
    start = ClockedDrives(arm_of_plan(own)).arm.true_positions
    assert np.all((limits.min_position <= start) & (start <= limits.max_position)), start


@pytest.mark.parametrize(("bus", "text", "words"), [
    ("mock", "0,0,0,-1,0", "5 numbers for 6 joints"),
    ("mock", "0,0,0,-1,0,1e3", "not a list of plain numbers"),
    ("mock", "0,0,0,0,0,0", f"joint4 = 0 is outside [{FR3_JOINT4[0]:g}, {FR3_JOINT4[1]:g}]"),
    ("ethercat", "0,0,0,-1,0,0", "bus:=ethercat drives a real arm, which starts where it is"),
])
def test_initial_positions_are_checked_against_the_joints_and_their_ranges(tmp_path: Path, bus: str, text: str,
                                                                           words: str):
    root = zero_outside_joint4(tmp_path)
    with pytest.raises((ConfigError, MultipleErrors)) as refused:
        plan_robot({"bus": bus, "description_package": str(root), "initial_positions": text}, generate=False)
    rendered = refused.value.render()
    assert f"initial_positions:={text}" in rendered and words in rendered, rendered
    assert "HOW: " in rendered and ("initial_positions" in rendered.split("HOW: ")[-1])


def test_the_planner_brings_an_arm_outside_a_range_back(tmp_path: Path):
    """`plem move --to home` plans: from a start outside a range the plan first moves straight back into it."""
    root, _, _ = generated(tmp_path, "low")
    robot = built(narrowed(root, "joint2", 0.3, 1.5), MockBus(6, initial_positions=[0.0, 0.1, 0.0, 0.0, 0.0, 0.0]))
    try:
        robot.set_mode("hold")
        plan = robot.plan("home")
        joint2 = np.array([point.positions[1] for point in plan.trajectory.points])
        assert joint2[0] == pytest.approx(0.1, abs=1e-4) and joint2[-1] == pytest.approx(0.5)
        assert np.all(joint2 >= joint2[0] - 1e-9)                       # never farther out than where it was
        result = robot.move_to("home").wait(TIMEOUT_S)
        assert result.outcome is TrajectoryOutcome.SUCCEEDED, result
        assert robot.state().position[1] == pytest.approx(0.5, abs=1e-3) and not faults(robot)
    finally:
        robot.shutdown()


def test_initial_positions_beyond_the_urdfs_range_are_refused_before_the_arm_jumps_there(tmp_path: Path):
    """No arm can be beyond its hard stops: the simulated arm refuses to start there (it used to be stopped at the
    limit in its first cycle, an encoder jump and a fault)."""
    bus = MockBus(6, initial_positions=[0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    with pytest.raises(ConfigError) as refused:
        built(zero_outside_joint4(tmp_path), bus)
    assert "joint4 = 0 is outside [-3.04, -0.15]" in refused.value.why and "initial_positions" in refused.value.how
