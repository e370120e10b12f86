"""Requests clients send to a robot's command service, and the replies they get back, as JSON.

`check_request` is the one validation both sides run: the client before a request leaves it (sizes,
finite numbers in range, joint names), the command service again when it arrives, so a malformed request
from anything else is refused before any work is done on it and never reaches the RT driver. Position limits
are checked where the motion is planned, from the arm's state (`ArmLimits.reaching`): an arm outside a range
may be sent back into it.
"""

from __future__ import annotations

import itertools
import json
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from plem.control.limits import ArmLimits
from plem.control.modes import Mode
from plem.control.reactions import Condition, Stop, reaction_from_json, reaction_json
from plem.control.spline import JointNamesRejected
from plem.control.streaming import DEFAULT_TIMEOUT_S, override_factor, stream_timeout
from plem.control.trajectory import (
    ErrorCode,
    JointTrajectory,
    TrajectoryOutcome,
    TrajectoryResult,
    TrajectoryTolerances,
)
from plem.errors import CommandRejected, PlemError, RobotFault
from plem.ipc import request_bounds as bounds
from plem.ipc.request_bounds import shown

#: Operations and the keys each accepts (all optional keys have defaults).
OPERATIONS: dict[str, tuple[str, ...]] = {
    "move_joints": ("target", "speed_scale", "tolerances", "until"),
    "execute_trajectory": ("joint_names", "points", "tolerances", "until"),
    "set_mode": ("mode",),
    "reset_fault": (),
    "stop": ("goal",),
    "stream": ("timeout",),
    "speed_override": ("factor",),
    "react": ("reaction", "once"),
    "unreact": ("reaction",),
    "payload": ("body",),
    "simulate": ("action", "link", "force", "torque", "point", "mass", "center_of_mass", "joint", "value"),
}
SIMULATIONS = ("push", "release", "digital_inputs", "mount_payload")
MOTIONS = ("move_joints", "execute_trajectory")
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
                        why=f"got {shown(value)}", how="send path/goal as one number per joint (rad)")
    arguments: dict[str, Any] = {}
    for key in ("path", "goal"):
        if value.get(key) is not None:
            arguments[key] = np.array(bounds.numbers(value[key], f"the {key} tolerance", limits.dof))
    if value.get("goal_time") is not None:
        arguments["goal_time"] = bounds.number(value["goal_time"], "goal_time", 0.0, bounds.MAX_SECONDS)
    if value.get("stopped_velocity_tolerance") is not None:
        arguments["stopped_velocity_tolerance"] = bounds.number(
            value["stopped_velocity_tolerance"], "stopped_velocity_tolerance", 0.0, bounds.MAX_MAGNITUDE,
            low_open=True)
    return TrajectoryTolerances(**arguments)


def _trajectory(args: Mapping[str, Any], limits: ArmLimits) -> JointTrajectory:
    """The trajectory of a request, its sizes and every number checked before anything is fitted."""
    names, points = args.get("joint_names"), args.get("points")
    if not isinstance(names, list) or not 0 < len(names) <= bounds.MAX_JOINTS:
        raise _rejected("joint_names is not a list of names", what="the joint names, one per column",
                        why=f"got {shown(names)}", how=f"send {list(limits.joint_names)}")
    names = [bounds.text(name, "joint name", bounds.MAX_NAME_CHARS) for name in names]
    if not isinstance(points, list) or not points or not all(isinstance(p, Mapping) for p in points):
        raise _rejected("the trajectory has no points", what="a non-empty list of points",
                        why=f"got {type(points).__name__}", how="send at least one point")
    bounds.point_count(len(points))
    unknown = sorted(set(names) - set(limits.joint_names))
    if unknown or len(set(names)) != len(names) or len(names) != limits.dof:
        raise JointNamesRejected("the trajectory's joints do not match the robot",
                                 what=f"each of {', '.join(limits.joint_names)} exactly once",
                                 why=f"got {', '.join(names)}", how="name every joint of the robot once")
    checked: list[dict[str, Any]] = []
    previous = -math.inf
    for index, point in enumerate(points):
        time_from_start = bounds.number(point.get("time_from_start"), f"point {index} time_from_start", 0.0,
                                        bounds.MAX_SECONDS)
        if time_from_start <= previous:
            raise _rejected(f"point {index} is out of time order", what="strictly increasing time_from_start",
                            why=f"time_from_start {time_from_start} after {previous}", how="sort the points by time")
        previous = time_from_start
        row: dict[str, Any] = {**point, "time_from_start": time_from_start}
        for key in ("positions", "velocities", "accelerations"):
            if point.get(key) is not None:
                row[key] = bounds.numbers(point[key], f"point {index} {key}", limits.dof)
        if row.get("positions") is None:
            raise _rejected(f"point {index} has no positions", what="positions for every point",
                            why=f"point {index} carries {', '.join(sorted(point)) or 'nothing'}",
                            how="send one position per joint in every point")
        checked.append(row)
    trajectory = JointTrajectory.from_lists(names, checked)
    trajectory.check_times()
    return trajectory


