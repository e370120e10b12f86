"""A payload in the arm model's own frames, and its mass and centre of mass fitted from efforts at held poses.

The compiled core's rigid-body model (`kinematics.compiled_model`) keeps each body in its joint's frame; a payload
is given in the flange link's frame, which a URDF places after the last joint with fixed joints (the Indy7's
`tcp` sits 6 cm past `link6`): `payload_in_joint_frame` moves it there.

Held still, a payload adds to each joint the torque of its weight, which is linear in (m, m·cx, m·cy, m·cz): the
columns of `payload_regressor`. Efforts measured at a few poses, less the model's own gravity torques, give
those four numbers by least squares (`fit_payload`), as long as the poses show the centre of mass to gravity from
enough directions (`estimation_poses` picks such poses). Vectors are in the arm's joint order, as everywhere.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from plem.control.kinematics import ArmDynamics, link_frame
from plem.control.limits import ArmLimits
from plem.control.payload import Payload, combined_body
from plem.errors import ConfigError, PlemError

#: Length (m) that makes the unknowns comparable: the fit weighs an error of 1 kg in the mass as one of 1 kg at
#: this distance in the centre of mass (a tool's typical reach past the flange).
REFERENCE_LENGTH = 0.1
#: Largest condition number of the regressor (in those units) a fit accepts: beyond it, the weakest combination
#: of (m, m·c) moves the torques so much less than the strongest that measurement noise decides it. Good poses
#: give about 6 on the Indy7; wiggling one wrist joint by 0.1 rad gives 44.
MAX_CONDITION = 30.0
#: Standard errors a fitted mass must exceed to count as a payload: below, no payload is measurable.
MASS_SIGNIFICANCE = 3.0
#: Wrist turns (rad) the estimation poses combine: a quarter turn shows the centre of mass from a new side.
WRIST_TURNS = (-np.pi / 2, 0.0, np.pi / 2)
#: Distance (rad) estimation poses keep from each joint's position limits.
LIMIT_CLEARANCE = 0.1
#: Poses `estimation_poses` returns, the start among them: four unknowns, and one more for the noise.
ESTIMATION_POSES = 5
PARAMETERS = ("the mass", "the centre of mass along the flange's x", "the centre of mass along the flange's y",
              "the centre of mass along the flange's z")


class PayloadFitError(PlemError):
    """Efforts at the given poses cannot determine a payload."""


def wrist_joints(dynamics: ArmDynamics) -> np.ndarray:
    """The arm-order indices of the last three joints of the chain (the wrist), in chain order."""
    indices: np.ndarray = np.argsort(dynamics.model_indices)[-3:]
    return indices


def flange_link(model: pin.Model) -> str:
    """The link the arm's last joint moves (the flange, e.g. the Indy7's `link6`), where payloads are given."""
    last = model.njoints - 1
    for frame in model.frames:
        if frame.type == pin.FrameType.BODY and frame.parentJoint == last and frame.placement.isIdentity():
            return str(frame.name)
    raise ConfigError("the URDF has no link on its last joint",
                      what=f"a link that joint {model.names[last]} moves, as the flange",
                      why=f"no link of the model sits at the frame of {model.names[last]}",
                      how="add the flange link as the child of the last joint in the URDF")


def payload_in_joint_frame(model: pin.Model, payload: Payload, link: str) -> Payload:
    """`payload`, given in the frame of link `link`, expressed in the frame of the joint that moves that link (the
    frame of the compiled core's body): its centre of mass placed and its inertia turned by the link's placement."""
    placement = model.frames[link_frame(model, link)].placement
    rotation = np.asarray(placement.rotation)
    com = rotation @ payload.com + np.asarray(placement.translation)
    inertia = None if payload.inertia is None else (rotation @ payload.inertia_about_com @ rotation.T).tolist()
    return Payload(payload.mass, (com[0], com[1], com[2]), inertia)


def payload_regressor(dynamics: ArmDynamics, q: np.ndarray, link: str) -> np.ndarray:
    """dof×4 matrix Y with Y·(m, m·cx, m·cy, m·cz) the joint torques that hold, at positions `q`, a point mass m
    whose centre is c in the frame of link `link` (the same sign as `ArmDynamics.gravity`).

    The weight m·g at the point p = p_link + R·c needs τ = -J_p^T m·g, with J_p = J_v - [R·c]× J_ω from the
    link's Jacobian in world-aligned axes; -(J_v - [R c]× J_ω)^T g = -J_v^T g + J_ω^T [g]× R c.
    """
    model = dynamics.model
    data = model.createData()
    frame = link_frame(model, link)
    configuration = dynamics.space.configuration(dynamics.to_model_order(q))
    pin.computeJointJacobians(model, data, configuration)
    pin.updateFramePlacements(model, data)
    jacobian = pin.getFrameJacobian(model, data, frame, pin.LOCAL_WORLD_ALIGNED)[:, dynamics.model_indices]
    gravity = np.asarray(model.gravity.linear)
    rotation = np.asarray(data.oMf[frame].rotation)
    regressor = np.empty((dynamics.dof, 4))
    regressor[:, 0] = -jacobian[:3].T @ gravity
    regressor[:, 1:] = jacobian[3:].T @ pin.skew(gravity) @ rotation
    return regressor


#: Column scale of the regressor for the unknowns (m, m·c / REFERENCE_LENGTH).
_UNITS = np.array([1.0, REFERENCE_LENGTH, REFERENCE_LENGTH, REFERENCE_LENGTH])


def _poorly_seen(stacked: np.ndarray) -> tuple[float, str]:
    """The condition number of the scaled regressor and the unknowns its weakest combination is mostly made of."""
    _, singular, vt = np.linalg.svd(stacked * _UNITS, full_matrices=False)
    condition = float(singular[0] / singular[-1]) if singular[-1] > 0 else float("inf")
    weights = np.abs(vt[-1])
    named = [PARAMETERS[i] for i in np.argsort(-weights) if weights[i] >= 0.3]
    return condition, " and ".join(named)


def fit_payload(samples: Sequence[tuple[np.ndarray, np.ndarray]], dynamics: ArmDynamics, link: str) -> Payload:
    """The payload (mass and centre of mass in `link`'s frame; no inertia, which still poses do not show) from
    `samples` of (positions, measured effort minus the model's gravity torque without payload), by least squares.

    Poses that leave a combination of the four unknowns undetermined (condition number above MAX_CONDITION) are a
    PayloadFitError naming it; a mass within MASS_SIGNIFICANCE standard errors of zero is no payload (mass 0).
    """
    wrist = ", ".join(dynamics.joint_names[k] for k in wrist_joints(dynamics))
    how = (f"hold more poses that turn the wrist ({wrist}) by about a quarter turn each way, so the flange's axes "
           "lie across gravity in some poses and along it in others (robot.estimate_payload() holds such poses)")
    if len(samples) < 2:
        raise PayloadFitError("too few poses to estimate the payload",
                              what="efforts at two poses or more, the wrist turned between them",
                              why=f"{len(samples)} pose{'s' if len(samples) != 1 else ''}", how=how)
    stacked = np.vstack([payload_regressor(dynamics, np.asarray(q, dtype=float), link) for q, _ in samples])
    torques = np.concatenate([np.asarray(tau, dtype=float).reshape(-1) for _, tau in samples])
    condition, weak = _poorly_seen(stacked)
    if not condition <= MAX_CONDITION:
        raise PayloadFitError(f"the poses do not determine {weak}",
                              what=f"poses whose efforts determine the mass and the centre of mass (condition "
                                   f"number at most {MAX_CONDITION:g})",
                              why=f"at these {len(samples)} poses the condition number is {condition:.3g}: {weak} "
                                  "barely changes the torques, so noise would decide it",
                              how=how)
    theta, *_ = np.linalg.lstsq(stacked, torques, rcond=None)
    residual = torques - stacked @ theta
    variance = float(residual @ residual) / max(len(torques) - 4, 1)
    mass_error = float(np.sqrt(variance * np.linalg.inv(stacked.T @ stacked)[0, 0]))
    mass = float(theta[0])
    if mass <= MASS_SIGNIFICANCE * mass_error:
        if mass < -MASS_SIGNIFICANCE * mass_error:
            raise PayloadFitError("the efforts say the arm carries less than nothing",
                                  what="efforts at least the model's own gravity torques",
                                  why=f"the fitted mass is {mass:.4g} kg (± {mass_error:.2g} kg)",
                                  how="check the description's inertials (the URDF), and that nothing holds or "
                                      "pushes the arm while it estimates")
        return Payload(0.0)
    com = theta[1:] / mass
    return Payload(mass, (com[0], com[1], com[2]))


def estimation_poses(dynamics: ArmDynamics, limits: ArmLimits, start_q: np.ndarray,
                     link: str) -> list[np.ndarray]:
    """ESTIMATION_POSES poses for `fit_payload`: `start_q` first, then wrist turns of it (each of the last three
    joints by a quarter turn either way or not, LIMIT_CLEARANCE inside its limits) chosen one by one to make the
    fit best conditioned (largest determinant of the normal matrix, in the units of MAX_CONDITION).

    Held still, a payload's weight shows only through the component of its centre of mass across gravity;
    turning the wrist turns the flange's axes through gravity, so each of m·cx, m·cy, m·cz moves the torques in
    some pose. The arm itself stays near where it starts, as the caller plans collision-free moves to them.
    """
    start = np.asarray(start_q, dtype=float)
    low, high = limits.min_position + LIMIT_CLEARANCE, limits.max_position - LIMIT_CLEARANCE
    wrist = wrist_joints(dynamics)
    candidates: list[np.ndarray] = []
    for turns in np.array(np.meshgrid(*[WRIST_TURNS] * 3)).reshape(3, -1).T:
        pose = start.copy()
        pose[wrist] = np.clip(start[wrist] + turns, low[wrist], high[wrist])
        if not any(np.allclose(pose, other) for other in [start, *candidates]):
            candidates.append(pose)
    regressors = [payload_regressor(dynamics, pose, link) * _UNITS for pose in candidates]
    chosen = [start]
    first = payload_regressor(dynamics, start, link) * _UNITS
    normal = first.T @ first
    while len(chosen) < ESTIMATION_POSES and candidates:
        scores = [np.linalg.slogdet(normal + y.T @ y + 1e-12 * np.eye(4))[1] for y in regressors]
        best = int(np.argmax(scores))
        chosen.append(candidates.pop(best))
        y = regressors.pop(best)
        normal = normal + y.T @ y
    return chosen


def last_body_with(model: pin.Model, payload: Payload) -> np.ndarray:
    """The compiled core's last body (mass, centre of mass, inertia about it, 13 numbers in the last joint's frame)
    from the description's own inertials with `payload`, given at the flange, rigidly added; what the core's model
    and the simulated arm take when a payload is set."""
    last = model.inertias[model.njoints - 1]
    mass, com, inertia = combined_body(float(last.mass), np.asarray(last.lever), np.asarray(last.inertia),
                                       payload_in_joint_frame(model, payload, flange_link(model)))
    body: np.ndarray = np.concatenate([[mass], com, inertia.reshape(9)])
    return body
