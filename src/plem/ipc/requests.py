"""Requests clients put in a robot's command ring, and the replies the RT driver posts back, as JSON.

`check_request` is the one validation both sides run: the client before a request enters the ring
(shape, finite numbers, joint names, position limits), the driver again when it takes it out, so a
malformed record written by anything else is refused without reaching the loop.
"""

from __future__ import annotations

import itertools
import json
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from plem.control.limits import ArmLimits
from plem.control.modes import Mode
from plem.control.spline import JointNamesRejected
from plem.control.trajectory import JointTrajectory, TrajectoryOutcome, TrajectoryResult, TrajectoryTolerances
from plem.errors import CommandRejected, PlemError, RobotFault

#: Operations and the keys each accepts (all optional keys have defaults).
OPERATIONS: dict[str, tuple[str, ...]] = {
    "move_joints": ("target", "speed_scale", "tolerances"),
    "execute_trajectory": ("joint_names", "points", "tolerances"),
    "set_mode": ("mode",),
    "reset_fault": (),
    "stop": (),
}
TOLERANCE_KEYS = ("path", "goal", "goal_time", "stopped_velocity_tolerance")
REPLY_STAGES = ("accepted", "rejected", "finished", "failed")
_counter = itertools.count(1)


def new_request_id() -> str:
    """Unique across the processes of one host: pid, a per-process counter and a random part."""
    return f"{os.getpid()}-{next(_counter)}-{os.urandom(3).hex()}"


@dataclass(frozen=True)
class CheckedRequest:
    """A request that passed validation, with its arguments in the form the robot API takes."""

    id: str
    op: str
    args: dict[str, Any]


def _rejected(summary: str, what: str, why: str, how: str) -> CommandRejected:
    return CommandRejected(summary, what=what, why=why, how=how)


def _tolerances(value: Any, limits: ArmLimits) -> TrajectoryTolerances | None:
    if value is None:
        return None
    if not isinstance(value, Mapping) or set(value) - set(TOLERANCE_KEYS):
        raise _rejected("tolerances are malformed", what=f"a mapping with keys from {', '.join(TOLERANCE_KEYS)}",
                        why=f"got {value!r}"[:300], how="send path/goal as one number per joint (rad)")
    arguments = dict(value)
    for key in ("path", "goal"):
        if arguments.get(key) is not None:
            arguments[key] = limits.check_vector(_numbers(arguments[key], f"the {key} tolerance"),
                                                 f"the {key} tolerance")
    for key in ("goal_time", "stopped_velocity_tolerance"):
        if key in arguments and (isinstance(arguments[key], bool) or not isinstance(arguments[key], (int, float))):
            raise _rejected(f"{key} is not a number", what="seconds or rad/s as a number",
                            why=f"got {arguments[key]!r}", how=f"send {key} as a number")
    return TrajectoryTolerances(**arguments)


def _numbers(value: Any, what: str) -> Any:
    """`value` unchanged unless it is a list holding something other than numbers (JSON true is not 1.0)."""
    if isinstance(value, list) and any(isinstance(v, bool) or not isinstance(v, (int, float)) for v in value):
        raise _rejected(f"{what} holds something other than numbers", what="a list of numbers",
                        why=f"got {value!r}"[:300], how="send plain numbers")
    return value