def check_request(payload: Mapping[str, Any], limits: ArmLimits) -> CheckedRequest:
    """Validate a decoded request against the robot's joints and limits; CommandRejected names the problem."""
    op = payload.get("op")
    request_id = bounds.request_id(payload.get("id"))
    if not isinstance(op, str) or op not in OPERATIONS:
        raise _rejected("not a plem request", what=f"an op from {', '.join(OPERATIONS)}",
                        why=f"op {shown(op, 80)}", how="send requests with plem.bridge.connect()")
    args = {k: v for k, v in payload.items() if k not in ("id", "op")}
    unknown = sorted(set(args) - set(OPERATIONS[op]))
    if unknown:
        raise _rejected(f"{op} got unknown arguments", what=f"arguments from: {', '.join(OPERATIONS[op]) or 'none'}",
                        why=f"unknown: {shown(', '.join(unknown))}", how="check the spelling")
    checked: dict[str, Any] = {}
    if op == "move_joints":
        target = np.array(bounds.numbers(args.get("target"), "the target", limits.dof))
        checked = {"target": target,
                   "speed_scale": bounds.number(args.get("speed_scale", 1.0), "speed_scale", bounds.MIN_SPEED_SCALE,
                                                 1.0),
                   "tolerances": _tolerances(args.get("tolerances"), limits)}
    elif op == "execute_trajectory":
        checked = {"trajectory": _trajectory(args, limits), "tolerances": _tolerances(args.get("tolerances"), limits)}
    elif op == "set_mode":
        mode = Mode.parse(bounds.text(args.get("mode", ""), "mode", 32))
        if mode not in (Mode.IDLE, Mode.HOLD, Mode.FREE_DRIVE):
            raise _rejected(f"mode {mode.name} cannot be requested", what="idle, hold or free_drive",
                            why=f"got {mode.name}", how="start a motion to enter TRAJECTORY; reset_fault leaves FAULT")
        checked = {"mode": mode}
    elif op == "stop" and args.get("goal") is not None:
        checked = {"goal": bounds.request_id(args["goal"])}
    elif op == "stream":
        checked = {"timeout": stream_timeout(args.get("timeout", DEFAULT_TIMEOUT_S))}
    elif op == "speed_override":
        checked = {"factor": override_factor(args.get("factor"))}
    elif op == "react":
        condition, action = reaction_from_json(args.get("reaction"))
        checked = {"condition": condition, "action": action, "once": args.get("once") is True}
    elif op == "unreact":
        checked = {"reaction": int(bounds.number(args.get("reaction"), "the reaction", 1, 2.0**63))}
    elif op == "payload":
        checked = {"body": bounds.numbers(args.get("body"), "the payload body", 13)}
    elif op == "simulate":
        checked = _simulation(args)
    if op in MOTIONS:
        checked["until"] = until_from_json(args.get("until"))
    return CheckedRequest(request_id, op, checked)


def until_json(until: Condition | None) -> dict[str, Any]:
    """A motion request's `until` condition as it carries it (a Stop reaction); nothing without one."""
    return {} if until is None else {"until": reaction_json(until, Stop())}


def until_from_json(value: object) -> Condition | None:
    """The `until` condition of a motion request, checked; None without one."""
    if value is None:
        return None
    condition, action = reaction_from_json(value)
    if not isinstance(action, Stop):
        raise _rejected("an until condition stops its motion", what="the Stop action", why="got another action",
                        how="give the condition as move_joints(..., until=...) does")
    return condition


def _simulation(args: Mapping[str, Any]) -> dict[str, Any]:
    """A request to the simulated arm (push a link, release it, mount a payload), its numbers checked."""
    action = args.get("action")
    if action not in SIMULATIONS:
        raise _rejected("not a simulator action", what=f"one of {', '.join(SIMULATIONS)}", why=f"got {shown(action)}",
                        how="use robot.simulator.push(), release(), set_digital_inputs() or mount_payload()")
    checked: dict[str, Any] = {"action": action}
    if action == "push":
        checked["link"] = bounds.text(args.get("link"), "link", bounds.MAX_NAME_CHARS)
        for key in ("force", "torque", "point"):
            checked[key] = bounds.numbers(args.get(key, [0.0, 0.0, 0.0]), f"the push's {key}", 3)
    elif action == "digital_inputs":
        checked["joint"] = bounds.whole(args.get("joint"), "the joint", 0, 15)
        checked["value"] = bounds.whole(args.get("value"), "the digital inputs", 0, 2**32 - 1)
    elif action == "mount_payload":
        checked["mass"] = bounds.number(args.get("mass"), "the payload's mass", 0.0, bounds.MAX_MAGNITUDE)
        checked["center_of_mass"] = bounds.numbers(args.get("center_of_mass", [0.0, 0.0, 0.0]),
                                                   "the payload's centre of mass", 3)
    return checked


