"""The ranges of the ROS parameters a description package sets for plem: the controller manager's update rate
and kinematics.yaml's solver settings, with the defaults plem uses when a package leaves them out."""

from __future__ import annotations

import math
from typing import Any

from plem.errors import ConfigError
from plem.ipc.request_bounds import truncated
from plem.robot.config import CYCLE_TIME_RANGE_US

#: kinematics.yaml's per-group settings when a package gives none (MoveIt's KDL defaults, attempts as in MoveIt 1).
SOLVER_DEFAULTS = {"kinematics_solver_search_resolution": 0.005, "kinematics_solver_timeout": 0.05,
                   "kinematics_solver_attempts": 3}
#: The range each of them may take (low excluded, high included) and its unit; attempts are whole numbers.
KINEMATICS_RANGES = {"kinematics_solver_timeout": (0.0, 10.0, "s"),
                     "kinematics_solver_search_resolution": (0.0, 1.0, "rad"),
                     "kinematics_solver_attempts": (0.0, 1000.0, "")}
#: The largest controller manager rate (Hz) a package may give: one update a microsecond. A rate above the loop's
#: (at most 1 / 250 µs = 4000 Hz) runs at the loop's rate, with a warning; one above this is no rate at all.
MAX_UPDATE_RATE = 1_000_000


def update_rate_error(value: Any, source: str | None = None) -> ConfigError | None:
    """Why controller_manager's `update_rate` (as read from `source`, when the message is to name it) is unusable,
    or None: a number of at least 1 and at most MAX_UPDATE_RATE Hz."""
    number = isinstance(value, int | float) and not isinstance(value, bool)
    if number and 1 <= value <= MAX_UPDATE_RATE:
        return None
    where = f"{source}: " if source else ""
    note = " (not a finite number)" if number and not math.isfinite(value) else ""
    return ConfigError(
        "controllers.yaml has an unusable update_rate",
        what=f"controller_manager.ros__parameters.update_rate: a number of Hz from 1 to {MAX_UPDATE_RATE:,} (the "
             f"loop runs at most at {1_000_000 // CYCLE_TIME_RANGE_US[0]} Hz, cycle_time {CYCLE_TIME_RANGE_US[0]} µs)",
        why=f"{where}update_rate is {truncated(repr(value), 80)}{note}",
        how=f"set update_rate to the loop's rate (1000 for cycle_time 1000 µs) in {source or 'controllers.yaml'}, "
            "or remove it to use the loop's rate")


def kinematics_value_problem(key: str, value: Any) -> str | None:
    """What range `value` of kinematics.yaml's `key` (one of KINEMATICS_RANGES) must be in, or None when it is."""
    low, high, unit = KINEMATICS_RANGES[key]
    whole = key == "kinematics_solver_attempts"
    kinds = (int,) if whole else (int, float)
    if not isinstance(value, bool) and isinstance(value, kinds) and low < value <= high:
        return None
    return (f"a whole number from 1 to {high:g}" if whole
            else f"a number above {low:g} and at most {high:g} {unit}")
