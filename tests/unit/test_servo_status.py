"""The Cartesian servo's slowing as moveit_servo's StatusCode, as the ROS servo_node/status topic carries it."""

from __future__ import annotations

import numpy as np
import pytest

from plem.bridge.cartesian_streaming import CartesianStep
from plem.middleware.servo import status_code


def step(scale: float, reason: str) -> CartesianStep:
    return CartesianStep(1, 1, np.zeros(6), 0.004, scale, reason, 0.1, 0)  # type: ignore[arg-type]


@pytest.mark.parametrize(("scale", "reason", "code"), [
    (1.0, "", 0),
    (0.6, "velocity limit", 0),   # moveit_servo has no code for it
    (0.5, "singularity", 1),      # DECELERATE_FOR_APPROACHING_SINGULARITY
    (0.001, "singularity", 2),    # HALT_FOR_SINGULARITY
    (0.3, "joint limit", 6),      # JOINT_BOUND
])
def test_each_slowing_has_moveit_servos_code(scale: float, reason: str, code: int):
    assert status_code(step(scale, reason)) == code
