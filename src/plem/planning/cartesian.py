"""Cartesian straight-line paths: the tool moved along lines between poses, as far as the arm can follow.

Positions interpolate linearly and orientations by slerp, in steps of at most `max_step` metres (or the
same share of the rotation, at 1 rad per metre). Every step is solved by IK from the previous state and must
be collision-free, with a collision-free straight joint-space move from the previous state. The path stops
at the first step that fails, and the fraction of the way it covers is reported, as MoveIt's
compute_cartesian_path does. A jump threshold, when above 0, also stops it at a joint-space step larger
than that many times the mean step (a flip to another IK branch).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import pinocchio as pin

from plem.errors import MoveItCode, PlanningError

#: Rotation (rad) counted as one metre of travel when the step count is chosen.
RADIANS_PER_METRE = 1.0
#: Largest joint step (rad) between collision checks of the move from one Cartesian step to the next.
CHECK_STEP = 0.02
#: Most steps a request may ask for (path length over max_step), which bounds its cost.
MAX_STEPS = 100_000


def cartesian_states(start: np.ndarray, waypoints: Sequence[pin.SE3], placement: Callable[[np.ndarray], pin.SE3],
                     solve: Callable[[pin.SE3, np.ndarray], np.ndarray | None], max_step: float,
                     jump_threshold: float, is_free: Callable[[np.ndarray], bool]) -> tuple[np.ndarray, float]:
    """Joint states along the lines from the tool's pose at `start` through `waypoints`, and the fraction of the
    way covered. `placement(q)` is the tool's pose, `solve(pose, seed)` IK from a seed (None on failure)."""
    if not (max_step > 0.0 and np.isfinite(max_step)):
        raise PlanningError("max_step must be above 0", what="a step length in metres above 0 (e.g. 0.01)",
                            why=f"max_step is {max_step}", how="set max_step, e.g. 0.01",
                            code=MoveItCode.INVALID_GOAL_CONSTRAINTS)
    poses = [placement(start), *waypoints]
    lengths = [_length(a, b) for a, b in zip(poses[:-1], poses[1:], strict=True)]
    total = sum(lengths)
    counts = [max(int(np.ceil(length / max_step)), 1) for length in lengths]
    if sum(counts) > MAX_STEPS:
        raise PlanningError("the Cartesian path has too many steps", what=f"at most {MAX_STEPS} steps",
                            why=f"{total:.3f} m in steps of {max_step} m is {sum(counts)} steps",
                            how="use a larger max_step", code=MoveItCode.INVALID_GOAL_CONSTRAINTS)
    states = [start]
    covered = stepped = 0.0  # Cartesian way covered (m), joint-space way stepped (rad)
    for begin, end, length, count in zip(poses[:-1], poses[1:], lengths, counts, strict=True):
        for k in range(1, count + 1):
            q = solve(along_line(begin, end, k / count), states[-1])
            step = np.inf if q is None else float(np.linalg.norm(q - states[-1]))
            # a step over jump_threshold times the mean so far is a flip to another IK branch
            jumped = jump_threshold > 0.0 and len(states) > 1 and step > jump_threshold * stepped / (len(states) - 1)
            if q is None or jumped or not is_free(q) or not _move_free(states[-1], q, is_free):
                return np.array(states), covered / total if total > 0 else 0.0
            states.append(q)
            covered += length / count
            stepped += step
    return np.array(states), 1.0


def along_line(a: pin.SE3, b: pin.SE3, share: float) -> pin.SE3:
    """The placement `share` of the way from `a` to `b`: the position on the straight line, the orientation by slerp
    (turning about one axis at a steady rate). Not pinocchio's SE3.Interpolate, whose position follows a screw when
    the orientation turns."""
    rotation = a.rotation @ pin.exp3(share * pin.log3(a.rotation.T @ b.rotation))
    return pin.SE3(rotation, a.translation + (b.translation - a.translation) * share)


def _length(a: pin.SE3, b: pin.SE3) -> float:
    """Travel between two poses: distance plus rotation at RADIANS_PER_METRE."""
    return float(np.linalg.norm(b.translation - a.translation)
                 + np.linalg.norm(pin.log3(a.rotation.T @ b.rotation)) / RADIANS_PER_METRE)


def _move_free(a: np.ndarray, b: np.ndarray, is_free: Callable[[np.ndarray], bool]) -> bool:
    """Whether the straight joint-space move from `a` to `b` is free, checked every CHECK_STEP rad."""
    count = int(np.ceil(np.abs(b - a).max() / CHECK_STEP))
    return all(is_free(a + (b - a) * k / count) for k in range(1, count))
