"""Every way ruckig can fail to plan is a CommandRejected in words: no result code, no ruckig exception text."""

from __future__ import annotations

import pytest
from ruckig import InputParameter, Ruckig, Trajectory

from plem.control.ruckig_results import RUCKIG_MAX_DURATION_S, calculate
from plem.errors import CommandRejected


def parameters(velocity: list[float], acceleration: list[float], jerk: list[float]) -> InputParameter:
    """From rest at 0 to rest at 1 rad, for as many joints as limits are given."""
    dof = len(velocity)
    given = InputParameter(dof)
    given.current_position, given.current_velocity, given.current_acceleration = [0.0] * dof, [0.0] * dof, [0.0] * dof
    given.target_position = [1.0] * dof
    given.max_velocity, given.max_acceleration, given.max_jerk = velocity, acceleration, jerk
    return given


@pytest.mark.parametrize("limits, words", [
    # two joints synchronised over more than ruckig's longest duration: result code -101, which ruckig's
    # Python binding does not list (it raises ValueError)
    (([1e-5, 2e-5], [1e-10, 3e-10], [1e-15, 5e-15]), f"longer than ruckig's limit of {RUCKIG_MAX_DURATION_S:g} s"),
    (([1e-300], [1e-300], [1e-300]), "not usable numbers"),   # RuckigError "error in step 1"
    (([0.0], [0.0], [0.0]), "zero limit"),                    # RuckigError "zero limits conflict"
])
def test_failures_are_refusals_in_words(limits, words):
    dof = len(limits[0])
    with pytest.raises(CommandRejected) as caught:
        calculate(Ruckig(dof), parameters(*limits), Trajectory(dof), "the test motion")
    text = caught.value.render()
    assert words in caught.value.why and caught.value.how, text
    assert "Result" not in text and "-10" not in text and "[ruckig]" not in text and "inp." not in text, text


def test_a_feasible_motion_is_planned():
    trajectory = Trajectory(1)
    calculate(Ruckig(1), parameters([1.0], [1.0], [1.0]), trajectory, "the test motion")
    assert trajectory.duration > 0
