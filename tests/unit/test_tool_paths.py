"""How a sequence's path is refused where it cannot be followed, on a stand-in arm whose tool sits at its first
three joint positions (so every branch of the checks can be reached on purpose)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from plem.errors import MoveItCode, PlanningError
from plem.planning.poses import Pose
from plem.planning.sequence import Joint, Linear
from plem.planning.tool_paths import Kinematics, build_path


def arm(solve=None, sigma: float = 1.0) -> Kinematics:
    """The stand-in: the tool at q[:3] with a fixed orientation; IK exact unless `solve` says otherwise."""
    def exact(target: pin.SE3, seed: np.ndarray) -> np.ndarray:
        return np.concatenate([target.translation, seed[3:]])

    return Kinematics(
        placement=lambda q: pin.SE3(np.eye(3), q[:3].copy()), solve=solve or exact,
        reachable=lambda target, seed: bool(np.linalg.norm(target.translation) < 1.0),
        joint_target=lambda item, q: np.array(item.target, dtype=float),
        in_root=lambda pose, frame, q: pin.SE3(np.eye(3), np.array(pose.position)),
        sigma=lambda q: sigma,
        describe=lambda placement: f"position {tuple(round(float(v), 3) for v in placement.translation)}",
        checkpoint=lambda: None)


START = np.array([0.3, 0.0, 0.3, 0.0, 0.0, 0.0])


def test_a_jump_between_steps_is_refused_as_a_flip_naming_the_item_and_pose() -> None:
    def flipping(target: pin.SE3, seed: np.ndarray) -> np.ndarray:
        q = np.concatenate([target.translation, seed[3:]])
        if target.translation[0] > 0.35:
            q[4] = 2.0  # the wrist on the other branch
        return q

    with pytest.raises(PlanningError) as caught:
        build_path(START, [Linear(Pose((0.3, 0.1, 0.3))), Linear(Pose((0.4, 0.1, 0.3)))], arm(flipping))
    error = caught.value
    assert error.summary == "item 1 needs a joint flip" and error.code == MoveItCode.INVALID_MOTION_PLAN
    assert "jump by 2.00 rad" in error.why and "tool pose position (0.35" in error.why


def test_a_singular_step_and_an_unreachable_pose_are_refused() -> None:
    with pytest.raises(PlanningError) as singular:
        build_path(START, [Linear(Pose((0.3, 0.1, 0.3)))], arm(sigma=0.001))
    assert singular.value.summary == "item 0 passes a singularity"
    with pytest.raises(PlanningError) as far:
        build_path(START, [Joint([0.3, 0.1, 0.3, 0, 0, 0]), Linear(Pose((2.0, 0.0, 0.0)))], arm())
    assert far.value.summary == "the pose of item 1 is outside the arm's workspace"
    assert far.value.code == MoveItCode.NO_IK_SOLUTION and "position (2.0, 0.0, 0.0)" in far.value.why
    with pytest.raises(PlanningError) as lost:
        build_path(START, [Linear(Pose((0.3, 0.1, 0.3)))], arm(solve=lambda target, seed: None))
    assert lost.value.summary == "item 0 leaves the arm's workspace" and "of the way along item 0" in lost.value.why


def test_a_blended_corner_stays_inside_its_sphere_and_is_not_a_stop() -> None:
    items = [Linear(Pose((0.3, 0.2, 0.3)), blend=0.05), Linear(Pose((0.5, 0.2, 0.3)))]
    samples = build_path(START, items, arm())
    corner = np.array([0.3, 0.2, 0.3])
    points = np.array([sample.q[:3] for sample in samples])
    near = np.linalg.norm(points - corner, axis=1)
    assert 0.0 < near.min() < 0.05  # cut, within the radius
    assert [k for k, sample in enumerate(samples) if sample.stop] == [0, len(samples) - 1]
    # off the legs only inside the sphere
    off_legs = np.minimum(np.abs(points[:, 0] - 0.3), np.abs(points[:, 1] - 0.2))
    assert np.all((off_legs < 1e-9) | (near <= 0.05 + 1e-9))
