"""JointJog messages as the bridge turns them into joint velocity samples, and the refusals of those it cannot."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from plem.control.streaming import DEFAULT_TIMEOUT_S
from plem.errors import CommandRejected
from plem.middleware.servo import JOINT_JOG, jog_velocities
from plem.middleware.types import library

JOINTS = tuple(f"joint{index}" for index in range(6))


def jog(**fields: Any) -> Any:
    return library().new(JOINT_JOG, **fields)


def test_velocities_land_on_the_named_joints_and_the_others_stay_at_rest() -> None:
    velocities, timeout = jog_velocities(jog(joint_names=["joint4", "joint1"], velocities=[0.3, -0.1]), JOINTS)
    assert velocities.tolist() == [0.0, -0.1, 0.0, 0.0, 0.3, 0.0] and timeout == DEFAULT_TIMEOUT_S


def test_displacements_over_a_duration_are_a_velocity_that_lasts_the_duration() -> None:
    velocities, timeout = jog_velocities(jog(joint_names=["joint0"], displacements=[0.2], duration=2.0), JOINTS)
    assert np.allclose(velocities, [0.1, 0, 0, 0, 0, 0]) and timeout == 2.0
    short = jog_velocities(jog(joint_names=["joint0"], displacements=[0.01], duration=0.05), JOINTS)
    assert np.allclose(short[0][0], 0.2) and short[1] == DEFAULT_TIMEOUT_S   # never shorter than a stream's timeout


def test_velocities_win_over_displacements_when_both_are_given() -> None:
    velocities, timeout = jog_velocities(jog(joint_names=["joint2"], velocities=[0.5], displacements=[3.0],
                                             duration=1.0), JOINTS)
    assert velocities[2] == 0.5 and timeout == DEFAULT_TIMEOUT_S


@pytest.mark.parametrize(("fields", "summary"), [
    ({"joint_names": ["elbow"], "velocities": [0.1]}, "names no joint of this robot once each"),
    ({"joint_names": ["joint0", "joint0"], "velocities": [0.1, 0.1]}, "names no joint of this robot once each"),
    ({"joint_names": [], "velocities": []}, "names no joint of this robot once each"),
    ({"joint_names": ["joint0", "joint1"], "velocities": [0.1]}, "velocities do not match its joint_names"),
    ({"joint_names": ["joint0"]}, "displacements do not match its joint_names"),
    ({"joint_names": ["joint0"], "displacements": [0.1]}, "needs a duration"),
    ({"joint_names": ["joint0"], "displacements": [0.1], "duration": 6.0}, "needs a duration"),
    ({"joint_names": ["joint0"], "velocities": [float("nan")]}, "are not all finite"),
])
def test_what_cannot_be_followed_is_refused_with_the_reason(fields: dict[str, Any], summary: str) -> None:
    with pytest.raises(CommandRejected, match=summary) as refused:
        jog_velocities(jog(**fields), JOINTS)
    assert refused.value.how
