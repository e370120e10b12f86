"""Inverse kinematics on real arms: the built-in Indys (6 and 7 joints) and the UR5 of example-robot-data."""

from __future__ import annotations

import importlib.metadata
import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from plem.control.kinematics import JointSpace
from plem.control.limits import ArmLimits
from plem.description.validate import validate_package
from plem.errors import MoveItCode, PlanningError
from plem.planning.inverse_kinematics import IkInputError, IkSolver

INDY7 = "indy7_v2_description"
INDYRP2 = "indyrp2_v2_description"
TOLERANCE = 1e-5
#: Generous: the tests check what is found, not how fast, and a loaded machine must not fail them.
TIMEOUT_S = 0.5


class Arm:
    """A model, its limits in pinocchio's joint order, an IK solver to its tool frame, and forward kinematics."""

    def __init__(self, model: pin.Model, tip: str, lower: np.ndarray, upper: np.ndarray,
                 joints: range | None = None) -> None:
        self.model, self.tip, self.lower, self.upper = model, tip, lower, upper
        self.data = model.createData()
        self.space = JointSpace(model)
        self.solver = IkSolver(model, joints or range(model.nv), tip, lower, upper)

    def pose(self, q: np.ndarray) -> pin.SE3:
        pin.framesForwardKinematics(self.model, self.data, self.space.configuration(q))
        return self.data.oMf[self.model.getFrameId(self.tip)].copy()

    def random(self, rng: np.random.Generator) -> np.ndarray:
        return rng.uniform(self.lower, self.upper)


def builtin(package: str) -> Arm:
    report = validate_package(package)
    assert report.urdf_xml is not None
    model = pin.buildModelFromXML(report.urdf_xml)
    limits = ArmLimits.from_joint_limits(report.limits, [model.names[j] for j in range(1, model.njoints)])
    return Arm(model, "tcp", limits.min_position, limits.max_position)


@pytest.fixture(scope="module")
def indy7() -> Arm:
    return builtin(INDY7)


@pytest.fixture(scope="module")
def indyrp2() -> Arm:
    return builtin(INDYRP2)


@pytest.fixture(scope="module")
def ur5() -> Arm:
    prefix = Path(importlib.metadata.distribution("example-robot-data").locate_file("cmeel.prefix"))
    model = pin.buildModelFromUrdf(str(prefix / "share/example-robot-data/robots/ur_description/urdf/ur5_robot.urdf"))
    return Arm(model, "tool0", model.lowerPositionLimit.copy(), model.upperPositionLimit.copy())


def errors(arm: Arm, q: np.ndarray, target: pin.SE3) -> tuple[float, float]:
    offset = arm.pose(q).actInv(target)
    return float(np.linalg.norm(offset.translation)), float(np.linalg.norm(pin.log3(offset.rotation)))


def within_limits(arm: Arm, q: np.ndarray) -> bool:
    return bool(np.all(q >= arm.lower) and np.all(q <= arm.upper))


@pytest.mark.parametrize("package", [INDY7, INDYRP2])
def test_ik_round_trips_forward_kinematics_on_6_and_7_joint_arms(package: str):
    arm = builtin(package)
    rng = np.random.default_rng(1)
    for _ in range(25):
        target = arm.pose(arm.random(rng))
        seed = (arm.lower + arm.upper) / 2
        result = arm.solver.solve(target, seed, timeout_s=TIMEOUT_S, rng=rng)
        assert result.success and result.attempts >= 1
        position_error, orientation_error = errors(arm, result.positions, target)
        assert position_error <= TOLERANCE and orientation_error <= TOLERANCE
        assert result.position_error == pytest.approx(position_error, abs=1e-9)
        assert result.orientation_error == pytest.approx(orientation_error, abs=1e-9)
        assert within_limits(arm, result.positions)


def test_position_only_reaches_the_point_whatever_the_orientation(indyrp2: Arm):
    rng = np.random.default_rng(2)
    for _ in range(10):
        reached = indyrp2.pose(indyrp2.random(rng))
        target = pin.SE3(pin.exp3(rng.normal(size=3)), reached.translation)  # an orientation the arm may not reach
        result = indyrp2.solver.solve(target, np.zeros(7), position_only=True, timeout_s=TIMEOUT_S, rng=rng)
        assert result.success and result.orientation_error == 0.0
        assert errors(indyrp2, result.positions, target)[0] <= TOLERANCE


