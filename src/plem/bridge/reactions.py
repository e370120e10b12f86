"""Reactions and the payload, as the in-process `Robot` and the process client `RobotClient` both offer them.

`on(condition, action)` arms a standing reaction that the core evaluates every cycle until it is removed;
`move_joints(..., until=condition)` binds one to a motion (it stops the motion, which then succeeds). The payload
changes the core's model at once (gravity in free drive, the external-torque estimate, the contact stop);
`estimate_payload()` holds a few poses and fits the mass and centre of mass from the measured efforts.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from plem.control.limits import ArmLimits
from plem.control.payload import Payload
from plem.control.reactions import Action, Condition

if TYPE_CHECKING:   # pinocchio is imported where a payload is set or estimated, not with the client
    from plem.control.kinematics import ArmDynamics


#: How long estimate_payload lets the arm settle at each pose before averaging its efforts (s), and for how long.
SETTLE_S = 0.5
AVERAGE_S = 0.3


@dataclass(frozen=True)
class ReactionHandle:
    """An armed reaction: `remove()` disarms it (a reaction that already fired once is gone)."""

    owner: ReactionCalls
    token: int

    def remove(self) -> None:
        """Disarm the reaction."""
        self.owner._remove_reaction(self.token)


class ReactionCalls:
    """Reactions and the payload; subclasses provide the requests and the arm's model."""

    # -- what a subclass provides --------------------------------------------------------------------
    def _arm_reaction(self, condition: Condition, action: Action, once: bool) -> int:
        """Arm a standing reaction; its token."""
        raise NotImplementedError

    def _remove_reaction(self, token: int) -> None:
        raise NotImplementedError

    def _send_payload(self, body: np.ndarray) -> None:
        """Give the core's model its last body (13 numbers) and wait until it took it."""
        raise NotImplementedError

    def _payload_dynamics(self) -> tuple[ArmDynamics, ArmLimits]:
        raise NotImplementedError

    def _hold_at(self, pose: np.ndarray) -> None:
        """Move to `pose` and wait until the motion ended."""
        raise NotImplementedError

    def _mean_state(self, seconds: float) -> tuple[np.ndarray, np.ndarray]:
        """Measured positions and efforts averaged over `seconds`, after the arm settled."""
        raise NotImplementedError

    # -- reactions -----------------------------------------------------------------------------------
    def on(self, condition: Condition, action: Action, once: bool = False) -> ReactionHandle:
        """Arm a standing reaction: whenever `condition` becomes true, the core starts `action` in that same cycle
        (`once`: only the first time). It stays until `remove()`d; the event log says when it fired and what it
        measured. Conditions come from `plem.control.reactions.Measure`, actions from the same module."""
        return ReactionHandle(self, self._arm_reaction(condition, action, once))

    # -- the payload ---------------------------------------------------------------------------------
    def set_payload(self, mass: float, center_of_mass: Sequence[float] = (0.0, 0.0, 0.0),
                    inertia: Sequence[Sequence[float]] | None = None) -> Payload:
        """Mount a payload at the flange (mass kg, centre of mass m in the flange link's frame, inertia kg·m² about
        it; None: a point mass). Gravity compensation, the external-torque estimate and the contact stop use it
        from the next cycle on; `set_payload(0)` removes it. Returns the checked Payload."""
        from plem.control.payload_estimation import last_body_with

        payload = Payload(mass, center_of_mass, inertia)  # type: ignore[arg-type]  # Payload checks the shapes
        dynamics, _ = self._payload_dynamics()
        self._send_payload(last_body_with(dynamics.model, payload))
        return payload

    def estimate_payload(self, apply: bool = True) -> Payload:
        """Hold five poses that turn the wrist, fit the payload's mass and centre of mass from the efforts measured
        there (the model's gravity without payload taken off), return to where the arm was, and (with `apply`) set
        it. The poses are near the start; the arm must be free to turn its wrist there."""
        from plem.control.payload_estimation import estimation_poses, fit_payload, flange_link, last_body_with

        dynamics, limits = self._payload_dynamics()
        link = flange_link(dynamics.model)
        start, _ = self._mean_state(0.0)
        samples = []
        for pose in estimation_poses(dynamics, limits, start, link):
            self._hold_at(pose)
            position, effort = self._mean_state(AVERAGE_S)
            gravity = np.zeros(limits.dof)
            dynamics.gravity(position, gravity)
            samples.append((position, effort - gravity))
        self._hold_at(start)
        payload = fit_payload(samples, dynamics, link)
        if apply:
            self._send_payload(last_body_with(dynamics.model, payload))
        return payload


def settle_then_average(read: Any, wait: Any, seconds: float, period_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Positions and efforts from `read()` (a JointState) averaged over `seconds` after SETTLE_S (none when
    `seconds` is 0), one read every `period_s`; `wait(s)` lets s seconds of the robot's time pass."""
    if seconds > 0:
        wait(SETTLE_S)
    positions, efforts = [], []
    for _ in range(max(1, round(seconds / period_s))):
        state = read()
        positions.append(state.position.copy())
        efforts.append(state.effort.copy())
        if seconds > 0:
            wait(period_s)
    return np.mean(positions, axis=0), np.mean(efforts, axis=0)
