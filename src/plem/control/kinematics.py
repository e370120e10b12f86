"""Rigid-body kinematics and dynamics of the arm from its URDF, through pinocchio.

One `ArmDynamics` serves the simulated arm (forward dynamics), free drive (gravity) and the planner
(forward kinematics, Jacobian). Vectors are in the arm's joint order; when the URDF lists the joints
in another order the values are permuted on the way in and out.

Positions are one number per joint everywhere in plem: a continuous joint's is its unwrapped angle. Pinocchio
carries such a joint as the cosine and sine of the angle (two configuration values for one degree of freedom);
`JointSpace` is the one place that turns positions into pinocchio's configuration vector.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from plem.control import compiled
from plem.errors import ConfigError

#: Pinocchio's joint types whose configuration is the (cos, sin) of an unbounded angle: URDF continuous joints.
CONTINUOUS_TYPES = frozenset({"JointModelRUBX", "JointModelRUBY", "JointModelRUBZ",
                              "JointModelRevoluteUnboundedUnaligned"})


def link_frame(model: pin.Model, link: str) -> int:
    """The frame of URDF link `link`. A URDF may give a link and a joint the same name (indy-ros2 names both `tcp`)
    and pinocchio makes a frame of each, so every lookup by a link's name names the frame type."""
    return int(model.getFrameId(link, pin.FrameType.BODY))


def has_link(model: pin.Model, link: str) -> bool:
    """Whether the model has a frame for URDF link `link` (see `link_frame`)."""
    return bool(model.existFrame(link, pin.FrameType.BODY))


