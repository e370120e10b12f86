"""Cartesian servo steps on the real Indy7 model: they move the tool as asked, reach pose targets, and slow to a
stop before singularities and joint limits, saying why."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from plem.control.cartesian_servo import CartesianServo, ServoSettings
from plem.control.kinematics import ArmDynamics
from plem.control.limits import ArmLimits
from plem.description.validate import validate_package
from plem.errors import CommandRejected, ConfigError

JOINTS = [f"joint{i}" for i in range(6)]
#: A working pose of the Indy7, away from its singularities (smallest singular value 0.17).
START = np.array([0.3, -0.3, -1.2, 0.2, -1.2, 0.2])
DT = 1e-3
SETTINGS = ServoSettings()


@pytest.fixture(scope="module")
def indy7() -> tuple[ArmDynamics, ArmLimits]:
    report = validate_package("indy7_v2_description")
    assert report.urdf_xml is not None
    return ArmDynamics(report.urdf_xml, JOINTS, "tcp"), ArmLimits.from_joint_limits(report.limits, JOINTS)


@pytest.fixture()
def servo(indy7: tuple[ArmDynamics, ArmLimits]) -> CartesianServo:
    return CartesianServo(*indy7)


def smallest_singular_value(dynamics: ArmDynamics, q: np.ndarray) -> float:
    return float(np.linalg.svd(dynamics.jacobian(q), compute_uv=False)[-1])


def test_a_twist_along_x_moves_the_tool_along_x(servo: CartesianServo, indy7: tuple[ArmDynamics, ArmLimits]):
    dynamics = indy7[0]
    step = servo.twist_step(START, np.array([0.1, 0, 0, 0, 0, 0]), DT)
    assert step.scale == 1.0 and step.reason == ""
    before, after = dynamics.forward_kinematics(START), dynamics.forward_kinematics(step.q)
    np.testing.assert_allclose(after.translation - before.translation, [0.1 * DT, 0, 0], atol=1e-6)
    assert np.linalg.norm(pin.log3(before.rotation.T @ after.rotation)) < 1e-6


def test_a_tool_frame_twist_is_the_base_frame_twist_turned_by_the_tools_rotation(servo: CartesianServo):
    twist = np.array([0.05, -0.02, 0.03, 0.2, 0.1, -0.3])
    rotation = servo.tool_pose(START).rotation
    in_tool = servo.twist_step(START, twist, DT, frame="tool")
    in_base = servo.twist_step(START, np.concatenate([rotation @ twist[:3], rotation @ twist[3:]]), DT)
    np.testing.assert_allclose(in_tool.q, in_base.q, atol=1e-14)
    assert not np.allclose(in_tool.q, servo.twist_step(START, twist, DT).q)


def test_a_pose_target_is_approached_monotonically_and_reached(servo: CartesianServo):
    target = servo.tool_pose(START + [0.15, -0.1, 0.2, 0.3, -0.25, 0.4])
    q = START
    distances, angles = [], []
    for _ in range(5000):
        q = servo.pose_step(q, target, DT).q
        offset = servo.tool_pose(q).actInv(target)
        distances.append(float(np.linalg.norm(offset.translation)))
        angles.append(float(np.linalg.norm(pin.log3(offset.rotation))))
        if distances[-1] < 1e-9 and angles[-1] < 1e-9:
            break
    assert distances[-1] < 1e-9 and angles[-1] < 1e-9, "the target was not reached in 5 s"
    assert np.all(np.diff(distances) <= 1e-12) and np.all(np.diff(angles) <= 1e-12)
    speeds = np.abs(np.diff(distances)) / DT    # within the step's first-order error of the commanded top speed
    assert speeds.max() == pytest.approx(SETTINGS.max_linear_speed, rel=1e-3)


def test_a_pose_target_is_approached_no_faster_than_the_tool_speed(servo: CartesianServo):
    twist = servo.approach_twist(servo.tool_pose(START), servo.tool_pose(START + [0.5, 0, 0, 0, 0, 0]), DT)
    assert np.linalg.norm(twist[:3]) <= SETTINGS.max_linear_speed + 1e-12
    assert np.linalg.norm(twist[3:]) <= SETTINGS.max_angular_speed + 1e-12


def test_the_elbow_straightening_slows_to_a_stop_before_the_singularity(servo: CartesianServo,
                                                                         indy7: tuple[ArmDynamics, ArmLimits]):
    dynamics = indy7[0]
    shoulder = dynamics.frame_placement(START, dynamics.model.getFrameId("joint1")).translation
    outward = dynamics.forward_kinematics(START).translation - shoulder
    twist = np.concatenate([0.2 * outward / np.linalg.norm(outward), np.zeros(3)])
    q, scales, reasons, sigmas = START, [], [], []
    for _ in range(3000):
        step = servo.twist_step(q, twist, DT)
        q = step.q
        scales.append(step.scale)
        reasons.append(step.reason)
        sigmas.append(smallest_singular_value(dynamics, q))
    assert scales[0] == 1.0 and scales[-1] == 0.0 and reasons[-1] == "singularity"
    assert min(sigmas) >= SETTINGS.stop_singular_value - 1e-6
    assert q[2] < -0.1, "the elbow came near straight"
    slowing = [s for s, r in zip(scales, reasons, strict=True) if r == "singularity"]
    assert np.all(np.diff(slowing) <= 1e-12), "the scale rose again on the way to the stop"
    assert np.abs(np.diff(scales)).max() < 0.1, "the scale jumped instead of falling smoothly"
    backing = servo.twist_step(q, -twist, DT)
    assert backing.scale > 0.5 and backing.reason != "singularity"


def test_a_joint_near_its_limit_stops_before_it(servo: CartesianServo, indy7: tuple[ArmDynamics, ArmLimits]):
    limits = indy7[1]
    q = START.copy()
    q[5] = limits.max_position[5] - 0.3
    spin = np.array([0, 0, 0, 0, 0, 0.5])       # about the tool's z axis: joint5 turns toward its upper limit
    steps = []
    for _ in range(2000):
        step = servo.twist_step(q, spin, DT, frame="tool")
        q = step.q
        steps.append(step)
    assert steps[0].scale == 1.0 and steps[-1].scale == 0.0 and steps[-1].reason == "joint limit"
    assert q[5] == pytest.approx(limits.max_position[5] - SETTINGS.joint_limit_stop, abs=1e-9)
    assert all(step.q[5] <= limits.max_position[5] - SETTINGS.joint_limit_stop + 1e-12 for step in steps)
    assert steps[0].reason == "" and any(0.0 < s.scale < 1.0 and s.reason == "joint limit" for s in steps)
    assert servo.twist_step(q, -spin, DT, frame="tool").scale == 1.0


def test_a_fast_joint_brakes_for_its_limit_within_its_acceleration(servo: CartesianServo,
                                                                    indy7: tuple[ArmDynamics, ArmLimits]):
    limits = indy7[1]
    q = START.copy()
    q[5] = limits.max_position[5] - 0.5
    spin = np.array([0, 0, 0, 0, 0, 3.0])       # braking from 3 rad/s at 3 rad/s² takes 1.5 rad: more than the margin
    speeds = []
    for _ in range(3000):
        step = servo.twist_step(q, spin, DT, frame="tool")
        speeds.append((step.q[5] - q[5]) / DT)
        q = step.q
    room = 0.5 - SETTINGS.joint_limit_stop
    assert speeds[0] == pytest.approx(np.sqrt(2 * limits.max_acceleration[5] * room), rel=1e-3)
    assert speeds[-1] == 0.0
    assert q[5] == pytest.approx(limits.max_position[5] - SETTINGS.joint_limit_stop, abs=1e-9)
    decelerations = -np.diff(speeds[:np.flatnonzero(speeds)[-1]])  / DT     # up to the landing step (µrad)
    assert decelerations.max() <= limits.max_acceleration[5] * (1 + 1e-6)


def test_a_twist_too_fast_for_the_joints_is_slowed_to_their_velocity_limits(servo: CartesianServo,
                                                                             indy7: tuple[ArmDynamics, ArmLimits]):
    step = servo.twist_step(START, np.array([3.0, 0, 0, 0, 0, 0]), DT)
    assert step.reason == "velocity limit" and 0.0 < step.scale < 1.0
    speeds = np.abs(step.q - START) / DT
    assert np.all(speeds <= indy7[1].max_velocity + 1e-9) and np.isclose(speeds / indy7[1].max_velocity, 1).any()


def test_the_singular_value_derivative_matches_finite_differences(servo: CartesianServo,
                                                                  indy7: tuple[ArmDynamics, ArmLimits]):
    dynamics = indy7[0]
    for q in (START, np.array([0.27, -0.85, -0.2, 0.2, -1.83, 0.3]), np.array([1.0, 0.5, -2.0, -1.0, 0.7, 2.0])):
        jacobian = dynamics.jacobian(q)
        left, _, right = np.linalg.svd(jacobian)
        gradient = servo._singular_value_gradient(jacobian, left[:, -1], right[-1])
        numeric = [(smallest_singular_value(dynamics, q + 1e-6 * e) - smallest_singular_value(dynamics, q - 1e-6 * e))
                   / 2e-6 for e in np.eye(6)]
        np.testing.assert_allclose(gradient, numeric, atol=1e-7)


def test_a_seven_joint_arm_is_servoed_too():
    """The Indy RP2 (7 joints): the step's Jacobian is 6×7, its least squares the minimum-norm joint motion."""
    report = validate_package("indyrp2_v2_description")
    assert report.urdf_xml is not None
    joints = [f"joint{i}" for i in range(7)]
    dynamics = ArmDynamics(report.urdf_xml, joints, "tcp")
    servo = CartesianServo(dynamics, ArmLimits.from_joint_limits(report.limits, joints))
    q = np.array([0.2, -0.4, 0.3, -1.4, 0.2, -1.0, 0.3])
    step = servo.twist_step(q, np.array([0.1, 0, 0, 0, 0, 0]), DT)
    moved = dynamics.forward_kinematics(step.q).translation - dynamics.forward_kinematics(q).translation
    np.testing.assert_allclose(moved, [0.1 * DT, 0, 0], atol=1e-6)
    target = servo.tool_pose(q + 0.2)
    for _ in range(3000):
        q = servo.pose_step(q, target, DT).q
    offset = servo.tool_pose(q).actInv(target)
    assert np.linalg.norm(offset.translation) < 1e-9 and np.linalg.norm(pin.log3(offset.rotation)) < 1e-9


