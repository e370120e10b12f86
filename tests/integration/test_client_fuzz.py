"""Fuzzing the Python client's public signatures against a real RT driver and command service of its own.

Every call either works or raises a PlemError, and returns within a deadline. The arguments are drawn from each
parameter's type hint (hypothesis `from_type`) and from values of other types; the arm may move, and the loop
keeps it inside every limit: after every call, no limit fault has happened and the command is inside the range.
"""

from __future__ import annotations

import concurrent.futures
import inspect
import itertools
import math
import typing
import uuid
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from plem.bridge import connect
from plem.bridge.client import RemoteHandle, RobotClient, Stream
from plem.control.events import EventKind
from plem.control.modes import Mode
from plem.control.trajectory import JointTrajectory, TrajectoryPoint, TrajectoryTolerances
from plem.errors import PlemError
from plem.launch.plan import plan_robot
from plem.launch.rt_driver import driving

#: The client's own methods fuzzed here (the planner's calls have a process and tests of their own).
METHODS = ("state", "live_state", "wait_for_state", "stream", "events", "faults", "last_fault", "stats",
           "move_joints", "execute_trajectory", "set_mode", "request_mode", "reset_fault", "request_reset", "stop",
           "wait_until_idle")
#: Longest a call may take: the longest wait a drawn timeout allows, plus acceptance of a motion (5 s).
DEADLINE_S = 20.0
#: Faults that would mean a command moved the arm past a limit.
LIMIT_CAUSES = {"position_limit", "velocity_limit", "command_position", "command_velocity", "command_acceleration",
                "command_jerk"}

#: Values of every other kind: what a script passes by mistake.
OTHER = st.one_of(
    st.none(), st.booleans(), st.integers(), st.just(10**400), st.floats(), st.text(max_size=8), st.binary(max_size=8),
    st.lists(st.floats(), max_size=8), st.dictionaries(st.text(max_size=4), st.floats(), max_size=3),
    st.builds(object))
#: What a script passes by mistake for a wait (timeout, duration): anything but a long wait, which is no mistake.
OTHER_THAN_A_WAIT = OTHER.filter(lambda value: not (isinstance(value, (int, float)) and not isinstance(value, bool)
                                                    and 1.0 < value < math.inf))
#: Waits drawn short, so that a call that works returns within the deadline.
SECONDS = st.one_of(st.floats(min_value=-1.0, max_value=0.3), st.sampled_from([math.nan, math.inf, -math.inf, 0.0]))
JOINT_VALUES = st.lists(st.floats(min_value=-1.0, max_value=1.0), min_size=6, max_size=6)


WAITS = ("timeout", "duration")


def trajectories(joint_names: tuple[str, ...]) -> st.SearchStrategy[Any]:
    """Trajectories of the arm's joints, and JointTrajectory as its type hint gives it."""
    rows = st.lists(st.fixed_dictionaries({"positions": JOINT_VALUES,
                                           "time_from_start": st.floats(min_value=0.0, max_value=3.0)}),
                    min_size=1, max_size=4).map(lambda points: sorted(points, key=lambda p: p["time_from_start"]))
    return st.one_of(rows.map(lambda points: JointTrajectory.from_lists(joint_names, points)),
                     st.builds(JointTrajectory, st.lists(st.text(max_size=6), max_size=7).map(tuple),
                               st.lists(st.builds(TrajectoryPoint, st.lists(st.floats(), max_size=7).map(tuple),
                                                  st.floats()), max_size=3).map(tuple)))


