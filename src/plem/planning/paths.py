"""Collision-free joint-space paths with OMPL: a planner chosen by name, a set of goal states, simplification.

OMPL objects live only inside `plan_path`: freed before it returns, so nothing of OMPL's outlives a request
(nanobind reports objects still alive at interpreter exit as leaks).
"""

from __future__ import annotations

import math
import re
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from ompl import base as ob
from ompl import geometric as og
from ompl import util as ou

from plem.errors import MoveItCode, PlanningError

#: OMPL's geometric planners plem offers, by the names MoveIt's planner_id uses.
PLANNERS: dict[str, Callable[[ob.SpaceInformation], ob.Planner]] = {
    "RRTConnect": og.RRTConnect, "RRT": og.RRT, "RRTstar": og.RRTstar, "InformedRRTstar": og.InformedRRTstar,
    "SORRTstar": og.SORRTstar, "BITstar": og.BITstar, "AORRTC": og.AORRTC, "PRM": og.PRM, "PRMstar": og.PRMstar,
    "KPIECE": og.KPIECE1, "BKPIECE": og.BKPIECE1, "LBKPIECE": og.LBKPIECE1, "FMT": og.FMT, "BFMT": og.BFMT,
}
DEFAULT_PLANNER = "RRTConnect"
#: Longest straight joint-space step (rad, largest joint) between two collision checks while planning.
CHECK_STEP = 0.02
#: Share of the remaining time path simplification may use.
SIMPLIFY_SHARE = 0.5
#: How far (rad or m) beyond the start and the goals a joint without position limits (continuous) is sampled.
UNBOUNDED_MARGIN = math.pi

ou.setLogLevel(ou.LOG_NONE)  # failures are reported as PlanningError, in plem's words


@dataclass(frozen=True)
class PathResult:
    """A collision-free path (rows are states, in the order of the joints planned for) and the planner that found it."""

    states: np.ndarray
    planner: str


def planner_name(planner_id: str) -> str:
    """The OMPL planner a MoveIt-style id names: 'RRTConnect', 'RRTConnectkConfigDefault', 'geometric::RRT', ''."""
    name = re.sub(r"kConfigDefault$", "", planner_id.strip().removeprefix("geometric::")) or DEFAULT_PLANNER
    aliases = {"KPIECE1": "KPIECE", "BKPIECE1": "BKPIECE", "LBKPIECE1": "LBKPIECE"}
    name = aliases.get(name, name)
    if name not in PLANNERS:
        raise PlanningError(f"unknown planner {planner_id!r}", what=f"one of {', '.join(PLANNERS)}",
                            why=f"{planner_id!r} is not one of OMPL's geometric planners plem offers",
                            how="choose a planner from the list (planner_id in ROS, --planner on the command line), "
                                f"or leave it empty for {DEFAULT_PLANNER}", code=MoveItCode.PLANNING_FAILED)
    return name


def plan_path(lower: np.ndarray, upper: np.ndarray, is_free: Callable[[np.ndarray], bool], start: np.ndarray,
              goals: Sequence[np.ndarray], planner_id: str = "", timeout_s: float = 5.0,
              stop: Callable[[], bool] = lambda: False) -> PathResult:
    """A path from `start` to any of `goals` through states `is_free` accepts, within [lower, upper].

    OMPL samples within finite bounds: a joint without limits (a continuous joint, unwrapped) is planned within
    `sampling_bounds`, from π below the lowest of its start and goals to π above the highest. Straight steps
    between states are checked every CHECK_STEP rad. Raises PlanningError when no path is found within
    `timeout_s` (code TIMED_OUT) or the planner gives up (PLANNING_FAILED); `stop()` ends the search early (its
    caller says why).
    """
    name = planner_name(planner_id)
    dof = len(start)
    lower, upper = sampling_bounds(lower, upper, start, goals)
    space = ob.RealVectorStateSpace(dof)
    bounds = ob.RealVectorBounds(dof)
    for i in range(dof):
        bounds.setLow(i, float(lower[i]))
        bounds.setHigh(i, float(upper[i]))
    space.setBounds(bounds)
    setup = og.SimpleSetup(space)
    buffer = np.empty(dof)

    def valid(state: ob.State) -> bool:
        for i in range(dof):
            buffer[i] = state[i]
        return is_free(buffer)

    setup.setStateValidityChecker(valid)
    information = setup.getSpaceInformation()
    information.setStateValidityCheckingResolution(CHECK_STEP / space.getMaximumExtent())
    setup.setStartState(_state(space, start))
    goal_states = ob.GoalStates(information)
    for goal in goals:
        goal_states.addState(_state(space, goal))
    setup.setGoal(goal_states)
    setup.setPlanner(PLANNERS[name](information))
    began = time.perf_counter()
    deadline = began + timeout_s
    status = setup.solve(ob.PlannerTerminationCondition(lambda: time.perf_counter() >= deadline or stop()))
    planning_time = time.perf_counter() - began
    if not setup.haveExactSolutionPath():
        code = MoveItCode.TIMED_OUT if planning_time >= timeout_s * 0.99 else MoveItCode.PLANNING_FAILED
        raise PlanningError(f"{name} found no path in {planning_time:.2f} s",
                            what="a collision-free path from the start to the goal",
                            why=f"OMPL's {name} ended with '{status}' after {planning_time:.2f} s",
                            how="allow more planning time (allowed_planning_time in ROS, --planning-time on the "
                                "command line), move obstacles away from the path, or choose another goal", code=code)
    setup.simplifySolution(max(timeout_s - planning_time, 0.0) * SIMPLIFY_SHARE or 0.001)
    path = setup.getSolutionPath()
    states = np.array([[path.getState(k)[i] for i in range(dof)] for k in range(path.getStateCount())])
    return PathResult(states, name)


def sampling_bounds(lower: np.ndarray, upper: np.ndarray, start: np.ndarray, goals: Sequence[np.ndarray]
                    ) -> tuple[np.ndarray, np.ndarray]:
    """[lower, upper] with each infinite bound replaced by UNBOUNDED_MARGIN beyond the start and every goal."""
    states = np.vstack([start, *goals])
    low = np.where(np.isfinite(lower), lower, states.min(axis=0) - UNBOUNDED_MARGIN)
    high = np.where(np.isfinite(upper), upper, states.max(axis=0) + UNBOUNDED_MARGIN)
    return low, high


def _state(space: ob.RealVectorStateSpace, values: np.ndarray) -> ob.State:
    state = space.allocState()
    for i, value in enumerate(values):
        state[i] = float(value)
    return state
