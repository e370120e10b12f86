"""The RT driver's service thread: takes client requests from the command ring and publishes loop statistics.

It runs beside the loop thread, at SCHED_FIFO priority 1 when permitted (below the loop; see
`keep_threads_scheduled`). Each request is validated again (`check_request`), handed to the robot
without waiting for the motion, and answered in the replies ring when the loop accepts, rejects or
finishes it. Ten times a second it writes a statistics record for monitors.
"""

from __future__ import annotations

import json
import threading
import time
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from plem.control.commands import CommandHandle
from plem.control.timing import histogram_summary
from plem.errors import CommandRejected, PlemError
from plem.ipc.channels import RobotChannels
from plem.ipc.requests import CheckedRequest, check_request, decode, reply, request_id_of
from plem.robot.robot import Robot

POLL_S = 0.001
STATS_PERIOD_S = 0.1


@dataclass
class _Pending:
    request_id: str
    handle: CommandHandle
    accepted_sent: bool = False


@dataclass
class CommandCounters:
    received: int = 0
    rejected: int = 0
    accepted: int = 0
    finished: int = 0
    failed: int = 0


@dataclass
class DriverService:
    """Serves one robot's command ring and statistics ring until `stop` is set."""

    robot: Robot
    channels: RobotChannels
    stop: threading.Event = field(default_factory=threading.Event)
    counters: CommandCounters = field(default_factory=CommandCounters)

    def __post_init__(self) -> None:
        self._consumer = self.channels.rings["commands"].consumer()
        self._replies = self.channels.rings["replies"]
        self._limits = self.channels.state.limits
        self._pending: list[_Pending] = []
        stats = self.robot.loop.stats
        self._previous = (stats.latency.histogram.copy(), stats.compute.histogram.copy())
        self.thread = threading.Thread(target=self._run, name=f"plem-service-{self.robot.robot_id}", daemon=True)

    def start(self) -> None:
        self.thread.start()

    def _run(self) -> None:
        next_stats = time.monotonic()
        while not self.stop.is_set():
            while (record := self._consumer.read()) is not None:
                self._serve(record)
            if self._pending:
                self._answer_pending()
            now = time.monotonic()
            if now >= next_stats:
                self._publish_stats()
                next_stats = now + STATS_PERIOD_S
            self.stop.wait(POLL_S)

    def _serve(self, record: bytes) -> None:
        self.counters.received += 1
        payload: Any = None
        try:
            payload = decode(record)
            handle = self._dispatch(check_request(payload, self._limits))
        except Exception as error:  # anything a record provokes is its rejection; the service goes on
            self.counters.rejected += 1
            request_id = request_id_of(payload)
            if request_id is not None:
                self._replies.write(reply(request_id, "rejected", error=_as_plem_error(error)))
            return
        self._pending.append(_Pending(payload["id"], handle))
        self._answer_pending()

    def _dispatch(self, request: CheckedRequest) -> CommandHandle:
        robot, args = self.robot, request.args
        if request.op == "move_joints":
            return robot.move_joints(args["target"], args["speed_scale"], args["tolerances"])
        if request.op == "execute_trajectory":
            return robot.execute_trajectory(args["trajectory"], args["tolerances"])
        if request.op == "set_mode":
            return robot.request_mode(args["mode"])
        if request.op == "reset_fault":
            return robot.request_reset()
        return robot.stop()

    def _answer_pending(self) -> None:
        still: list[_Pending] = []
        for pending in self._pending:
            handle = pending.handle
            if handle.rejection is not None:
                self.counters.rejected += 1
                self._replies.write(reply(pending.request_id, "rejected", error=handle.rejection))
                continue
            if not pending.accepted_sent and handle.is_accepted:
                self.counters.accepted += 1
                self._replies.write(reply(pending.request_id, "accepted"))
                pending.accepted_sent = True
            if handle.done:
                failed = handle.error is not None
                self.counters.failed += failed
                self.counters.finished += not failed
                self._replies.write(reply(pending.request_id, "failed" if failed else "finished", handle.result,
                                          handle.error))
            else:
                still.append(pending)
        self._pending = still

    def _publish_stats(self) -> None:
        """Loop timing (whole run and the last interval), command counters and ring positions as JSON.

        Only histogram arithmetic: a percentile over the raw window would hold the interpreter lock, which
        the loop thread needs, for about 100 µs at a time.
        """
        robot = self.robot
        stats = robot.loop.stats
        latency, compute = stats.latency.histogram.copy(), stats.compute.histogram.copy()
        interval = (histogram_summary(latency - self._previous[0]), histogram_summary(compute - self._previous[1]))
        self._previous = (latency, compute)
        report = robot.loop.report
        record = {
            "monotonic_ns": time.monotonic_ns(), "cycles": stats.cycles, "overruns": stats.overruns,
            "missed_periods": stats.missed_periods, "mode": robot.mode.name.lower(),
            "fault_reason": robot.fault_reason,
            "latency": asdict(stats.latency.whole_run()), "compute": asdict(stats.compute.whole_run()),
            "latency_interval": asdict(interval[0]), "compute_interval": asdict(interval[1]),
            "commands": asdict(self.counters),
            "rings": {name: ring.head for name, ring in self.channels.rings.items()},
            "realtime": {"policy": report.policy, "priority": report.priority,
                         "memory_locked": report.memory_locked, "dma_latency_held": report.dma_latency_held},
        }
        self.channels.rings["stats"].write(json.dumps(record, default=_plain).encode())


def _as_plem_error(error: Exception) -> PlemError:
    if isinstance(error, PlemError):
        return error
    return CommandRejected("the request could not be handled", what="a request the driver can execute",
                           why=f"{type(error).__name__}: {error}"[:300], how="check the request's values")


def _plain(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    return str(value)