class JointSpace:
    """Pinocchio's configuration vector of a model of single-DOF joints, from one position per joint.

    Positions come in pinocchio's joint order, one per degree of freedom (a joint's `idx_v`); a continuous
    joint's position is its angle (any number of turns), which pinocchio holds as (cos, sin) at its `idx_q`.
    Every pinocchio call that takes joint positions in plem builds its configuration here.
    """

    def __init__(self, model: pin.Model) -> None:
        joints = list(model.joints)[1:]
        circular = [joint for joint in joints if joint.shortname() in CONTINUOUS_TYPES]
        single = [joint for joint in joints if joint.nq == joint.nv == 1]
        #: Joints of more than one degree of freedom (floating, planar), whose positions this space cannot hold.
        self.multi_axis = tuple(f"{model.names[joint.id]} ({joint.shortname()})" for joint in joints if joint.nv != 1)
        self.nq, self.nv = model.nq, model.nv
        #: Whether positions are pinocchio's configuration as they are (no continuous joint).
        self.identity = not circular and self.nq == self.nv
        #: For each position, whether it belongs to a continuous joint (no position bounds).
        self.continuous = np.zeros(self.nv, dtype=bool)
        self.continuous[[joint.idx_v for joint in circular]] = True
        self._single_q = np.array([joint.idx_q for joint in single], dtype=np.intp)
        self._single_v = np.array([joint.idx_v for joint in single], dtype=np.intp)
        self._circle_q = np.array([joint.idx_q for joint in circular], dtype=np.intp)
        self._circle_v = np.array([joint.idx_v for joint in circular], dtype=np.intp)
        self._q = np.zeros(self.nq)

    def configuration(self, positions: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Pinocchio's configuration for `positions` (one per degree of freedom), into `out` or a buffer of this
        space (overwritten by the next call); `positions` itself when they are the same."""
        if self.identity:
            return positions
        q = self._q if out is None else out
        q[self._single_q] = positions[self._single_v]
        angles = positions[self._circle_v]
        q[self._circle_q] = np.cos(angles)
        q[self._circle_q + 1] = np.sin(angles)
        return q


class ArmDynamics:
    """Pinocchio model and data of one arm, with results written into caller-owned arrays.

    One instance is not thread-safe (it shares pinocchio's data between calls): the loop owns the
    robot's instance, other threads build their own.
    """

    def __init__(self, urdf_xml: str, joint_names: Sequence[str], tip_frame: str | None = None) -> None:
        try:
            self.model = pin.buildModelFromXML(urdf_xml)
        except (RuntimeError, ValueError) as error:
            raise ConfigError("pinocchio could not build a model from the URDF",
                              what="a URDF pinocchio can load (revolute, continuous and prismatic joints, inertials)",
                              why=str(error).strip() or type(error).__name__,
                              how="run `plem validate <package> --strict` and fix what it reports") from error
        self.data = self.model.createData()
        self.joint_names = tuple(joint_names)
        self.space = JointSpace(self.model)
        self._order = self._joint_order()
        self._identity = bool(np.array_equal(self._order, np.arange(len(self._order))))
        self._q = np.zeros(self.model.nq)
        self._positions = np.zeros(self.model.nv)
        self._v = np.zeros(self.model.nv)
        self._a = np.zeros(self.model.nv)
        self._tip_id = link_frame(self.model, tip_frame) if tip_frame else len(self.model.frames) - 1
        self.tip_frame = self.model.frames[self._tip_id].name

    def _joint_order(self) -> np.ndarray:
        """For each arm joint, its degree of freedom in pinocchio's order; a ConfigError when they do not match."""
        model = self.model
        problems = []
        order = []
        for name in self.joint_names:
            if not model.existJointName(name):
                problems.append(f"{name} is not a joint of the URDF")
                continue
            joint = model.joints[model.getJointId(name)]
            if joint.nv != 1:
                problems.append(f"{name} is a {joint.nv}-axis joint ({joint.shortname()})")
            order.append(joint.idx_v)
        if problems or model.nv != len(self.joint_names):
            if model.nv != len(self.joint_names):
                moving = ", ".join(model.names[1:])
                problems.append(f"the URDF has {model.nv} degrees of freedom ({moving}) for "
                                f"{len(self.joint_names)} arm joints")
            raise ConfigError("the URDF does not match the arm's joints",
                              what="one revolute, continuous or prismatic joint in the URDF for each joint of the "
                                   "arm, and no other moving joint",
                              why="; ".join(problems),
                              how="use the arm's description package, or pass joint names that match its URDF")
        return np.array(order, dtype=np.intp)

    @property
    def dof(self) -> int:
        """Number of arm joints."""
        return len(self.joint_names)

    def _load(self, target: np.ndarray, values: np.ndarray) -> np.ndarray:
        """`values` in pinocchio's order: passed through when the orders agree, else permuted into `target`."""
        if self._identity:
            if type(values) is np.ndarray:
                return values
            target[:] = values
        else:
            target[self._order] = values
        return target

    def _configuration(self, q: np.ndarray) -> np.ndarray:
        """Pinocchio's configuration for positions `q` in the arm's joint order (a buffer of this instance)."""
        if self.space.identity:
            return self._load(self._q, q)
        return self.space.configuration(self._load(self._positions, q), self._q)

    def _store(self, out: np.ndarray, values: np.ndarray) -> np.ndarray:
        if self._identity:
            out[:] = values
        else:
            out[:] = values[self._order]
        return out

    def gravity(self, q: np.ndarray, out: np.ndarray) -> np.ndarray:
        """Joint torques that hold the arm still against gravity at `q` (N·m)."""
        tau = pin.computeGeneralizedGravity(self.model, self.data, self._configuration(q))
        return self._store(out, tau)

    def inverse_dynamics(self, q: np.ndarray, v: np.ndarray, a: np.ndarray, out: np.ndarray) -> np.ndarray:
        """Torques that produce acceleration `a` at state (q, v), gravity included."""
        tau = pin.rnea(self.model, self.data, self._configuration(q), self._load(self._v, v), self._load(self._a, a))
        return self._store(out, tau)

    def forward_dynamics(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray, out: np.ndarray) -> np.ndarray:
        """Joint accelerations under torques `tau` at state (q, v), gravity included."""
        acc = pin.aba(self.model, self.data, self._configuration(q), self._load(self._v, v), self._load(self._a, tau))
        return self._store(out, acc)

    def inertia_diagonal(self, q: np.ndarray) -> np.ndarray:
        """Diagonal of the joint-space mass matrix at `q` (kg·m²): each joint's own inertia there."""
        diagonal = np.diag(pin.crba(self.model, self.data, self._configuration(q))).copy()
        return diagonal if self._identity else diagonal[self._order]

    def forward_kinematics(self, q: np.ndarray) -> pin.SE3:
        """Pose of the tip frame in the base frame at `q` (a copy the caller may keep)."""
        return self.frame_placement(q, self._tip_id)

    def frame_placement(self, q: np.ndarray, frame: int) -> pin.SE3:
        """Pose of frame number `frame` (a link, joint or tool frame) in the root frame at `q` (a copy)."""
        pin.framesForwardKinematics(self.model, self.data, self._configuration(q))
        return self.data.oMf[frame].copy()

    def to_model_order(self, values: Sequence[float] | np.ndarray) -> np.ndarray:
        """A new vector of positions in pinocchio's joint order (one per joint, `JointSpace`) from the arm's order."""
        q = np.empty(self.model.nv)
        q[self._order] = values
        return q

    def to_arm_order(self, q: np.ndarray) -> np.ndarray:
        """A new vector in the arm's joint order from positions in pinocchio's joint order."""
        values: np.ndarray = np.asarray(q, dtype=float)[self._order]
        return values.copy()

    @property
    def model_indices(self) -> np.ndarray:
        """For each arm joint, its index among pinocchio's degrees of freedom (`idx_v`)."""
        return self._order.copy()

    def position_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """The URDF's position range of each arm joint (joint order): -inf and inf where it has none (continuous)."""
        lower, upper = np.full(self.dof, -np.inf), np.full(self.dof, np.inf)
        model = self.model
        for k, name in enumerate(self.joint_names):
            joint = model.joints[model.getJointId(name)]
            low, high = model.lowerPositionLimit[joint.idx_q], model.upperPositionLimit[joint.idx_q]
            if joint.shortname() not in CONTINUOUS_TYPES and low < high:
                lower[k], upper[k] = low, high
        return lower, upper

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """6×dof Jacobian of the tip frame, in the world-aligned frame at the tip (columns in joint order)."""
        jac: np.ndarray = pin.computeFrameJacobian(self.model, self.data, self._configuration(q), self._tip_id,
                                       pin.LOCAL_WORLD_ALIGNED)
        return jac if self._identity else jac[:, self._order]


def compiled_model(model: pin.Model, joint_names: Sequence[str]) -> np.ndarray:
    """The compiled core's model (`compiled.MODEL`) of a pinocchio model whose joints are the arm's `joint_names`.

    Joints keep pinocchio's order (parents first) with their index in the arm's order; each must have one
    degree of freedom, turning about or sliding along one axis (revolute, continuous or prismatic). A
    continuous joint's angle is its position, where pinocchio carries its cosine and sine.
    """
    names = list(joint_names)
    problems = []
    if model.nv != len(names):
        problems.append(f"the URDF has {model.nv} degrees of freedom for {len(names)} joints")
    if len(names) > compiled.MAX_JOINTS:
        problems.append(f"the core drives at most {compiled.MAX_JOINTS} joints")
    data = model.createData()
    pin.forwardKinematics(model, data, pin.neutral(model))
    structure = compiled.new(compiled.MODEL)
    target = structure[0]
    for k, joint_id in enumerate(range(1, model.njoints)):
        name = model.names[joint_id]
        subspace = np.asarray(data.joints[joint_id].S).reshape(6, -1)
        linear, angular = np.abs(subspace[:3]).sum(), np.abs(subspace[3:]).sum()
        if name not in names or subspace.shape[1] != 1 or (linear > 0) == (angular > 0):
            kind = "not one of the arm joints" if name not in names else "not revolute, continuous or prismatic"
            problems.append(f"{name} is {kind}")
            continue
        if k >= compiled.MAX_JOINTS:
            continue
        placement, inertia = model.jointPlacements[joint_id], model.inertias[joint_id]
        target["parent"][k] = model.parents[joint_id] - 1
        target["kind"][k] = 1 if linear > 0 else 0
        target["arm_index"][k] = names.index(name)
        target["axis"][k] = subspace[:3, 0] if linear > 0 else subspace[3:, 0]
        target["rotation"][k] = np.asarray(placement.rotation).reshape(9)
        target["translation"][k] = placement.translation
        target["mass"][k] = inertia.mass
        target["com"][k] = inertia.lever
        target["inertia"][k] = np.asarray(inertia.inertia).reshape(9)
    if problems:
        raise ConfigError("the URDF does not match the arm's joints",
                          what="one revolute, continuous or prismatic joint in the URDF for each joint of the arm",
                          why="; ".join(problems),
                          how="use the arm's description package, or pass joint names that match its URDF")
    target["dof"] = len(names)
    target["gravity"] = model.gravity.linear
    return structure
