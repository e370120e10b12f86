"""Payloads on the real Indy7 model: their checks, the last body with one added, and their fit from held poses."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from plem.control.kinematics import ArmDynamics
from plem.control.limits import ArmLimits
from plem.control.payload import MAX_PAYLOAD_MASS, Payload, combined_body
from plem.control.payload_estimation import (
    ESTIMATION_POSES,
    PayloadFitError,
    estimation_poses,
    fit_payload,
    flange_link,
    payload_in_joint_frame,
    payload_regressor,
)
from plem.description.validate import validate_package
from plem.errors import ConfigError

JOINTS = [f"joint{i}" for i in range(6)]
#: A pose of the Indy7 away from its singularities, the flange pointing down and forward.
START = np.array([0.2, -0.4, -1.6, 0.1, -1.2, 0.3])
#: A 2.5 kg gripper with its centre off every flange axis, and a box-like inertia.
GRIPPER = Payload(2.5, (0.03, -0.02, 0.08), [[0.004, 0.0002, 0.0], [0.0002, 0.005, 0.0001], [0.0, 0.0001, 0.003]])


@pytest.fixture(scope="module")
def indy7() -> tuple[ArmDynamics, ArmLimits]:
    report = validate_package("indy7_v2_description")
    assert report.urdf_xml is not None
    return ArmDynamics(report.urdf_xml, JOINTS, "tcp"), ArmLimits.from_joint_limits(report.limits, JOINTS)


def gravity_with(dynamics: ArmDynamics, payload: Payload, link: str, q: np.ndarray) -> np.ndarray:
    """Pinocchio's own gravity torques at `q` of the model with `payload` added to the last body at `link`."""
    model = pin.Model(dynamics.model)
    placement = model.frames[model.getFrameId(link, pin.FrameType.BODY)].placement
    model.inertias[model.njoints - 1] += placement.act(pin.Inertia(payload.mass, payload.com,
                                                                   payload.inertia_about_com))
    tau: np.ndarray = pin.computeGeneralizedGravity(model, model.createData(), q)
    return tau


def residuals(dynamics: ArmDynamics, payload: Payload, link: str, poses: list[np.ndarray],
              noise: float = 0.0, seed: int = 0) -> list[tuple[np.ndarray, np.ndarray]]:
    """(q, measured - model without payload) at `poses`, measured = pinocchio's gravity with it, plus noise."""
    rng = np.random.default_rng(seed)
    without = np.zeros(dynamics.dof)
    return [(q, gravity_with(dynamics, payload, link, q) - dynamics.gravity(q, without)
             + rng.normal(0.0, noise, dynamics.dof)) for q in poses]


def test_the_flange_is_the_link_the_last_joint_moves(indy7):
    assert flange_link(indy7[0].model) == "link6"


@pytest.mark.parametrize(("mass", "com", "inertia", "found"), [
    (-1.0, (0, 0, 0), None, "mass -1 kg"),
    (float("nan"), (0, 0, 0), None, "mass nan kg"),
    (MAX_PAYLOAD_MASS + 1, (0, 0, 0), None, "mass 101 kg"),
    (1.0, (0, 0, 2.5), None, "2.5 m from the flange"),
    (1.0, (0, float("inf"), 0), None, "centre of mass is not finite"),
    (1.0, (0, 0), None, "2 values, not 3"),
    (1.0, (0, 0, 0), [[1, 0.5, 0], [0, 1, 0], [0, 0, 1]], "not symmetric"),
    (1.0, (0, 0, 0), [[1, 0, 0], [0, -1, 0], [0, 0, 1]], "not positive semi-definite"),
    (1.0, (0, 0, 0), [[0.1, 0, 0], [0, 0.1, 0], [0, 0, 0.5]], "triangle inequality"),
    (1.0, (0, 0, 0), [[1, 0], [0, 1]], "not 3×3"),
])
def test_a_payload_no_arm_can_carry_is_refused_saying_why(mass, com, inertia, found):
    with pytest.raises(ConfigError) as error:
        Payload(mass, com, inertia)
    assert found in error.value.why
    assert "payload:=" in error.value.how and "set_payload" in error.value.how


