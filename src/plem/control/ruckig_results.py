"""ruckig's results in words: every way a jerk-limited plan can fail, as a CommandRejected that names the fix.

ruckig answers with a numeric result (its Python binding turns a code it does not list into a ValueError) or
raises RuckigError on input it cannot use; a user sees neither, only what went wrong and what to change.
"""

from __future__ import annotations

import re
from typing import Any

from ruckig import Result, RuckigError

from plem.errors import CommandRejected

#: The longest motion ruckig plans (s): its numerical limit, ErrorTrajectoryDuration beyond it.
RUCKIG_MAX_DURATION_S = 7.6e3
_LIMITS_FILE = "config/joint_limits.yaml of the description package"
#: ruckig's result codes (ruckig/result.hpp), with what each means and how to avoid it.
_RESULTS: dict[int, tuple[str, str]] = {
    -1: ("ruckig could not plan the motion", f"check the target and the limits in {_LIMITS_FILE}"),
    -100: ("the start, target or limits are not usable numbers (zero, negative or too small limits)",
           f"use a larger speed_scale, and positive limits in {_LIMITS_FILE}"),
    -101: (f"the motion would last longer than ruckig's limit of {RUCKIG_MAX_DURATION_S:g} s",
           "use a larger speed_scale, or split the motion into shorter ones"),
    -102: ("the motion would pass a position limit", "choose a target inside every joint's range"),
    -104: ("a zero limit leaves no way to reach the target", f"give every joint positive limits in {_LIMITS_FILE}"),
    -110: ("no time-optimal profile was found for some joint (the limits are too far apart in scale)",
           "use a larger speed_scale, or check the limits for values orders of magnitude apart"),
    -111: ("the joints could not be synchronised to one duration",
           "use a larger speed_scale, or move fewer joints at once"),
}
_UNLISTED = re.compile(r"(-?\d+) is not a valid Result")


def calculate(planner: Any, parameters: Any, trajectory: Any, what: str) -> None:
    """Run ruckig's `planner.calculate(parameters, trajectory)`; any result but success is a CommandRejected.

    The arguments are ruckig objects (its binding ships no types).
    """
    try:
        result = planner.calculate(parameters, trajectory)
    except RuckigError as error:
        raise _refusal(-104 if "zero limits" in str(error) else -100, what) from None
    except ValueError as error:   # a result code the binding does not list
        unlisted = _UNLISTED.search(str(error))
        if unlisted is None:
            raise
        raise _refusal(int(unlisted.group(1)), what) from None
    if result not in (Result.Working, Result.Finished):
        raise _refusal(int(result), what)


def _refusal(code: int, what: str) -> CommandRejected:
    why, how = _RESULTS.get(code, _RESULTS[-1])
    return CommandRejected(f"{what} could not be planned within the joint limits",
                           what="a jerk-limited motion inside the velocity, acceleration and jerk limits",
                           why=why, how=how)