def test_a_seed_that_solves_the_target_is_returned_as_it_is(indy7: Arm):
    q = np.array([0.3, -0.5, 1.2, 0.1, 0.8, -2.0])
    result = indy7.solver.solve(indy7.pose(q), q, timeout_s=TIMEOUT_S)
    assert result.success and result.attempts == 1
    np.testing.assert_array_equal(result.positions, q)


def test_the_solution_nearest_the_seed_is_found_not_another_branch(indy7: Arm):
    rng = np.random.default_rng(3)
    for _ in range(10):
        q = indy7.random(rng) * 0.9
        seed = q + rng.uniform(-0.05, 0.05, 6)
        result = indy7.solver.solve(indy7.pose(q), seed, timeout_s=TIMEOUT_S, rng=rng)
        assert result.success and result.attempts == 1
        np.testing.assert_allclose(result.positions, q, atol=1e-2)  # other branches are tenths of a radian away


def test_joints_of_more_than_a_turn_end_on_the_angle_nearest_the_seed(ur5: Arm):
    rng = np.random.default_rng(4)
    calls = []

    def third_time(q: np.ndarray) -> bool:  # refuses solutions twice, so random seeds provide the third
        calls.append(q.copy())
        return len(calls) >= 3

    seed = np.array([5.0, -1.0, 1.0, -4.0, 5.5, -5.5])
    target = ur5.pose(np.array([-1.0, -1.2, 1.5, 2.0, -0.9, 0.7]))
    result = ur5.solver.solve(target, seed, accept=third_time, timeout_s=TIMEOUT_S, rng=rng)
    assert result.success and result.attempts >= 3 and len(calls) == 3
    assert errors(ur5, result.positions, target)[0] <= TOLERANCE
    turnable = [0, 1, 3, 4, 5]  # ±2π; the elbow's range is ±π
    assert np.all(np.abs(result.positions[turnable] - seed[turnable]) <= math.pi + 1e-9)
    assert within_limits(ur5, result.positions)


def test_a_refused_solution_makes_the_search_go_on_to_another(indy7: Arm):
    rng = np.random.default_rng(5)
    q = np.array([0.2, 0.4, 1.0, 0.3, -0.9, 0.5])
    refused = q

    def not_that_one(candidate: np.ndarray) -> bool:
        return bool(np.abs(candidate - refused).max() > 1e-3)

    result = indy7.solver.solve(indy7.pose(q), q, accept=not_that_one, timeout_s=TIMEOUT_S, rng=rng)
    assert result.success and result.attempts >= 2
    assert np.abs(result.positions - q).max() > 1e-3
    assert errors(indy7, result.positions, indy7.pose(q))[0] <= TOLERANCE


def test_a_seed_outside_the_limits_is_clipped_and_the_result_stays_inside(indy7: Arm):
    rng = np.random.default_rng(6)
    target = indy7.pose(indy7.random(rng))
    result = indy7.solver.solve(target, np.full(6, 10.0), timeout_s=TIMEOUT_S, rng=rng)
    assert result.success and within_limits(indy7, result.positions)


def test_an_unreachable_target_fails_with_the_best_residual(indy7: Arm):
    rng = np.random.default_rng(7)
    target = pin.SE3(np.eye(3), np.array([10.0, 0.0, 0.5]))
    result = indy7.solver.solve(target, np.zeros(6), timeout_s=0.05, rng=rng)
    assert not result.success and result.attempts > 1
    reach = 1.5  # the Indy7 reaches about 0.8 m from its base
    assert 10.0 - reach < result.position_error < 10.0
    assert errors(indy7, result.positions, target)[0] == pytest.approx(result.position_error, abs=1e-9)
    assert within_limits(indy7, result.positions)


def test_a_group_of_some_joints_moves_only_those(indy7: Arm):
    solver = IkSolver(indy7.model, [0, 1, 2], "tcp", indy7.lower, indy7.upper)
    seed = np.array([0.0, 0.0, 0.0, 0.4, 0.9, -0.3])
    goal = seed.copy()
    goal[:3] = [0.5, -0.4, 1.1]
    result = solver.solve(indy7.pose(goal), seed, position_only=True, timeout_s=TIMEOUT_S,
                          rng=np.random.default_rng(8))
    assert result.success
    np.testing.assert_array_equal(result.positions[3:], seed[3:])
    assert errors(indy7, result.positions, indy7.pose(goal))[0] <= TOLERANCE


