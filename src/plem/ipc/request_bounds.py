"""The sizes and ranges every command is held to before any work is done on it.

Commands arrive from scripts, the CLI, ROS 2 topics and actions; all of them end up as one JSON request
to the robot's command service, which checks these bounds first. The numbers are generous for real
use (MoveIt sends tens to hundreds of points) and small enough that checking, planning and answering one
request takes bounded time.
"""

from __future__ import annotations

import math
import re
from typing import Any

from plem.errors import CommandRejected

#: Bytes of one encoded request (a 5000-point, 7-joint trajectory with velocities and accelerations
#: takes about 2.5 MB as JSON).
MAX_REQUEST_BYTES = 4 << 20
#: Points of one trajectory.
MAX_POINTS = 5000
#: Joints of one arm.
MAX_JOINTS = 16
#: Characters of a joint name.
MAX_NAME_CHARS = 128
#: Characters of a request id: letters, digits and `_.:-`.
MAX_ID_CHARS = 64
#: Seconds a trajectory may last, and the longest goal time tolerance.
MAX_SECONDS = 86_400.0
#: Largest magnitude of a velocity, acceleration or tolerance value; positions are bounded by the limits.
MAX_MAGNITUDE = 1e6
#: Characters of each text field (summary, what, why, how) of an answer.
MAX_TEXT_CHARS = 2000
#: Slowest speed_scale (of move_joints, `plem move --speed-scale` and the planner's velocity and acceleration
#: scaling): a motion then takes 1000 times as long as at full speed. Slower ones would outlast the longest
#: motion ruckig plans (7600 s) for an ordinary arm's range, and no real use needs them.
MIN_SPEED_SCALE = 1e-3

_ID = re.compile(rf"[A-Za-z0-9_.:-]{{1,{MAX_ID_CHARS}}}")


def shown(value: Any, limit: int = 200) -> str:
    """`repr(value)` cut to `limit` characters, for messages about input of any size."""
    text = repr(value) if not isinstance(value, str) else value
    return truncated(text, limit)


def truncated(text: str, limit: int = MAX_TEXT_CHARS) -> str:
    """`text` unchanged when short enough, else cut with a marker saying how much was left out."""
    if len(text) <= limit:
        return text
    marker = f" … [{len(text) - limit} more characters]"
    return text[:max(limit - len(marker), 0)] + marker


def number(value: Any, what: str, low: float, high: float, *, low_open: bool = False) -> float:
    """`value` as a float if it is a real number (not a bool, not a string) in [low, high] (or (low, high])."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise CommandRejected(f"{what} is not a number", what=f"{what} as a number",
                              why=f"got {shown(value)} ({type(value).__name__})", how=f"send {what} as a plain number")
    if isinstance(value, int) and not -1e300 < value < 1e300:
        value = math.inf if value > 0 else -math.inf
    result = float(value)
    below = result <= low if low_open else result < low
    if not math.isfinite(result) or below or result > high:
        interval = f"{'(' if low_open else '['}{low:g}, {high:g}]"
        raise CommandRejected(f"{what} is out of range", what=f"a finite number in {interval}",
                              why=f"{what} = {result:g}", how=f"send {what} within {interval}")
    return result


def whole(value: Any, what: str, low: int, high: int) -> int:
    """`value` as an int if it is a whole number (not a bool, not a string) in [low, high]."""
    checked = number(value, what, low, high)
    if not checked.is_integer():
        raise CommandRejected(f"{what} is not a whole number", what=f"{what} as a whole number",
                              why=f"got {shown(value)}", how=f"send {what} without a fraction")
    return int(checked)


def numbers(values: Any, what: str, count: int, magnitude: float = MAX_MAGNITUDE) -> list[float]:
    """A list of exactly `count` numbers, each finite and within ±magnitude."""
    if not isinstance(values, list) or len(values) != count:
        size = f"{len(values)} values" if isinstance(values, list) else type(values).__name__
        raise CommandRejected(f"{what} does not have one value per joint", what=f"a list of {count} numbers",
                              why=f"got {size}", how=f"send {what} as {count} numbers")
    return [number(value, what, -magnitude, magnitude) for value in values]


def point_count(count: int) -> None:
    """Refuse a trajectory of more than MAX_POINTS points."""
    if count > MAX_POINTS:
        raise CommandRejected("the trajectory has too many points", what=f"at most {MAX_POINTS} points",
                              why=f"got {count} points",
                              how="send fewer points (a trajectory needs a point only where its shape changes), "
                                  "or split the motion into several goals")


def text(value: Any, what: str, limit: int) -> str:
    """A string of 1 to `limit` printable characters."""
    if not isinstance(value, str) or not 0 < len(value) <= limit or not value.isprintable():
        raise CommandRejected(f"{what} is not a valid name", what=f"1 to {limit} printable characters",
                              why=f"got {shown(value, 80)}", how=f"send a shorter plain {what}")
    return value


def request_id(value: Any) -> str:
    """A request id: 1 to MAX_ID_CHARS letters, digits and `_.:-`."""
    if not isinstance(value, str) or not _ID.fullmatch(value):
        raise CommandRejected("the request id is malformed", what=f"1 to {MAX_ID_CHARS} letters, digits or _.:-",
                              why=f"got {shown(value, 80)}", how="send requests with plem.bridge.connect()")
    return value
