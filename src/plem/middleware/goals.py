"""Trajectory and mode commands arriving over ROS 2, run through the same client every script uses.

A JointTrajectory message (topic or FollowJointTrajectory goal) becomes a plem trajectory checked by
`RobotClient` exactly as a script's would be; its outcome maps to the action's status and
control_msgs error code. A rejected command still ends as a goal, with the code and the full
WHAT/WHY/HOW text in `error_string`, so a ROS user sees why.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from plem.bridge.client import DriverGone, RemoteHandle, RobotClient
from plem.control.modes import Mode
from plem.control.trajectory import (
    ErrorCode,
    JointTrajectory,
    TrajectoryOutcome,
    TrajectoryResult,
    TrajectoryTolerances,
)
from plem.errors import CommandRejected, PlemError
from plem.ipc.request_bounds import MAX_POINTS, point_count
from plem.ipc.requests import error_from_json, result_from_json
from plem.middleware.action import ABORTED, CANCELED, SUCCEEDED
from plem.middleware.types import InterfaceLibrary

#: A trajectory stamped this close to now starts on receipt; plem does not delay starts.
START_SLACK_NS = 50_000_000
FJT = "control_msgs/action/FollowJointTrajectory"
#: What a trajectory may hold besides its points: header, joint names, a goal's tolerances.
TRAJECTORY_SLACK_BYTES = 256 * 1024
_STATUS = {TrajectoryOutcome.SUCCEEDED: SUCCEEDED, TrajectoryOutcome.CANCELED: CANCELED,
           TrajectoryOutcome.PREEMPTED: CANCELED, TrajectoryOutcome.ABORTED: ABORTED,
           TrajectoryOutcome.REJECTED: ABORTED}


def seconds(duration: Any) -> float:
    """builtin_interfaces Time or Duration in seconds."""
    return float(duration.sec + duration.nanosec * 1e-9)


def trajectory_from_message(message: Any, now_ns: int | None = None) -> JointTrajectory:
    """A plem JointTrajectory from trajectory_msgs/JointTrajectory; CommandRejected for what plem cannot run.

    The point count is checked before anything is converted, so an oversized message costs no work.
    """
    point_count(len(message.points))
    stamp_ns = message.header.stamp.sec * 1_000_000_000 + message.header.stamp.nanosec
    if stamp_ns:
        now_ns = time.time_ns() if now_ns is None else now_ns
        end_ns = stamp_ns + round(seconds(message.points[-1].time_from_start) * 1e9) if message.points else stamp_ns
        if end_ns < now_ns:
            raise CommandRejected("the trajectory ends in the past", what="header.stamp 0 (start now) or a recent time",
                                  why=f"it ended {(now_ns - end_ns) / 1e9:.3f} s ago", how="send header.stamp = 0")
        if abs(stamp_ns - now_ns) > START_SLACK_NS:
            raise CommandRejected("delayed or back-dated starts are not supported",
                                  what="header.stamp 0: the trajectory starts when it arrives",
                                  why=f"header.stamp is {(stamp_ns - now_ns) / 1e9:+.3f} s from now",
                                  how="send header.stamp = 0")
    points = [{"positions": list(point.positions), "time_from_start": seconds(point.time_from_start),
               **({"velocities": list(point.velocities)} if len(point.velocities) else {}),
               **({"accelerations": list(point.accelerations)} if len(point.accelerations) else {})}
              for point in message.points]
    return JointTrajectory.from_lists(list(message.joint_names), points)


def trajectory_bytes(dof: int) -> int:
    """The largest JointTrajectory (or FollowJointTrajectory goal) in CDR worth decoding for an arm of `dof` joints:
    MAX_POINTS points of four full rows each, and room for names, tolerances and alignment; anything larger is
    refused anyway, so it is dropped before it costs any work."""
    row = 8 + 8 * dof                                # sequence length, alignment, the values
    return MAX_POINTS * (4 * row + 8) + TRAJECTORY_SLACK_BYTES


def tolerances_from_goal(goal: Any, joint_names: Sequence[str]) -> TrajectoryTolerances:
    """Path and goal position tolerances by joint name, and the goal time tolerance (0 or -1: unchecked)."""

    def per_joint(tolerances: Sequence[Any]) -> np.ndarray | None:
        if not tolerances:
            return None
        values = dict.fromkeys(joint_names, 0.0)
        for tolerance in tolerances:
            if tolerance.name not in values:
                raise CommandRejected(f"a tolerance names unknown joint '{tolerance.name}'",
                                      what=f"joints of this robot: {', '.join(joint_names)}",
                                      why=f"got {tolerance.name!r}", how="name the robot's joints")
            values[tolerance.name] = tolerance.position
        return np.array(list(values.values()))

    return TrajectoryTolerances(per_joint(goal.path_tolerance), per_joint(goal.goal_tolerance),
                                seconds(goal.goal_time_tolerance))


@dataclass
class Finished:
    """A goal that ended before it started (e.g. rejected)."""

    status: int
    result: dict[str, Any]

    def poll(self) -> tuple[None, tuple[int, dict[str, Any]]]:
        """No feedback; the status and result it ended with."""
        return None, (self.status, self.result)

    def cancel(self) -> bool:
        """Nothing to cancel: the goal has ended."""
        return False


def rejected_trajectory(error: PlemError) -> Finished:
    """A FollowJointTrajectory goal refused with its error code and message."""
    result = TrajectoryResult.rejected(error) if isinstance(error, CommandRejected) else \
        TrajectoryResult(TrajectoryOutcome.REJECTED, error.render(), ErrorCode.INVALID_GOAL)
    return Finished(ABORTED, {"error_code": int(result.error_code), "error_string": result.message})


class TrajectoryGoal:
    """A running FollowJointTrajectory goal: feedback from the state block, result from the driver's reply."""

    def __init__(self, client: RobotClient, handle: RemoteHandle, library: InterfaceLibrary) -> None:
        self._client = client
        self._handle = handle
        self._library = library
        self._started = time.monotonic()

    def poll(self) -> tuple[Any | None, tuple[int, dict[str, Any]] | None]:
        """Feedback while the motion runs; its status and result once the driver replied."""
        reply = self._handle.reply if self._handle.done else None
        if reply is None:
            try:
                return self._feedback(), None
            except DriverGone as gone:   # the driver stopped the motion with itself; say so instead of waiting
                return rejected_trajectory(gone).poll()
        result = result_from_json(reply["result"])
        if isinstance(result, TrajectoryResult):   # the runtime's own outcome, also when the motion failed
            return None, (_STATUS[result.outcome], {"error_code": int(result.error_code),
                                                    "error_string": result.message})
        error = error_from_json(reply["error"]) if reply["error"] is not None else None
        return None, (ABORTED, {"error_code": int(ErrorCode.INVALID_GOAL),
                                "error_string": error.render() if error else "the motion ended without a result"})

    def cancel(self) -> bool:
        """Ask the driver to stop this goal's motion; always accepted."""
        self._handle.cancel()  # names this goal: a goal that replaced it keeps running
        return True

    def _feedback(self) -> Any | None:
        state = self._client.state()
        if state is None:
            return None
        new = self._library.new
        elapsed = time.monotonic() - self._started
        since = new("builtin_interfaces/msg/Duration", sec=int(elapsed), nanosec=int(elapsed % 1 * 1e9))
        desired = new("trajectory_msgs/msg/JointTrajectoryPoint", positions=state.command_position.tolist(),
                      velocities=state.command_velocity.tolist(),
                      accelerations=state.command_acceleration.tolist(), time_from_start=since)
        actual = new("trajectory_msgs/msg/JointTrajectoryPoint", positions=state.position.tolist(),
                     velocities=state.velocity.tolist(), effort=state.effort.tolist(), time_from_start=since)
        error = new("trajectory_msgs/msg/JointTrajectoryPoint",
                    positions=(state.command_position - state.position).tolist(),
                    velocities=(state.command_velocity - state.velocity).tolist(), time_from_start=since)
        return new(f"{FJT}_Feedback", header=new("std_msgs/msg/Header", stamp=self._library.stamp()),
                   joint_names=list(self._client.joint_names), desired=desired, actual=actual, error=error)


