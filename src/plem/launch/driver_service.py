"""The RT driver's service thread: takes the command service's records and publishes loop statistics.

It runs beside the loop thread, at SCHED_FIFO priority 1 when permitted (below the loop; see
`keep_threads_scheduled`), and does only small, bounded work: the records on the intake ring are a few
hundred bytes, motions arrive as tables in the motion slab that the loop samples in place, and every
answer on the outcomes ring fits its slot. Validation and planning happen in the command service
process (`plem.launch.command_service`). Ten times a second it writes a statistics record for monitors.
"""

from __future__ import annotations

import json
import logging
import threading
import time
from collections import OrderedDict
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from plem.control.commands import CommandHandle, PlanBasis, StartMotion
from plem.control.modes import Mode
from plem.control.payload import Payload
from plem.control.reactions import reaction_from_json
from plem.control.timing import histogram_summary
from plem.control.trajectory import TrajectoryTolerances
from plem.errors import CommandRejected, PlemError
from plem.fieldbus.cia402 import decode_statusword
from plem.ipc.channels import RobotChannels
from plem.ipc.request_bounds import truncated
from plem.ipc.requests import error_json, result_json, until_from_json
from plem.robot.robot import Robot

POLL_S = 0.001
STATS_PERIOD_S = 0.1
#: Prepared start states kept for start records still to come.
PREPARED_KEPT = 16
#: Characters of each text of an error on the outcomes ring (its 4096-byte slot holds four of them).
OUTCOME_TEXT_CHARS = 600
#: Longest note on how a motion was re-timed that travels with it to its result.
NOTE_CHARACTERS = 400
#: The command service's counters: requests received, refused, and answered without the driver.
CLIENT_COUNTERS = ("received", "rejected", "answered_here")
#: A motion's first sample may differ this much (rad, rad/s, rad/s²) from the state it was planned from.
START_MATCH = 1e-6
_log = logging.getLogger("plem.rt_driver")


@dataclass
class _Pending:
    """A command handed to the robot, by its token in `_pending`: what to report about it, and its slot."""

    handle: CommandHandle
    slot: int | None = None
    accepted_sent: bool = False
    accepted: dict[str, int] | None = None   # what its acceptance carries (a stream's session, a reaction's token)


@dataclass
class CommandCounters:
    """What the driver did with the commands the command service handed it."""

    accepted: int = 0
    rejected: int = 0
    finished: int = 0
    failed: int = 0