def test_a_continuous_joint_is_solved_as_an_unwrapped_angle_nearest_the_seed():
    """Pinocchio holds a continuous joint as (cos, sin): IK takes and gives its angle, a whole number of turns from
    the goal's, the one nearest the seed."""
    report = validate_package(INDY7)
    assert report.urdf_xml is not None
    urdf = report.urdf_xml.replace('<joint name="joint5" type="revolute">', '<joint name="joint5" type="continuous">')
    model = pin.buildModelFromXML(urdf)
    assert (model.nq, model.nv) == (7, 6)
    limits = ArmLimits.from_joint_limits(report.limits, [f"joint{i}" for i in range(6)])
    lower, upper = limits.min_position.copy(), limits.max_position.copy()
    lower[5], upper[5] = -np.inf, np.inf
    arm = Arm(model, "tcp", lower, upper)
    goal = np.array([0.3, -0.5, 1.2, 0.1, 0.8, 5.0])
    seed = np.array([0.25, -0.4, 1.1, 0.0, 0.7, 4.0 + 4 * math.pi])
    result = arm.solver.solve(arm.pose(goal), seed, timeout_s=TIMEOUT_S, rng=np.random.default_rng(9))
    assert result.success and max(errors(arm, result.positions, arm.pose(goal))) <= TOLERANCE
    turns = (result.positions[5] - goal[5]) / (2 * math.pi)
    assert round(turns) == 2 and abs(turns - 2) < 1e-3, result.positions  # the seed's turn, not pinocchio's (-π, π]


def test_a_model_with_a_floating_base_is_refused():
    report = validate_package(INDY7)
    assert report.urdf_xml is not None
    model = pin.buildModelFromXML(report.urdf_xml, pin.JointModelFreeFlyer())
    with pytest.raises(IkInputError, match="single-axis") as raised:
        IkSolver(model, range(6, 12), "tcp", np.full(12, -np.inf), np.full(12, np.inf))
    assert "root_joint" in raised.value.why and raised.value.how


def test_a_nan_target_is_refused_with_what_why_and_how(indy7: Arm):
    target = pin.SE3(np.eye(3), np.array([0.3, math.nan, 0.5]))
    with pytest.raises(IkInputError) as raised:
        indy7.solver.solve(target, np.zeros(6))
    error = raised.value
    assert isinstance(error, PlanningError) and error.code is MoveItCode.INVALID_GOAL_CONSTRAINTS
    assert "NaN" in error.summary and "finite" in error.how
    assert error.render().startswith("ERROR: ") and "\nHOW: " in error.render()


@pytest.mark.parametrize(("seed", "found"), [(np.zeros(5), "seed"), (np.array([0, 0, math.inf, 0, 0, 0]), "seed")])
def test_a_seed_of_the_wrong_size_or_not_finite_is_refused(indy7: Arm, seed: np.ndarray, found: str):
    with pytest.raises(IkInputError, match=found) as raised:
        indy7.solver.solve(indy7.pose(np.zeros(6)), seed)
    assert raised.value.code is MoveItCode.INVALID_ROBOT_STATE


@pytest.mark.parametrize("budget", [{"timeout_s": math.nan}, {"timeout_s": -1.0}, {"position_tolerance": 0.0},
                                    {"orientation_tolerance": math.nan}])
def test_a_timeout_or_tolerance_out_of_range_is_refused(indy7: Arm, budget: dict[str, float]):
    with pytest.raises(IkInputError, match="kinematics_solver_timeout"):
        indy7.solver.solve(indy7.pose(np.zeros(6)), np.zeros(6), **budget)


def test_a_target_whose_rotation_is_not_orthonormal_is_refused(indy7: Arm):
    target = pin.SE3(np.eye(3), np.array([0.3, 0.1, 0.5]))
    target.rotation = np.eye(3) * 1.1
    with pytest.raises(IkInputError, match="normalise"):
        indy7.solver.solve(target, np.zeros(6))


def test_an_unknown_tip_frame_or_bad_limits_are_refused(indy7: Arm):
    with pytest.raises(IkInputError, match="no frame 'gripper'") as raised:
        IkSolver(indy7.model, range(6), "gripper", indy7.lower, indy7.upper)
    assert raised.value.code is MoveItCode.INVALID_LINK_NAME
    with pytest.raises(IkInputError, match="lower <= upper"):
        IkSolver(indy7.model, range(6), "tcp", indy7.upper, indy7.lower)
