"""Inverse kinematics of one planning group: Levenberg-Marquardt on pinocchio, with random restarts.

The given seed is tried first, so when it converges the solution is the one nearest the robot's state (what
MoveIt's users expect); then uniformly random seeds within the limits, until the time is up. Speed comes from
few Python calls per iteration: one pass of pinocchio for the pose and the Jacobian, a 6×6 (3×3 for a position)
damped normal system solved by Cholesky.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import eigenpy
import numpy as np
import pinocchio as pin

from plem.control.kinematics import CONTINUOUS_TYPES, JointSpace, has_link, link_frame
from plem.errors import MoveItCode, PlanningError

#: Iterations one seed may take before the next seed is tried (seeds that converge almost all do so within 30).
SEED_ITERATIONS = 40
#: Damping of the first step from a seed (m² and rad², added to the diagonal of J Jᵀ) ...
DAMPING = 1e-2
#: ... its floor, and the damping at which a seed is given up (the error grows whatever the step).
DAMPING_MIN = 1e-9
DAMPING_MAX = 1.0
#: Damping factor after a step that lowers the error, and after one that does not (the step is then retried).
DAMPING_DOWN = 0.5
DAMPING_UP = 10.0
#: Longest step in joint space (norm over the joints, rad or m); longer steps are shortened to it.
MAX_STEP = 1.5
#: A seed is given up when lowering steps in a row each keep more than STALL_RATIO of the squared error: this many
#: for a random seed, more for the given one (its solution is the one wanted, nearest the robot's state).
STALL_STEPS = 2
STALL_STEPS_GIVEN = 4
STALL_RATIO = 0.9
#: Squared twist, relative to the squared tolerances, below which a configuration's errors are worked out exactly.
NEAR_FACTOR = 2.0
#: Largest deviation of the target's rotation matrix from orthonormal.
ROTATION_TOLERANCE = 1e-6
TURN = 2 * math.pi
#: Joint types of pinocchio whose position is an angle, so that a whole turn gives the same pose.
REVOLUTE_TYPES = frozenset({"JointModelRX", "JointModelRY", "JointModelRZ", "JointModelRevoluteUnaligned",
                            *CONTINUOUS_TYPES})


class IkInputError(PlanningError):
    """An IK target, seed or group the solver cannot work with (NaN, wrong size, unknown frame)."""


@dataclass(frozen=True)
class IkResult:
    """The configuration IK found (or the best one tried), whether it reaches the target, and its residual.

    `positions` holds every joint's position in pinocchio's joint order (`JointSpace`); when `success` is false
    it is the one nearest the target of those tried (one that reaches the target but that `accept` refused counts too).
    """

    positions: np.ndarray
    success: bool
    attempts: int
    position_error: float
    orientation_error: float


def _pose_errors(offset: pin.SE3, position_only: bool) -> tuple[float, float]:
    """The distance (m) and the rotation angle (rad, 0 when position_only) an offset between two frames makes."""
    translation = offset.translation
    if position_only:
        return math.sqrt(translation.dot(translation)), 0.0
    rotation = pin.log3(offset.rotation)
    return math.sqrt(translation.dot(translation)), math.sqrt(rotation.dot(rotation))


def _damped_step(jacobian: np.ndarray, error: np.ndarray, damping: float, cholesky: eigenpy.LLT) -> np.ndarray:
    """The damped least-squares step Jᵀ (J Jᵀ + λI)⁻¹ e, shortened to MAX_STEP."""
    normal = jacobian.dot(jacobian.T)
    normal.ravel()[:: len(normal) + 1] += damping  # the diagonal, as a view (cheaper than .flat)
    cholesky.compute(normal)
    step: np.ndarray = cholesky.solve(error).dot(jacobian)
    size2 = step.dot(step)
    if size2 > MAX_STEP * MAX_STEP:
        step *= MAX_STEP / math.sqrt(size2)
    return step


class IkSolver:
    """Numerical IK of one group's joints for the pose of one frame.

    Positions, seeds, `joints` (indices of the group's joints among them) and limits are one number per joint in
    pinocchio's joint order (`JointSpace`): a continuous joint is an angle with infinite limits, and its solution
    is the equivalent angle nearest the seed.
    Not thread-safe: it owns pinocchio data and solver buffers; each thread builds its own.
    """

    def __init__(self, model: pin.Model, joints: Sequence[int], tip_frame: str,
                 lower: np.ndarray, upper: np.ndarray) -> None:
        if not has_link(model, tip_frame):
            raise IkInputError(f"the model has no frame {tip_frame!r}", what="the tip link of the planning group",
                               why=f"{tip_frame!r} is not a link or frame of the URDF",
                               how="set the group's tip link in the SRDF to a link of the URDF",
                               code=MoveItCode.INVALID_LINK_NAME)
        self._model = model
        self._data = model.createData()
        self._tip = link_frame(model, tip_frame)
        self._space = JointSpace(model)
        if self._space.multi_axis:
            raise IkInputError("IK moves single-axis joints only",
                               what="a model of revolute, continuous, prismatic and fixed joints",
                               why=f"the model has multi-axis joints: {', '.join(self._space.multi_axis)}",
                               how="describe the arm without floating or planar joints in the URDF",
                               code=MoveItCode.INVALID_GROUP_NAME)
        self._indices, revolute = _group_joints(model, [int(index) for index in joints])
        self._whole = bool(model.nv == len(self._indices) and np.array_equal(self._indices, np.arange(model.nv)))
        lower, upper = np.array(lower, dtype=float), np.array(upper, dtype=float)
        if lower.shape != (model.nv,) or upper.shape != (model.nv,) or not bool(np.all(lower <= upper)):
            raise IkInputError("the joint limits do not fit the model",
                               what=f"{model.nv} lower and upper position limits, lower <= upper",
                               why=f"lower {lower.tolist()}, upper {upper.tolist()}",
                               how="give every joint of the group lower <= upper in the URDF or joint_limits.yaml",
                               code=MoveItCode.INVALID_ROBOT_STATE)
        self._lower, self._upper = lower[self._indices], upper[self._indices]
        finite = np.isfinite(self._lower) & np.isfinite(self._upper)
        # A whole turn is taken off revolute joints that step past a finite limit, where the result is inside.
        self._wrap_turn = np.where(revolute & finite, TURN, 0.0)
        self._wrap_base = np.where(finite, self._lower, 0.0)
        self._wrap_all = bool(np.all(self._wrap_turn))
        # Joints with more than a turn of range may end on the equivalent angle nearest the seed.
        self._turnable = revolute & (self._upper - self._lower > TURN)
        # Random seeds span the limits, or a turn where a limit is infinite.
        self._sample_low = np.where(np.isfinite(self._lower), self._lower,
                                    np.where(np.isfinite(self._upper), self._upper - TURN, -math.pi))
        self._sample_high = np.where(np.isfinite(self._upper), self._upper, self._sample_low + TURN)
        self._buffer = np.zeros(model.nv)
        self._cholesky = {3: eigenpy.LLT(3), 6: eigenpy.LLT(6)}
        self._rng = np.random.default_rng()

    def solve(self, target: pin.SE3, seed: np.ndarray, *, timeout_s: float = 0.005,
              position_only: bool = False, accept: Callable[[np.ndarray], bool] | None = None,
              rng: np.random.Generator | None = None, stop: Callable[[], bool] | None = None,
              position_tolerance: float = 1e-5, orientation_tolerance: float = 1e-5) -> IkResult:
        """A configuration putting the tip frame at `target` (world frame), searched from `seed`, then random seeds.

        `accept(q)` may refuse a solution (a collision check, say); the search then goes on. `stop()`, asked between
        seeds, ends the search early (a cancelled request). Errors are in m and rad.
        """
        deadline = time.perf_counter() + timeout_s
        _check_budget(timeout_s, position_tolerance, orientation_tolerance)
        start = self._checked_seed(target, seed)
        rng = rng or self._rng
        origin = np.minimum(np.maximum(start[self._indices], self._lower), self._upper)
        self._buffer[:] = start  # the joints outside the group keep the seed's values
        x = origin
        attempts = 0
        best_cost = math.inf
        best = (start, math.inf, math.inf)
        success = False
        while not success:
            attempts += 1
            x, position_error, orientation_error, converged = self._descend(
                x, target, deadline, position_tolerance, orientation_tolerance, position_only,
                STALL_STEPS_GIVEN if attempts == 1 else STALL_STEPS)
            full = start.copy()
            full[self._indices] = self._nearest_turn(x, origin) if converged else x
            success = converged and (accept is None or bool(accept(full)))
            cost = position_error**2 + orientation_error**2
            if cost < best_cost:
                best_cost, best = cost, (full, position_error, orientation_error)
            if time.perf_counter() >= deadline or (stop is not None and stop()):
                break
            x = rng.uniform(self._sample_low, self._sample_high)
        positions, position_error, orientation_error = (full, position_error, orientation_error) if success else best
        return IkResult(positions, success, attempts, position_error, orientation_error)

    def _checked_seed(self, target: pin.SE3, seed: np.ndarray) -> np.ndarray:
        """The seed as a new float vector; raises when the target or the seed cannot be solved for."""
        pose = target.homogeneous
        if not np.all(np.isfinite(pose)):
            raise IkInputError("the IK target pose has NaN or infinite values",
                               what="a pose with a finite position (m) and orientation",
                               why=f"the pose's matrix is {pose.tolist()}",
                               how="send a goal pose with finite numbers: a position in m and a unit quaternion",
                               code=MoveItCode.INVALID_GOAL_CONSTRAINTS)
        rotation = target.rotation
        if np.abs(rotation.T.dot(rotation) - np.eye(3)).max() > ROTATION_TOLERANCE:
            raise IkInputError("the IK target orientation is not a rotation",
                               what="an orthonormal rotation (from a unit quaternion)",
                               why=f"the rotation matrix is {rotation.tolist()}",
                               how="normalise the goal pose's orientation quaternion to length 1",
                               code=MoveItCode.INVALID_GOAL_CONSTRAINTS)
        values = np.array(seed, dtype=float)
        if values.shape != (self._model.nv,) or not np.all(np.isfinite(values)):
            raise IkInputError("the IK seed state does not fit the arm",
                               what=f"{self._model.nv} finite joint positions (rad or m)",
                               why=f"the seed is {values.tolist()}",
                               how="send a start or seed robot state with a finite position for every joint",
                               code=MoveItCode.INVALID_ROBOT_STATE)
        return values

    def _nearest_turn(self, x: np.ndarray, origin: np.ndarray) -> np.ndarray:
        """`x` with whole turns added to the joints of more than a turn of range: nearest the seed, inside limits."""
        if not self._turnable.any():
            return x
        moved = x + np.round((origin - x) / TURN) * TURN
        moved = np.where(moved > self._upper, moved - TURN, moved)
        moved = np.where(moved < self._lower, moved + TURN, moved)
        return np.where(self._turnable, moved, x)

    def _descend(self, x: np.ndarray, target: pin.SE3, deadline: float, position_tolerance: float,
                 orientation_tolerance: float, position_only: bool, stall_steps: int
                 ) -> tuple[np.ndarray, float, float, bool]:
        """Levenberg-Marquardt from one seed: the best configuration reached, its errors, whether it converged.

        The error is the twist from the tip to the target in the tip's frame (pose's log), or the translation only,
        against the tip's Jacobian in its own frame.
        """
        model, data, tip, local = self._model, self._data, self._tip, pin.LOCAL
        joint_jacobians, frame_placement, frame_jacobian, log6 = (
            pin.computeJointJacobians, pin.updateFramePlacement, pin.getFrameJacobian, pin.log6)
        count_nonzero, clock = np.count_nonzero, time.perf_counter
        lower, upper, whole, buffer, indices, configuration = (
            self._lower, self._upper, self._whole, self._buffer, self._indices, self._space.configuration)
        cholesky = self._cholesky[3 if position_only else 6]
        # Below this squared twist the errors are worked out exactly (the twist's norm is within a factor of them).
        near = NEAR_FACTOR * (position_tolerance**2 + (0.0 if position_only else orientation_tolerance**2))
        damping = DAMPING
        stalls = 0
        best_cost = math.inf
        best_x = best_jacobian = best_error = x
        best_offset = target
        for _ in range(SEED_ITERATIONS):
            if whole:
                q = x
            else:
                buffer[indices] = x
                q = buffer
            joint_jacobians(model, data, configuration(q))
            offset = frame_placement(model, data, tip).actInv(target)
            jacobian = frame_jacobian(model, data, tip, local)
            if not whole:
                jacobian = jacobian[:, indices]
            if position_only:
                error = offset.translation
                jacobian = jacobian[:3]
            else:
                error = log6(offset).vector
            cost = error.dot(error)
            if cost <= near:
                position_error, orientation_error = _pose_errors(offset, position_only)
                if position_error <= position_tolerance and orientation_error <= orientation_tolerance:
                    return x, position_error, orientation_error, True
            if cost < best_cost:
                stalls = stalls + 1 if cost > STALL_RATIO * best_cost else 0
                if stalls >= stall_steps:
                    break
                best_cost, best_offset, best_x, best_jacobian, best_error = cost, offset, x, jacobian, error
                damping = max(damping * DAMPING_DOWN, DAMPING_MIN)
            else:
                damping *= DAMPING_UP
                if damping > DAMPING_MAX:
                    break
                x, jacobian, error = best_x, best_jacobian, best_error
            moved = x + _damped_step(jacobian, error, damping, cholesky)
            if count_nonzero((moved < lower) | (moved > upper)):
                moved = self._into_limits(x, moved, jacobian, error, damping, cholesky)
            x = moved
            if clock() >= deadline:
                break
        return (best_x, *_pose_errors(best_offset, position_only), False)

    def _into_limits(self, x: np.ndarray, moved: np.ndarray, jacobian: np.ndarray, error: np.ndarray,
                     damping: float, cholesky: eigenpy.LLT) -> np.ndarray:
        """The end of a step from `x` that left the limits, brought back inside them.

        A revolute joint takes the same angle a turn off where that is inside. A joint still outside stops at its
        limit, and the step of the others is solved again to make up for it.
        """
        lower, upper = self._lower, self._upper
        wrapped = self._wrapped(moved)
        blocked = (wrapped < lower) | (wrapped > upper)
        if not np.count_nonzero(blocked):
            return wrapped
        fixed = (np.minimum(np.maximum(moved, lower), upper) - x) * blocked
        step = _damped_step(jacobian * ~blocked, error - jacobian.dot(fixed), damping, cholesky)
        inside: np.ndarray = np.minimum(np.maximum(self._wrapped(x + fixed + step), lower), upper)
        return inside

    def _wrapped(self, moved: np.ndarray) -> np.ndarray:
        """Revolute joints with finite limits taken into [lower, lower + 2π) by whole turns; others unchanged."""
        if self._wrap_all:
            wrapped: np.ndarray = np.mod(moved - self._lower, TURN) + self._lower
            return wrapped
        mixed: np.ndarray = moved - np.floor((moved - self._wrap_base) * (1 / TURN)) * self._wrap_turn
        return mixed


def _check_budget(timeout_s: float, position_tolerance: float, orientation_tolerance: float) -> None:
    """Raises unless the timeout is finite and not negative and the tolerances are positive (a NaN never ends)."""
    if not (0.0 <= timeout_s < math.inf and 0.0 < position_tolerance < math.inf
            and 0.0 < orientation_tolerance < math.inf):
        raise IkInputError("the IK timeout or tolerances are out of range",
                           what="a finite timeout >= 0 s and tolerances > 0 (m, rad)",
                           why=f"timeout {timeout_s} s, position tolerance {position_tolerance} m, "
                               f"orientation tolerance {orientation_tolerance} rad",
                           how="set kinematics_solver_timeout in kinematics.yaml (or the request's timeout) to a "
                               "positive number of seconds, and the goal tolerances to positive numbers",
                           code=MoveItCode.INVALID_GOAL_CONSTRAINTS)


def _group_joints(model: pin.Model, indices: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """The group's position indices (each also its Jacobian column), and which of them are revolute or continuous."""
    owners = {joint.idx_v: joint for joint in list(model.joints)[1:]}
    revolute = []
    for index in indices:
        joint = owners.get(index)
        if joint is None:
            raise IkInputError("the planning group names a joint the model does not have",
                               what=f"joint position indices from 0 to {model.nv - 1}",
                               why=f"index {index} is not a joint of the model",
                               how="plan for a group of the SRDF whose joints are in the URDF",
                               code=MoveItCode.INVALID_GROUP_NAME)
        revolute.append(joint.shortname() in REVOLUTE_TYPES)
    return np.array(indices, dtype=np.intp), np.array(revolute, dtype=bool)