def tolerances_json(tolerances: TrajectoryTolerances) -> dict[str, Any]:
    """Tolerances as requests carry them: unchecked joints as 0 (as ROS sends them), waiting forever as the
    longest goal time a request may give."""

    def plain(values: np.ndarray | None) -> list[float] | None:
        return None if values is None else [float(v) if math.isfinite(v) else 0.0 for v in values]

    return {"path": plain(tolerances.path), "goal": plain(tolerances.goal),
            "goal_time": min(tolerances.goal_time, bounds.MAX_SECONDS),
            "stopped_velocity_tolerance": tolerances.stopped_velocity_tolerance}


def encode(payload: Mapping[str, Any]) -> bytes:
    """One JSON record; NaN and infinity are refused (JSON has no such numbers)."""
    try:
        return json.dumps(payload, allow_nan=False, separators=(",", ":")).encode()
    except (TypeError, ValueError) as error:
        raise _rejected("the request cannot be encoded", what="plain numbers, strings and lists",
                        why=shown(str(error)), how="send finite floats and lists") from None


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a JSON number")


def decode(record: bytes) -> dict[str, Any]:
    """A JSON object from a record (NaN and Infinity are not numbers); anything else is CommandRejected."""
    if len(record) > bounds.MAX_REQUEST_BYTES:
        raise _rejected("the request is too large", what=f"at most {bounds.MAX_REQUEST_BYTES} bytes",
                        why=f"got {len(record)} bytes", how="send fewer trajectory points")
    try:
        payload = json.loads(record, parse_constant=_no_constant)
    except (UnicodeDecodeError, ValueError, RecursionError) as error:
        raise _rejected("unreadable request", what="a JSON object", why=shown(str(error)),
                        how="send requests with plem.bridge.connect()") from None
    if not isinstance(payload, dict):
        raise _rejected("unreadable request", what="a JSON object", why=f"got {type(payload).__name__}",
                        how="send requests with plem.bridge.connect()")
    return payload


def request_id_of(payload: Any) -> str | None:
    """The id of a possibly malformed request, so its rejection can still be addressed (None if unusable)."""
    try:
        return bounds.request_id(payload.get("id")) if isinstance(payload, dict) else None
    except CommandRejected:
        return None


# -- replies -------------------------------------------------------------------------------------
def reply(request_id: str, stage: str, result: Any = None, error: PlemError | None = None) -> bytes:
    """The answer to a request: accepted, rejected (never started), finished (with a result) or failed.

    Every text in it is cut to MAX_TEXT_CHARS with a marker, so an answer's size is bounded whatever
    the request held.
    """
    return reply_of_json(request_id, stage, result_json(result), None if error is None else error_json(error))


def reply_of_json(request_id: str, stage: str, result: Any, error: dict[str, Any] | None) -> bytes:
    """The answer to a request from a result and an error already in JSON form (as the RT driver reports them)."""
    return encode({"id": request_id, "stage": stage, "result": result, "error": error})


def error_json(error: PlemError, limit: int = bounds.MAX_TEXT_CHARS) -> dict[str, Any]:
    """An error as JSON with each text field cut to `limit` characters."""
    return {key: bounds.truncated(value, limit) if isinstance(value, str) else value
            for key, value in error.to_dict().items()}


def result_json(result: Any, limit: int = bounds.MAX_TEXT_CHARS) -> Any:
    """A command's result as JSON: a trajectory outcome (its message cut to `limit`), a mode, or as it is."""
    if isinstance(result, TrajectoryResult):
        return {"outcome": result.outcome.value, "message": bounds.truncated(result.message, limit),
                "error_code": int(result.error_code)}
    if isinstance(result, Mode):
        return result.name.lower()
    return result


def result_from_json(value: Any) -> Any:
    """Turn a reply's result back into the type the in-process robot API returns."""
    if isinstance(value, dict) and "outcome" in value:
        return TrajectoryResult(TrajectoryOutcome(value["outcome"]), value["message"], ErrorCode(value["error_code"]))
    if isinstance(value, str):
        return Mode.parse(value)
    return value


_ERROR_TYPES: dict[str, type[PlemError]] = {cls.__name__: cls for cls in (CommandRejected, RobotFault, PlemError)}


def error_from_json(value: Mapping[str, Any]) -> PlemError:
    """Rebuild the PlemError a reply carries (its class when known, PlemError otherwise)."""
    cls = _ERROR_TYPES.get(value.get("error", ""), PlemError)
    return cls(value.get("summary", "error"), what=value.get("what", ""), why=value.get("why", ""),
               how=value.get("how", ""))