def _speed_scale(value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0.0 < value <= 1.0:
        raise _rejected("speed_scale out of range", what="a number in (0, 1]", why=f"speed_scale = {value!r}",
                        how="use 1.0 for full speed, 0.5 for half")
    return float(value)


def _trajectory(args: Mapping[str, Any], limits: ArmLimits) -> JointTrajectory:
    names, points = args.get("joint_names"), args.get("points")
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        raise _rejected("joint_names is not a list of names", what="the joint names, one per column",
                        why=f"got {names!r}"[:300], how=f"send {list(limits.joint_names)}")
    if not isinstance(points, list) or not points or not all(isinstance(p, Mapping) for p in points):
        raise _rejected("the trajectory has no points", what="a non-empty list of points",
                        why=f"got {type(points).__name__}", how="send at least one point")
    trajectory = JointTrajectory.from_lists(names, points)
    unknown = sorted(set(names) - set(limits.joint_names))
    if unknown or len(set(names)) != len(names) or len(names) != limits.dof:
        raise JointNamesRejected("the trajectory's joints do not match the robot",
                                 what=f"each of {', '.join(limits.joint_names)} exactly once",
                                 why=f"got {', '.join(names)}", how="name every joint of the robot once")
    order = [names.index(name) for name in limits.joint_names]
    previous = -math.inf
    for index, point in enumerate(trajectory.points):
        if not math.isfinite(point.time_from_start) or point.time_from_start <= previous:
            raise _rejected(f"point {index} is out of time order", what="strictly increasing finite time_from_start",
                            why=f"time_from_start {point.time_from_start} after {previous}",
                            how="sort the points by time")
        previous = point.time_from_start
        for key in ("positions", "velocities", "accelerations"):
            row = getattr(point, key)
            if row is not None:
                checked = limits.check_vector(row, f"point {index} {key}")
                if key == "positions":
                    limits.check_positions(checked[order], f"point {index}")
    return trajectory


def check_request(payload: Mapping[str, Any], limits: ArmLimits) -> CheckedRequest:
    """Validate a decoded request against the robot's joints and limits; CommandRejected names the problem."""
    request_id, op = payload.get("id"), payload.get("op")
    if not isinstance(request_id, str) or not isinstance(op, str) or op not in OPERATIONS:
        raise _rejected("not a plem request", what=f"an id and an op from {', '.join(OPERATIONS)}",
                        why=f"id {request_id!r}, op {op!r}"[:300], how="send requests with plem.bridge.connect()")
    args = {k: v for k, v in payload.items() if k not in ("id", "op")}
    unknown = sorted(set(args) - set(OPERATIONS[op]))
    if unknown:
        raise _rejected(f"{op} got unknown arguments", what=f"arguments from: {', '.join(OPERATIONS[op]) or 'none'}",
                        why=f"unknown: {', '.join(unknown)}", how="check the spelling")
    checked: dict[str, Any] = {}
    if op == "move_joints":
        target = limits.check_vector(_numbers(args.get("target"), "the target"), "the target")
        limits.check_positions(target, "the target")
        checked = {"target": target, "speed_scale": _speed_scale(args.get("speed_scale", 1.0)),
                   "tolerances": _tolerances(args.get("tolerances"), limits)}
    elif op == "execute_trajectory":
        checked = {"trajectory": _trajectory(args, limits), "tolerances": _tolerances(args.get("tolerances"), limits)}
    elif op == "set_mode":
        mode = Mode.parse(args.get("mode", ""))
        if mode not in (Mode.IDLE, Mode.HOLD, Mode.FREE_DRIVE):
            raise _rejected(f"mode {mode.name} cannot be requested", what="idle, hold or free_drive",
                            why=f"got {mode.name}", how="start a motion to enter TRAJECTORY; reset_fault leaves FAULT")
        checked = {"mode": mode}
    return CheckedRequest(request_id, op, checked)


def encode(payload: Mapping[str, Any]) -> bytes:
    """One JSON record; NaN and infinity are refused (JSON has no such numbers)."""
    try:
        return json.dumps(payload, allow_nan=False, separators=(",", ":")).encode()
    except (TypeError, ValueError) as error:
        raise _rejected("the request cannot be encoded", what="plain numbers, strings and lists",
                        why=str(error), how="send finite floats and lists") from None


def decode(record: bytes) -> dict[str, Any]:
    """A JSON object from a ring record; anything else is CommandRejected."""
    try:
        payload = json.loads(record)
    except (UnicodeDecodeError, ValueError, RecursionError) as error:
        raise _rejected("unreadable request", what="a JSON object", why=str(error)[:200],
                        how="send requests with plem.bridge.connect()") from None
    if not isinstance(payload, dict):
        raise _rejected("unreadable request", what="a JSON object", why=f"got {type(payload).__name__}",
                        how="send requests with plem.bridge.connect()")
    return payload


def request_id_of(payload: Any) -> str | None:
    """The id of a possibly malformed request, so its rejection can still be addressed."""
    return payload.get("id") if isinstance(payload, dict) and isinstance(payload.get("id"), str) else None


# -- replies -------------------------------------------------------------------------------------
def reply(request_id: str, stage: str, result: Any = None, error: PlemError | None = None) -> bytes:
    """The driver's answer: accepted, rejected (never started), finished (with a result) or failed."""
    return encode({"id": request_id, "stage": stage, "result": _result_json(result),
                   "error": None if error is None else error.to_dict()})


def _result_json(result: Any) -> Any:
    if isinstance(result, TrajectoryResult):
        return {"outcome": result.outcome.value, "message": result.message, "error_code": int(result.error_code)}
    if isinstance(result, Mode):
        return result.name.lower()
    return result


def result_from_json(value: Any) -> Any:
    """Turn a reply's result back into the type the in-process robot API returns."""
    if isinstance(value, dict) and "outcome" in value:
        return TrajectoryResult(TrajectoryOutcome(value["outcome"]), value["message"], value["error_code"])
    if isinstance(value, str):
        return Mode.parse(value)
    return value


_ERROR_TYPES: dict[str, type[PlemError]] = {cls.__name__: cls for cls in (CommandRejected, RobotFault, PlemError)}


def error_from_json(value: Mapping[str, Any]) -> PlemError:
    """Rebuild the PlemError a reply carries (its class when known, PlemError otherwise)."""
    cls = _ERROR_TYPES.get(value.get("error", ""), PlemError)
    return cls(value.get("summary", "error"), what=value.get("what", ""), why=value.get("why", ""),
               how=value.get("how", ""))