def strategies(client: RobotClient) -> dict[str, st.SearchStrategy[Any]]:
    """Strategies for parameters whose type hint alone would rarely give a call that works."""
    return {
        "timeout": SECONDS | st.none(), "duration": SECONDS | st.none(), "after_cycle": st.integers(),
        "target": JOINT_VALUES | st.from_type(typing.Sequence[float]),
        "speed_scale": st.floats(min_value=1e-3, max_value=1.0) | st.floats(),
        "tolerances": st.one_of(st.none(), st.builds(TrajectoryTolerances, goal=st.none() | st.lists(
            st.floats(min_value=0.0, max_value=1.0), min_size=6, max_size=6)),
            st.dictionaries(st.sampled_from(["path", "goal", "goal_time", "gaol"]), JOINT_VALUES | st.floats())),
        "trajectory": trajectories(client.joint_names),
        "mode": st.sampled_from(["hold", "idle", "free_drive", "trajectory", "fault"]) | st.from_type(Mode),
    }


def arguments(client: RobotClient, name: str) -> st.SearchStrategy[dict[str, Any]]:
    """Keyword arguments for one method: each parameter from its type hint (or the override above), or any other
    value, or left out when it has a default."""
    method = getattr(client, name)
    hints = typing.get_type_hints(method)
    chosen = strategies(client)
    drawn: dict[str, st.SearchStrategy[Any]] = {}
    for parameter in inspect.signature(method).parameters.values():
        typed = chosen[parameter.name] if parameter.name in chosen else st.from_type(hints[parameter.name])
        drawn[parameter.name] = st.one_of(typed, typed, OTHER_THAN_A_WAIT if parameter.name in WAITS else OTHER)
    optional = [p.name for p in inspect.signature(method).parameters.values() if p.default is not p.empty]
    return st.fixed_dictionaries(drawn).flatmap(lambda given: st.sets(st.sampled_from(optional) if optional
                                                                      else st.nothing()).map(
        lambda left_out: {key: value for key, value in given.items() if key not in left_out}))


@pytest.fixture(scope="module")
def client() -> Iterator[RobotClient]:
    """A simulated arm of its own, served by a real RT driver and command service, holding."""
    robot_id = f"fuzz_{uuid.uuid4().hex[:8]}"
    with driving(plan_robot({"bus": "mock", "robot_id": robot_id}, generate=False)), connect(robot_id) as connected:
        connected.set_mode("hold")
        yield connected


def finished_within_deadline(call: Callable[[], Any]) -> Any:
    """The call's result; it must neither hang nor raise anything but a PlemError."""
    with concurrent.futures.ThreadPoolExecutor(1) as pool:
        future = pool.submit(call)
        try:
            return future.result(DEADLINE_S)
        except concurrent.futures.TimeoutError:
            pytest.fail(f"the call did not return within {DEADLINE_S:g} s")
        except PlemError:
            event("refused with a PlemError")
            return None


def use(result: Any, given: dict[str, Any]) -> None:
    """Read a little of what a call returned: a stream with a limit to its end, a handle's answer."""
    if isinstance(result, Stream) and (given.get("timeout") is not None or given.get("duration") is not None):
        list(itertools.islice(result, 5))
    elif isinstance(result, RemoteHandle):
        result.wait(DEADLINE_S / 2)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(data=st.data(), name=st.sampled_from(METHODS))
def test_every_call_works_or_raises_a_plem_error_and_returns(client, data, name):
    given_arguments = data.draw(arguments(client, name), label=name)
    result = finished_within_deadline(lambda: getattr(client, name)(**given_arguments))
    if result is not None:
        event(f"{name} worked")
    finished_within_deadline(lambda: use(result, given_arguments))
    limit_faults = [event.describe() for event in client.faults()
                     if event.kind is EventKind.FAULT and event.cause in LIMIT_CAUSES]
    assert not limit_faults, limit_faults
    state = client.live_state()
    assert np.all(client.limits.min_position <= state.command_position)
    assert np.all(state.command_position <= client.limits.max_position)
    if state.faulted:
        finished_within_deadline(client.reset_fault)
    elif state.mode is Mode.TRAJECTORY:
        finished_within_deadline(lambda: client.stop().wait(DEADLINE_S / 2))