def test_an_arm_whose_joints_are_listed_in_another_order_gets_its_targets_in_that_order(
        servo: CartesianServo, indy7: tuple[ArmDynamics, ArmLimits]):
    """Positions, limits and targets are in the arm's joint order even where it is not the URDF's chain order."""
    report = validate_package("indy7_v2_description")
    assert report.urdf_xml is not None
    order = [1, 2, 3, 4, 5, 0]
    names = [JOINTS[i] for i in order]
    listed = CartesianServo(ArmDynamics(report.urdf_xml, names, "tcp"), ArmLimits.from_joint_limits(report.limits,
                                                                                                      names))
    q = START.copy()
    q[5] = indy7[1].max_position[5] - 0.05           # near a limit, so the limits' order matters too
    twist = np.array([0.05, 0.02, -0.03, 0.1, -0.2, 0.5])
    expected = servo.twist_step(q, twist, DT, frame="tool")
    got = listed.twist_step(q[order], twist, DT, frame="tool")
    np.testing.assert_allclose(got.q, expected.q[order], atol=1e-15)
    assert (got.scale, got.reason) == (expected.scale, expected.reason) and expected.reason == "joint limit"


@pytest.mark.parametrize(("q", "twist", "dt", "why"), [
    (START, [0.1, 0, 0, 0, 0, float("nan")], DT, "twist (or the pose target it comes from) is not all finite"),
    (START, [0.1, 0, 0], DT, "the twist has 3 values"),
    (START, [0.1, 0, 0, 0, 0, 0], 0.0, "the period is 0.0 s"),
    (START[:5], [0.1, 0, 0, 0, 0, 0], DT, "got 5"),
    (np.where(np.arange(6) == 2, np.inf, START), [0.1, 0, 0, 0, 0, 0], DT, "not finite for joint2"),
])
def test_a_step_from_values_that_are_not_finite_or_not_of_their_shape_is_refused(servo: CartesianServo, q, twist,
                                                                                 dt, why):
    with pytest.raises(CommandRejected) as error:
        servo.twist_step(np.asarray(q), np.asarray(twist, dtype=float), dt)
    assert why in error.value.why


def test_a_pose_target_that_is_not_finite_is_refused(servo: CartesianServo):
    target = servo.tool_pose(START)
    target.translation = np.array([0.3, np.nan, 0.5])
    with pytest.raises(CommandRejected, match="pose target"):
        servo.pose_step(START, target, DT)


@pytest.mark.parametrize(("changes", "why"), [
    ({"stop_singular_value": 0.1}, "stop_singular_value 0.1 is not below slowdown_singular_value 0.08"),
    ({"joint_limit_stop": 0.2}, "joint_limit_stop 0.2 is not below joint_limit_margin 0.1"),
    ({"max_linear_speed": -1.0}, "max_linear_speed = -1.0 is not a positive number"),
    ({"damping": float("nan")}, "damping = nan is not a positive number"),
])
def test_settings_that_cannot_work_are_refused(changes: dict[str, float], why: str):
    with pytest.raises(ConfigError) as error:
        ServoSettings(**changes)
    assert why in error.value.why