def start_trajectory(client: RobotClient, library: InterfaceLibrary, goal: Any) -> TrajectoryGoal | Finished:
    """Run a FollowJointTrajectory goal, or end it at once with the reason it cannot run."""
    try:
        trajectory = trajectory_from_message(goal.trajectory)
        tolerances = tolerances_from_goal(goal, client.joint_names)
        return TrajectoryGoal(client, client.execute_trajectory(trajectory, tolerances), library)
    except PlemError as error:
        return rejected_trajectory(error)


class ModeGoal:
    """A running plem_msgs/SetMode goal."""

    def __init__(self, client: RobotClient, handle: RemoteHandle | None, error: PlemError | None = None) -> None:
        self._client = client
        self._handle = handle
        self._error = error

    def poll(self) -> tuple[dict[str, Any] | None, tuple[int, dict[str, Any]] | None]:
        """The current mode as feedback until the driver replied, then success or the reason it failed."""
        try:
            state = self._client.state()
        except DriverGone as gone:
            return None, (ABORTED, {"success": False, "mode": "", "message": gone.render()})
        mode = str(state.mode) if state is not None else ""
        error = self._error
        if self._handle is not None:
            reply = self._handle.reply if self._handle.done else None
            if reply is None:
                return {"mode": mode}, None
            error = error_from_json(reply["error"]) if reply["error"] is not None else None
            reached = result_from_json(reply["result"]) if error is None else None
            if isinstance(reached, Mode):   # the mode the reply names: the state block may be a cycle behind it
                mode = str(reached)
        if error is not None:
            return None, (ABORTED, {"success": False, "mode": mode, "message": error.render()})
        return None, (SUCCEEDED, {"success": True, "mode": mode, "message": ""})

    def cancel(self) -> bool:
        """A mode change cannot be canceled once requested."""
        return False


def start_mode_change(client: RobotClient, goal: Any) -> ModeGoal:
    """Request a plem_msgs/SetMode goal's mode; a refused request ends the goal with the reason."""
    try:
        return ModeGoal(client, client.request_mode(goal.mode))
    except PlemError as error:
        return ModeGoal(client, None, error)

