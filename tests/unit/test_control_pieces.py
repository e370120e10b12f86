"""Modes, limits, ruckig motions, kinematics and free drive on their own."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

from plem.control.commands import CommandHandle
from plem.control.free_drive import default_damping
from plem.control.kinematics import ArmDynamics
from plem.control.limits import ArmLimits
from plem.control.modes import REQUESTABLE, Mode, check_transition
from plem.control.motion import OVERRIDE_ROOM, plan_point_to_point, plan_stop
from plem.description.limits import JointLimit
from plem.description.validate import Stage, validate_package
from plem.errors import CommandRejected, ConfigError

JOINTS = tuple(f"joint{i}" for i in range(6))


@pytest.fixture(scope="module")
def indy7():
    report = validate_package("indy7_v2_description", stage=Stage.LAUNCH)
    return report.urdf_xml, ArmLimits.from_joint_limits(report.limits, JOINTS)


# -- modes -----------------------------------------------------------------------------------------

def test_fault_is_left_only_by_reset_and_trajectory_only_by_a_motion():
    for mode in Mode:
        with pytest.raises(CommandRejected):
            check_transition(Mode.FAULT, mode)
        if mode is not Mode.TRAJECTORY:
            with pytest.raises(CommandRejected):
                check_transition(mode, Mode.TRAJECTORY)
    check_transition(Mode.IDLE, Mode.HOLD)
    assert Mode.FAULT not in set().union(*REQUESTABLE.values())


@pytest.mark.parametrize("text, mode", [("hold", Mode.HOLD), ("FREE-DRIVE", Mode.FREE_DRIVE), (0, Mode.IDLE)])
def test_modes_parse_from_names_and_numbers(text, mode):
    assert Mode.parse(text) is mode


# -- limits ----------------------------------------------------------------------------------------

def test_limits_follow_the_arm_joint_order_and_absent_limits_are_infinite():
    limits = ArmLimits.from_joint_limits({"b": JointLimit("b", -1, 1, 2.0), "a": JointLimit("a", max_jerk=9.0)},
                                         ("a", "b"))
    assert limits.max_velocity[1] == 2.0 and math.isinf(limits.max_velocity[0])
    assert limits.max_jerk[0] == 9.0 and math.isinf(limits.min_position[0]) and limits.min_position[1] == -1


def test_missing_joint_limits_are_a_config_error():
    with pytest.raises(ConfigError, match="joint_limits.yaml"):
        ArmLimits.from_joint_limits({"a": JointLimit("a")}, ("a", "b"))


def test_position_check_names_joint_limit_and_value(indy7):
    _, limits = indy7
    with pytest.raises(CommandRejected) as caught:
        limits.check_positions(np.array([0, 0, 0, -3.2, 0, 0]), "the target")
    text = caught.value.render()
    assert "joint3" in text and "min_position" in text and "-3.2" in text


# -- motions ---------------------------------------------------------------------------------------

def sampled(motion, dt=0.001):
    times = np.arange(0, motion.duration + dt, dt)
    p, v, a = (np.zeros((len(times), 6)) for _ in range(3))
    out = np.zeros((3, 6))
    for i, t in enumerate(times):
        motion.sample(t, out)
        p[i], v[i], a[i] = out
    return p, v, a


def test_point_to_point_is_time_optimal_within_limits_and_ends_at_rest(indy7):
    _, limits = indy7
    rest = (np.zeros(6), np.zeros(6), np.zeros(6))
    target = np.array([1.0, -0.5, 0.2, 0.0, 2.0, -1.0])
    motion = plan_point_to_point(limits, rest, target)
    p, v, a = sampled(motion)
    assert np.allclose(p[-1], target) and np.allclose(v[-1], 0) and np.allclose(a[-1], 0)
    assert np.all(np.abs(v) <= limits.max_velocity + 1e-9) and np.all(np.abs(a) <= limits.max_acceleration + 1e-9)
    assert np.all(np.abs(np.diff(a, axis=0)) / 0.001 <= limits.max_jerk + 1e-6)
    # time-optimal within the share of the acceleration limit it uses (the rest is the speed override's room)
    assert np.max(np.abs(a[:, 4])) == pytest.approx(limits.max_acceleration[4] * OVERRIDE_ROOM, rel=1e-6)


def test_speed_scale_scales_time(indy7):
    _, limits = indy7
    rest = (np.zeros(6), np.zeros(6), np.zeros(6))
    target = np.full(6, 0.7)
    full = plan_point_to_point(limits, rest, target)
    half = plan_point_to_point(limits, rest, target, speed_scale=0.5)
    assert half.duration == pytest.approx(2 * full.duration, rel=1e-6)


def test_stop_reaches_standstill_with_bounded_jerk(indy7):
    _, limits = indy7
    moving = (np.zeros(6), np.full(6, 1.5), np.full(6, -2.0))
    stop = plan_stop(limits, moving)
    p, v, a = sampled(stop)
    assert np.allclose(v[-1], 0, atol=1e-9) and np.allclose(a[-1], 0, atol=1e-9)
    assert np.all(np.abs(np.diff(a, axis=0)) / 0.001 <= limits.max_jerk + 1e-6)


def test_state_at_matches_sampling(indy7):
    _, limits = indy7
    motion = plan_point_to_point(limits, (np.zeros(6), np.zeros(6), np.zeros(6)), np.full(6, 0.4))
    out = np.zeros((3, 6))
    for t in np.linspace(0, motion.duration, 17):
        motion.sample(t, out)
        for expected, got in zip(out, motion.state_at(t), strict=False):
            assert np.allclose(expected, got, atol=1e-12)


# -- kinematics ------------------------------------------------------------------------------------

def test_dynamics_agree_with_bare_pinocchio(indy7):
    xml, _ = indy7
    arm = ArmDynamics(xml, JOINTS)
    model = pin.buildModelFromXML(xml)
    data = model.createData()
    q = np.array([0.1, 0.7, -0.4, 0.3, 0.5, -0.2])
    v = np.array([0.2, -0.1, 0.3, 0.0, 0.1, 0.4])
    out = np.zeros(6)
    assert np.allclose(arm.gravity(q, out), pin.computeGeneralizedGravity(model, data, q))
    tau = arm.inverse_dynamics(q, v, np.ones(6), np.zeros(6))
    assert np.allclose(arm.forward_dynamics(q, v, tau, out), np.ones(6))
    pin.framesForwardKinematics(model, data, q)
    assert np.allclose(arm.forward_kinematics(q).homogeneous, data.oMf[model.nframes - 1].homogeneous)
    assert arm.jacobian(q).shape == (6, 6)


def test_joint_order_different_from_the_urdf_is_permuted(indy7):
    xml, _ = indy7
    reversed_names = tuple(reversed(JOINTS))
    arm = ArmDynamics(xml, reversed_names)
    straight = ArmDynamics(xml, JOINTS)
    q = np.array([0.1, 0.7, -0.4, 0.3, 0.5, -0.2])
    g_reversed = arm.gravity(q[::-1].copy(), np.zeros(6))
    assert np.allclose(g_reversed[::-1], straight.gravity(q, np.zeros(6)))
    assert np.allclose(arm.jacobian(q[::-1].copy())[:, ::-1], straight.jacobian(q))


def test_urdf_without_the_joints_is_a_config_error(indy7):
    xml, _ = indy7
    with pytest.raises(ConfigError, match="not a joint of the URDF"):
        ArmDynamics(xml, ("joint0", "joint1", "joint2", "joint3", "joint4", "wrist"))


# -- free drive ------------------------------------------------------------------------------------

def test_damping_is_capped_by_joint_inertia_for_stability(indy7):
    xml, limits = indy7
    arm = ArmDynamics(xml, JOINTS)
    damping = default_damping(arm, limits, 0.001)
    inertia = arm.inertia_diagonal(np.zeros(6))
    assert np.all(damping * 0.001 / inertia <= 0.2 + 1e-12)
    assert damping[1] > damping[5]


def test_a_stale_rejection_is_left_to_the_caller_to_plan_again_and_others_are_raised():
    stale = CommandHandle("move_joints")
    stale.reject(CommandRejected("planned from an outdated state", what="w", why="y", how="h"), stale=True)
    stale.wait_accepted(0)   # returns: the robot's methods re-plan on `stale`
    assert stale.stale and stale.rejection is not None
    refused = CommandHandle("move_joints")
    refused.reject(CommandRejected("outside the position limits", what="w", why="y", how="h"))
    with pytest.raises(CommandRejected, match="outside the position limits"):
        refused.wait_accepted(0)