def test_every_problem_of_a_payload_is_named_at_once():
    with pytest.raises(ConfigError) as error:
        Payload(-2.0, (3.0, 0.0, 0.0))
    assert "mass -2 kg" in error.value.why and "3 m from the flange" in error.value.why


def test_a_payload_from_four_or_ten_numbers_reads_the_inertia_in_urdf_order():
    assert Payload.from_numbers([1.5, 0, 0, 0.05]) == Payload(1.5, (0, 0, 0.05))
    payload = Payload.from_numbers([1, 0, 0, 0, 0.3, 0.01, 0.02, 0.4, 0.03, 0.5])
    assert payload.inertia_about_com.tolist() == [[0.3, 0.01, 0.02], [0.01, 0.4, 0.03], [0.02, 0.03, 0.5]]
    with pytest.raises(ConfigError, match="5 numbers"):
        Payload.from_numbers([1, 0, 0, 0, 1])


def test_the_combined_body_is_pinocchios_sum_of_inertias(indy7):
    inertia = indy7[0].model.inertias[indy7[0].model.njoints - 1]
    mass, com, combined = combined_body(inertia.mass, inertia.lever, inertia.inertia, GRIPPER)
    expected = inertia + pin.Inertia(GRIPPER.mass, GRIPPER.com, GRIPPER.inertia_about_com)
    assert mass == pytest.approx(expected.mass, abs=1e-12)
    np.testing.assert_allclose(com, expected.lever, atol=1e-12)
    np.testing.assert_allclose(combined, expected.inertia, atol=1e-12)


def test_a_weightless_payload_leaves_the_body_as_it_was(indy7):
    inertia = indy7[0].model.inertias[1]
    mass, com, combined = combined_body(inertia.mass, inertia.lever, inertia.inertia, Payload(0.0))
    assert mass == inertia.mass and np.array_equal(com, inertia.lever) and np.array_equal(combined, inertia.inertia)


def test_a_payload_at_the_tool_link_moves_into_the_last_joints_frame(indy7):
    model = indy7[0].model
    moved = payload_in_joint_frame(model, GRIPPER, "tcp")
    np.testing.assert_allclose(moved.com, GRIPPER.com + [0.0, 0.0, 0.06], atol=1e-12)
    # the core's body: the last joint's inertia with the payload added there gives pinocchio's gravity with it
    last = model.inertias[model.njoints - 1]
    mass, com, combined = combined_body(last.mass, last.lever, last.inertia, moved)
    core_model = pin.Model(model)
    core_model.inertias[model.njoints - 1] = pin.Inertia(mass, com, combined)
    tau = pin.computeGeneralizedGravity(core_model, core_model.createData(), START)
    np.testing.assert_allclose(tau, gravity_with(indy7[0], GRIPPER, "tcp", START), atol=1e-10)


def test_the_regressor_gives_the_payloads_gravity_torques(indy7):
    dynamics = indy7[0]
    point = Payload(GRIPPER.mass, GRIPPER.center_of_mass)
    theta = np.concatenate([[point.mass], point.mass * point.com])
    for q in (START, np.zeros(6), START[::-1]):
        (_, expected), = residuals(dynamics, point, "tcp", [q])
        np.testing.assert_allclose(payload_regressor(dynamics, q, "tcp") @ theta, expected, atol=1e-10)


def test_the_fit_recovers_the_mass_and_centre_of_mass_from_exact_torques(indy7):
    dynamics, limits = indy7
    poses = estimation_poses(dynamics, limits, START, "link6")
    fitted = fit_payload(residuals(dynamics, GRIPPER, "link6", poses), dynamics, "link6")
    assert fitted.mass == pytest.approx(GRIPPER.mass, abs=1e-6)
    np.testing.assert_allclose(fitted.com, GRIPPER.com, atol=1e-6)
    assert fitted.inertia is None


