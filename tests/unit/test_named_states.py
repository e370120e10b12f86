"""Named states as a user types them: the SRDF's spelling first, then any case when that is unambiguous; `zero`."""

from __future__ import annotations

import pytest

from plem.errors import MoveItCode, PlanningError
from plem.planning.named_states import find_state, resolve_state, with_zero


def test_zero_is_added_only_when_the_srdf_has_no_state_of_that_name() -> None:
    assert with_zero({}, 2) == {"zero": [0.0, 0.0]}  # no SRDF states: no `home` is made up
    assert with_zero({"Home": [1.0, 2.0]}, 2) == {"Home": [1.0, 2.0], "zero": [0.0, 0.0]}
    assert with_zero({"Zero": [0.5, 0.0]}, 2) == {"Zero": [0.5, 0.0]}  # the SRDF's own wins, in any case


def test_exact_names_win_then_a_single_match_ignoring_case() -> None:
    states = ["home", "Home", "HomePos", "ready"]
    assert find_state("Home", states) == "Home" and find_state("home", states) == "home"
    assert find_state("READY", states) == "ready" and find_state("homepos", states) == "HomePos"
    assert find_state("HOME", states) is None and find_state("rest", states) is None


def test_an_unknown_or_ambiguous_name_lists_the_states_there_are() -> None:
    with pytest.raises(PlanningError) as caught:
        resolve_state("home", ["HomePos", "zero"])
    error = caught.value
    assert error.code == MoveItCode.INVALID_GOAL_CONSTRAINTS and "HomePos, zero" in error.what
    assert "no state is named 'home'" in error.why and "<group_state>" in error.how
    with pytest.raises(PlanningError) as caught:
        resolve_state("home", ["Home", "HOME"])
    assert "Home, HOME differ from 'home' only in case" in caught.value.why and "exactly" in caught.value.how
