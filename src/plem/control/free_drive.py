"""Free drive: the drives apply gravity compensation plus damping, so a person can guide the arm.

The torque is g(q) − D·v, clamped to each joint's effort limit, computed each cycle by the compiled core.
Damping makes the arm come to rest when the push stops, instead of drifting on with the momentum it was given.
"""

from __future__ import annotations

import numpy as np

from plem.control.kinematics import ArmDynamics
from plem.control.limits import ArmLimits

DAMPING_PER_EFFORT = 0.02  # N·m·s/rad of damping per N·m of effort limit: bigger joints, more damping
MAX_DAMPING = 10.0
STABLE_FRACTION = 0.2      # damping · cycle / inertia stays below this, so the sampled loop is stable


def default_damping(dynamics: ArmDynamics, limits: ArmLimits, cycle_time_s: float) -> np.ndarray:
    """Per-joint damping: grows with joint size, capped so light wrist joints do not oscillate.

    A damping torque computed from last cycle's velocity is stable only while D·dt/I stays well below 1,
    so each joint's damping is limited by its own inertia (at the zero pose).
    """
    effort = np.where(np.isfinite(limits.max_effort), limits.max_effort, MAX_DAMPING / DAMPING_PER_EFFORT)
    by_size = np.minimum(effort * DAMPING_PER_EFFORT, MAX_DAMPING)
    by_stability = STABLE_FRACTION * dynamics.inertia_diagonal(np.zeros(limits.dof)) / cycle_time_s
    return np.minimum(by_size, by_stability)


class FreeDriveController:
    """What free drive needs of the arm: its dynamics (the core's gravity model comes from them) and damping."""

    def __init__(self, dynamics: ArmDynamics, limits: ArmLimits, cycle_time_s: float,
                 damping: np.ndarray | None = None) -> None:
        self.dynamics = dynamics
        self.damping = (default_damping(dynamics, limits, cycle_time_s) if damping is None
                        else np.asarray(damping, dtype=float))