@pytest.mark.parametrize("seed", range(5))
def test_the_fit_stays_within_5_percent_of_the_mass_under_torque_noise(indy7, seed):
    dynamics, limits = indy7
    poses = estimation_poses(dynamics, limits, START, "link6")
    fitted = fit_payload(residuals(dynamics, GRIPPER, "link6", poses, noise=0.05, seed=seed), dynamics, "link6")
    assert fitted.mass == pytest.approx(GRIPPER.mass, rel=0.05)


def test_estimation_poses_are_few_near_the_start_and_inside_the_limits(indy7):
    dynamics, limits = indy7
    poses = estimation_poses(dynamics, limits, START, "link6")
    assert len(poses) == ESTIMATION_POSES and np.array_equal(poses[0], START)
    for pose in poses:
        assert np.array_equal(pose[:3], START[:3])     # only the wrist turns
        assert np.all(pose >= limits.min_position) and np.all(pose <= limits.max_position)
        assert np.abs(pose - START).max() <= np.pi / 2 + 1e-12


@pytest.mark.parametrize("start", [
    np.array([0.2, -0.4, -1.6, 0.0, 2.0, 0.3]),    # the flange's z axis straight up: its component never shows
    START,                                          # 3.3° from vertical: it shows, 70 times weaker than the rest
])
def test_poses_that_only_spin_the_flange_are_refused_naming_what_they_miss(indy7, start):
    dynamics = indy7[0]
    spun = [start + [0, 0, 0, 0, 0, turn] for turn in (-1.0, 0.0, 1.0, 2.0)]
    with pytest.raises(PayloadFitError) as error:
        fit_payload(residuals(dynamics, GRIPPER, "link6", spun), dynamics, "link6")
    assert error.value.summary.startswith("the poses do not determine the centre of mass along the flange's z")
    assert "condition number" in error.value.why
    assert "joint3, joint4, joint5" in error.value.how


def test_a_small_wiggle_of_one_wrist_joint_is_refused(indy7):
    wiggled = [START + [0, 0, 0, 0, turn, 0] for turn in (-0.1, 0.0, 0.1)]
    with pytest.raises(PayloadFitError, match="condition number"):
        fit_payload(residuals(indy7[0], GRIPPER, "link6", wiggled), indy7[0], "link6")


def test_one_pose_is_refused(indy7):
    with pytest.raises(PayloadFitError, match="too few poses"):
        fit_payload(residuals(indy7[0], GRIPPER, "link6", [START]), indy7[0], "link6")


def test_no_payload_fits_as_none(indy7):
    dynamics, limits = indy7
    poses = estimation_poses(dynamics, limits, START, "link6")
    fitted = fit_payload(residuals(dynamics, Payload(0.0), "link6", poses, noise=0.05), dynamics, "link6")
    assert fitted == Payload(0.0)


def test_an_arm_whose_joints_are_listed_in_another_order_gets_the_same_poses_and_fit_in_that_order():
    report = validate_package("indy7_v2_description")
    assert report.urdf_xml is not None
    order = [1, 2, 3, 4, 5, 0]
    names = [JOINTS[i] for i in order]
    listed = ArmDynamics(report.urdf_xml, names, "tcp")
    chain = ArmDynamics(report.urdf_xml, JOINTS, "tcp")
    expected = estimation_poses(chain, ArmLimits.from_joint_limits(report.limits, JOINTS), START, "link6")
    poses = estimation_poses(listed, ArmLimits.from_joint_limits(report.limits, names), START[order], "link6")
    np.testing.assert_array_equal(np.array(poses), np.array(expected)[:, order])
    samples = [(q[order], tau[order]) for q, tau in residuals(chain, GRIPPER, "link6", expected)]
    fitted = fit_payload(samples, listed, "link6")
    np.testing.assert_allclose(fitted.com, GRIPPER.com, atol=1e-6)