@dataclass
class DriverService:
    """Serves one robot's intake ring and statistics ring until `stop` is set."""

    robot: Robot
    channels: RobotChannels
    stop: threading.Event = field(default_factory=threading.Event)
    counters: CommandCounters = field(default_factory=CommandCounters)

    def __post_init__(self) -> None:
        self._intake = self.channels.rings["intake"].consumer()
        self._outcomes = self.channels.rings["outcomes"]
        if self.channels.motions is None:
            raise ValueError("the driver service needs the motion slab: the driver's channels (RobotChannels.create)")
        self._slab = self.channels.motions
        self._pending: dict[int, _Pending] = {}
        self._prepared: OrderedDict[int, tuple[PlanBasis, int | None, np.ndarray]] = OrderedDict()
        self._client_counters: dict[str, int] = dict.fromkeys(CLIENT_COUNTERS, 0)
        stats = self.robot.loop.stats
        self._previous = (stats.latency.histogram.copy(), stats.compute.histogram.copy())
        self.thread = threading.Thread(target=self._run, name=f"plem-service-{self.robot.robot_id}", daemon=True)

    def start(self) -> None:
        """Start serving in the background thread `thread`; set `stop` to end it."""
        self.thread.start()

    def _run(self) -> None:
        next_stats = time.monotonic()
        while not self.stop.is_set():
            while (record := self._intake.read()) is not None:
                self._serve(record)
            if self._pending:
                self._answer_pending()
            now = time.monotonic()
            if now >= next_stats:
                self._publish_stats()
                next_stats = now + STATS_PERIOD_S
            self.stop.wait(POLL_S)

    def _serve(self, record: bytes) -> None:
        """One intake record; whatever goes wrong with it is answered as its rejection and serving goes on."""
        token = 0
        try:
            command = json.loads(record)
            token = int(command.get("token", 0))
            self._dispatch(command, token)
        except Exception as error:  # noqa: BLE001 - the service thread must outlive any record
            self._write(token, "rejected", error=_as_plem_error(error), slot=_slot_of(record))

    def _dispatch(self, command: dict[str, Any], token: int) -> None:
        robot, op = self.robot, command["op"]
        if op == "counters":
            self._client_counters = {key: int(command.get(key, 0)) for key in CLIENT_COUNTERS}
        elif op == "prepare":
            self._prepare(token, float(command["lead_s"]))
        elif op == "start":
            self._start(token, command)
        elif op == "set_mode":
            self._pending[token] = _Pending(robot.request_mode(Mode.parse(command["mode"])))
        elif op == "reset_fault":
            self._pending[token] = _Pending(robot.request_reset())
        elif op == "stream":
            handle = robot.request_stream(float(command["timeout"]))
            self._pending[token] = _Pending(handle, accepted={"session": handle.token})
        elif op == "react":
            condition, action = reaction_from_json(command["reaction"])
            reaction, handle = robot.request_reaction(condition, action, once=bool(command["once"]))
            self._pending[token] = _Pending(handle, accepted={"reaction": reaction})
        elif op == "unreact":
            removal = robot.request_reaction_removal(int(command["reaction"]))
            if removal is None:
                self._write(token, "finished")   # fired once, or removed with its motion, already
                return
            self._pending[token] = _Pending(removal)
        elif op == "payload":
            self._pending[token] = _Pending(robot.request_payload(np.array(command["body"], dtype=float)))
        elif op == "simulate":
            self._simulate(command)
            self._write(token, "finished")
        elif op == "speed_override":
            self._pending[token] = _Pending(robot.request_speed_override(float(command["factor"])))
        elif op == "stop":
            goal = command.get("goal")
            target = None if goal is None else self._pending.get(int(goal))
            if goal is not None and target is None:
                self._write(token, "finished")  # the goal to cancel has ended already: nothing to stop
                return
            self._pending[token] = _Pending(robot.stop(target.handle if target else None))
        else:
            raise ValueError(f"unknown intake operation {op!r}")
        self._answer_pending()

    def _simulate(self, command: dict[str, Any]) -> None:
        """Push a link of the simulated arm, release it, set a drive's digital inputs, or mount a payload on it
        (bus:=mock only)."""
        simulator = self.robot.simulator
        if command["action"] == "push":
            simulator.push(command["link"], command["force"], command["torque"], command["point"])
        elif command["action"] == "release":
            simulator.release()
        elif command["action"] == "digital_inputs":
            simulator.set_digital_inputs(command["joint"], command["value"])
        else:
            simulator.mount_payload(Payload(float(command["mass"]), tuple(command["center_of_mass"])))

    def _prepare(self, token: int, lead_s: float) -> None:
        """Tell the command service where a new motion starts: the held position, or the running motion ahead."""
        runtime = self.robot.runtime
        basis = runtime.basis
        found = basis.start(runtime.cycle_count, lead_s, runtime.dt)
        if found is None:   # the command service asks again until it is known, or gives up with the reason
            self._write(token, "prepared", start=None, unknown=basis.unknown)
            return
        activation, start = found[0], np.stack(found[1])
        self._prepared[token] = (basis, activation, start)
        while len(self._prepared) > PREPARED_KEPT:
            self._prepared.popitem(last=False)
        self._write(token, "prepared", start=start.tolist())

    def _start(self, token: int, command: dict[str, Any]) -> None:
        """Hand a planned motion from the slab to the loop, after checking it starts where it was planned from."""
        slot = int(command["slot"])
        prepared = self._prepared.pop(int(command["prepared"]), None)
        if prepared is None:
            self._write(token, "rejected", stale=True, slot=slot, error=_STALE)
            return
        basis, activation, start = prepared
        motion = self._slab.view(slot, int(command["segments"]))
        first = np.stack(motion.state_at(0.0))
        if not np.all(np.abs(first - start) <= START_MATCH):
            raise CommandRejected("a planned motion does not start where it was planned from",
                                  what=f"its first sample within {START_MATCH:g} of the prepared start",
                                  why=f"largest difference {np.nanmax(np.abs(first - start)):.3g}",
                                  how="retry; restart the robot if it happens again")
        tolerances = command.get("tolerances")
        label = str(command.get("label", "motion"))[:32]
        note = str(command.get("note", ""))[:NOTE_CHARACTERS]
        handle = CommandHandle(label)
        self._pending[token] = _Pending(handle, slot)
        self.robot.runtime.submit(StartMotion(motion, basis, activation,
                                              TrajectoryTolerances(**tolerances) if tolerances
                                              else TrajectoryTolerances(), handle, label, note, slot, motion.segments,
                                              until=until_from_json(command.get("until"))))

    def _answer_pending(self) -> None:
        for token, pending in list(self._pending.items()):
            handle = pending.handle
            if handle.rejection is not None:
                self.counters.rejected += not handle.stale
                self._write(token, "rejected", error=handle.rejection, stale=handle.stale or None, slot=pending.slot)
                del self._pending[token]
                continue
            if not pending.accepted_sent and handle.is_accepted:
                self.counters.accepted += 1
                self._write(token, "accepted", result=pending.accepted)
                pending.accepted_sent = True
            if handle.done:
                failed = handle.error is not None
                self.counters.failed += failed
                self.counters.finished += not failed
                self._write(token, "failed" if failed else "finished", result=handle.result, error=handle.error,
                            slot=pending.slot)
                del self._pending[token]

    def _write(self, token: int, stage: str, *, result: Any = None, error: PlemError | None = None,
               **extra: Any) -> None:
        """One outcome record, its texts cut so that it always fits its slot."""
        record = {"token": token, "stage": stage, "result": result_json(result, OUTCOME_TEXT_CHARS),
                  "error": None if error is None else error_json(error, OUTCOME_TEXT_CHARS),
                  **{key: value for key, value in extra.items() if value is not None}}
        data = json.dumps(record, separators=(",", ":"), allow_nan=False, default=_plain).encode()
        if len(data) > self._outcomes.slot_bytes:  # a full-length result message and error text together
            record.update(result=None, error=None if error is None else {"error": "PlemError",
                                                                        "summary": truncated(error.summary, 200)})
            data = json.dumps(record, separators=(",", ":"), default=_plain).encode()
        self._outcomes.write(data)

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
        bus, exchange = robot.bus.status, getattr(robot.bus, "exchange", None)
        encoders, statuswords, error_codes = robot.runtime.drive_inputs()
        record = {
            "monotonic_ns": time.monotonic_ns(), "cycles": stats.cycles, "overruns": stats.overruns,
            "missed_periods": stats.missed_periods, "mode": robot.mode.name.lower(),
            "fault_reason": robot.fault_reason,
            "latency": asdict(stats.latency.whole_run()), "compute": asdict(stats.compute.whole_run()),
            "latency_interval": asdict(interval[0]), "compute_interval": asdict(interval[1]),
            "commands": {**self._client_counters, **asdict(self.counters),
                         "rejected": self._client_counters["rejected"] + self.counters.rejected},
            "rings": {name: ring.head for name, ring in self.channels.rings.items()},
            "command_queue": {"capacity": self.channels.rings["intake"].slots, "fill": self._intake.pending,
                              "written": self.channels.rings["intake"].head},
            "realtime": {"policy": report.policy, "priority": report.priority,
                         "memory_locked": report.memory_locked, "dma_latency_held": report.dma_latency_held},
            "bus": {"lost_frames": bus.lost_frames, "working_counter_errors": bus.working_counter_errors,
                    "working_counter": bus.working_counter,
                    "expected_working_counter": bus.expected_working_counter,
                    "exchange": asdict(exchange.whole_run()) if exchange is not None else None},
            "encoders": encoders.tolist(),
            "drives": [{"state": decode_statusword(int(word)).name.lower(), "error_code": int(code)}
                       for word, code in zip(statuswords, error_codes, strict=True)],
            "joint_offsets": robot.runtime.offsets.tolist(),
        }
        self.channels.rings["stats"].write(json.dumps(record, default=_plain).encode())


_STALE = CommandRejected("the motion was planned from an outdated state",
                         what="a plan starting from the arm's current command",
                         why="the command changed while the motion was being planned", how="plan again")


def _slot_of(record: bytes) -> int | None:
    """The motion slot a failed start record named, so the command service gets it back."""
    try:
        slot = json.loads(record).get("slot")
    except (ValueError, AttributeError):
        return None
    return slot if isinstance(slot, int) else None


def _as_plem_error(error: Exception) -> PlemError:
    if isinstance(error, PlemError):
        return error
    return CommandRejected("the request could not be handled", what="a request the driver can execute",
                           why=f"{type(error).__name__}: {error}"[:300], how="check the request's values")


def _plain(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    return str(value)
