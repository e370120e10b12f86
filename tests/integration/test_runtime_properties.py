"""Properties of the runtime: whatever targets and preemptions arrive, no command leaves the joint limits."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from plem.control.events import EventKind
from plem.control.modes import Mode
from plem.errors import CommandRejected

from .robot_fixtures import Trace, assert_within_limits, simulated_robot

angles = st.floats(min_value=-3.3, max_value=3.3, allow_nan=False)
targets = st.lists(angles, min_size=6, max_size=6)
scales = st.floats(min_value=0.3, max_value=1.0)


@pytest.fixture(scope="module")
def robot():
    robot = simulated_robot()
    robot.set_mode("hold")
    yield robot
    robot.shutdown()


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(first=targets, second=targets, scale=scales, preempt_after=st.integers(min_value=1, max_value=1500))
def test_random_targets_and_preemptions_stay_within_limits(robot, first, second, scale, preempt_after):
    trace = Trace.attach(robot)
    handles = []
    for target, cycles in ((first, preempt_after), (second, 30_000)):
        try:
            handles.append(robot.move_joints(target, speed_scale=scale))
        except CommandRejected as error:
            assert np.any(np.abs(target) > 3.054326191) and "position limits" in error.summary
            continue
        for _ in range(cycles):
            robot.step()
            if handles[-1].done:
                break
    robot.wait_until_idle(60)
    if trace.command:
        assert_within_limits(robot, trace.commands())
    assert not robot.events.recent({EventKind.FAULT}), robot.fault_reason
    assert robot.mode is Mode.HOLD
