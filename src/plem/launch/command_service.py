"""A robot's command service: the process between its clients and its RT driver.

The RT driver starts it as `python -m plem.launch.command_service <robot_id>` and restarts it if it dies.
It listens on the robot's command socket, and everything that costs time happens here, outside the RT
process: reading and bounding requests, validating them, fitting trajectories and planning motions. The
driver receives only small records on its intake ring and motions as tables in the motion slab, which
its loop samples in place; it answers on the outcomes ring. A client that floods, stalls or sends
garbage costs this process time, never the loop: a request whose answer is known already (the mode the arm
is in, a stop with nothing to stop) is answered here, one that repeats the request still on its way to the
driver shares that request's answer, and each connection has at most MAX_IN_FLIGHT mode changes and resets
waiting for the driver.
"""

from __future__ import annotations

import itertools
import json
import logging
import os
import selectors
import socket
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from plem.control.commands import PLAN_ATTEMPTS, UNKNOWN_WAIT_S, preemption_lead, unknown_future
from plem.control.modes import Mode
from plem.control.motion import StartState, plan_point_to_point
from plem.control.polynomial import PolynomialMotion
from plem.control.reactions import reaction_json
from plem.errors import CommandRejected, PlemError
from plem.ipc.channels import RobotChannels
from plem.ipc.command_socket import (
    CommandSocketError,
    FrameReader,
    frame,
    listen,
    peer_credentials,
    remove_own_socket,
    trusted,
)
from plem.ipc.requests import (
    MOTIONS,
    CheckedRequest,
    check_request,
    decode,
    reply,
    reply_of_json,
    request_id_of,
    tolerances_json,
    until_json,
)
from plem.launch.component import announce, begin
from plem.planning import fit_to_limits

DRIVER_TIMEOUT_S = 2.0
#: Clients served at once; more are turned away.
MAX_CLIENTS = 64
#: Bytes of answers waiting for a client that does not read; beyond this it is disconnected.
MAX_PENDING_OUTPUT = 1 << 20
POLL_S = 0.0005
#: Mode changes and fault resets of one connection waiting for the driver at once; more are refused until it
#: answers (a stop is never refused: it shares the answer of the stop before it, or goes to the driver).
MAX_IN_FLIGHT = 16
RESTART_HOW = "check the robot with `plem state`; restart it with `plem launch` if its loop stopped"
COUNTERS_PERIOD_S = 0.1
#: How often a plan asks again where it starts while the running motion's future is not known ahead.
UNKNOWN_POLL_S = 0.01
_log = logging.getLogger("plem.command_service")


class DriverSilent(PlemError):
    """The RT driver did not answer its command service in time."""


@dataclass
class _Client:
    """One connection: its frames in, its answers out, and who it is."""

    sock: socket.socket
    uid: int
    reader: FrameReader = field(default_factory=FrameReader)
    output: bytearray = field(default_factory=bytearray)
    goals: dict[str, int] = field(default_factory=dict)   # request id → token of its motions still running
    in_flight: int = 0   # its mode changes and resets waiting for the driver


@dataclass
class _Command:
    """A request handed to the driver, by the token the driver answers with."""

    client: _Client | None
    request_id: str
    slot: int | None = None
    #: Requests that repeat this one, answered with its answer: (client, request id).
    sharing: list[tuple[_Client, str]] = field(default_factory=list)
    counted: bool = False   # it counts toward its client's in_flight


@dataclass
class Counters:
    """Requests received from clients and refused here (before reaching the driver)."""

    received: int = 0
    rejected: int = 0
    answered_here: int = 0   # answered without the driver: known already, or shared with a request on its way


class CommandService:
    """Serves one robot's command socket until `stop` is set."""

    def __init__(self, channels: RobotChannels, server: socket.socket, cycle_time_s: float) -> None:
        self.limits = channels.state.limits
        self.cycle_time_s = cycle_time_s
        self.server = server
        self.intake = channels.rings["intake"]
        self.outcomes = channels.rings["outcomes"].reader(from_oldest=False)
        if channels.motions is None:
            raise ValueError("the command service needs the motion slab: channels of RobotChannels.attach_service")
        self.slab = channels.motions
        self.free_slots = list(range(self.slab.shared_slots))
        self.counters = Counters()
        self._tokens = itertools.count(1)
        self._commands: dict[int, _Command] = {}
        self._answers: dict[int, dict[str, Any]] = {}  # outcomes awaited by the request being planned
        self._selector = selectors.DefaultSelector()
        self._selector.register(server, selectors.EVENT_READ)
        self._clients: dict[int, _Client] = {}
        self._sent_counters: dict[str, int] = {}
        self._next_counters = 0.0
        self.state = channels.state
        self._last_token = 0   # the newest record's token on the intake ring
        self._repeatable: tuple[tuple[str, Mode | None], int] | None = None   # the newest mode change/reset/stop

    # -- the socket --------------------------------------------------------------------------------
    def run(self, stop: threading.Event) -> None:
        """Accept clients, serve their requests and pass the driver's answers on, until `stop` is set."""
        while not stop.is_set():
            for key, events in self._selector.select(POLL_S):
                if key.fileobj is self.server:
                    self._accept()
                elif events & selectors.EVENT_READ and key.data in self._clients:
                    self._receive(self._clients[key.data])
                if events & selectors.EVENT_WRITE and key.data in self._clients:
                    self._flush(self._clients[key.data])
            self._pump()
            self._send_counters()

    def _accept(self) -> None:
        try:
            sock, _ = self.server.accept()
        except BlockingIOError:
            return
        _, uid, _ = peer_credentials(sock)
        if not trusted(uid) or len(self._clients) >= MAX_CLIENTS:
            sock.close()  # the socket's mode keeps other users out already; this holds for root's sockets too
            return
        sock.setblocking(False)
        client = _Client(sock, uid)
        self._clients[sock.fileno()] = client
        self._selector.register(sock, selectors.EVENT_READ, sock.fileno())

    def _receive(self, client: _Client) -> None:
        try:
            data = client.sock.recv(1 << 16)
        except BlockingIOError:
            return
        except OSError:
            data = b""
        if not data:
            self._drop(client)
            return
        try:
            frames = client.reader.feed(data)
        except CommandSocketError as error:
            self.counters.rejected += 1
            self._answer(client, reply("-", "rejected", error=error))
            self._flush(client)
            self._drop(client)
            return
        for record in frames:
            self._serve(client, record)

    def _answer(self, client: _Client | None, record: bytes) -> None:
        if client is None or client.sock.fileno() not in self._clients:
            return
        if len(client.output) > MAX_PENDING_OUTPUT:
            _log.warning("a client (uid %d) stopped reading its answers; disconnected", client.uid)
            self._drop(client)
            return
        client.output += frame(record)
        self._flush(client)

    def _flush(self, client: _Client) -> None:
        fd = client.sock.fileno()
        if client.output:
            try:
                sent = client.sock.send(client.output)
                del client.output[:sent]
            except BlockingIOError:
                pass
            except OSError:
                self._drop(client)
                return
        if fd in self._clients:
            self._selector.modify(client.sock, selectors.EVENT_READ | (selectors.EVENT_WRITE if client.output else 0),
                                  fd)

    def _drop(self, client: _Client) -> None:
        fd = client.sock.fileno()
        if self._clients.pop(fd, None) is not None:
            self._selector.unregister(client.sock)
        client.sock.close()
        for command in self._commands.values():
            if command.client is client:
                command.client = None  # the motion runs on; nobody is told when it ends

    # -- requests ----------------------------------------------------------------------------------
    def _serve(self, client: _Client, record: bytes) -> None:
        self.counters.received += 1
        payload: Any = None
        try:
            payload = decode(record)
            request = check_request(payload, self.limits)
            if request.op in MOTIONS:
                self._start_motion(client, request)
            elif not self._answered_here(client, request):
                self._send(client, request)
        except PlemError as error:
            self.counters.rejected += 1
            self._answer(client, reply(request_id_of(payload) or "-", "rejected", error=error))
        except Exception as error:  # noqa: BLE001 - a request that trips a bug is refused; serving goes on
            _log.exception("a request could not be handled")
            self.counters.rejected += 1
            self._answer(client, reply(request_id_of(payload) or "-", "rejected", error=PlemError(
                "the request could not be handled", what="a request the command service can execute",
                why=f"{type(error).__name__}: {error}", how="check the request; report this with the robot's output")))

    def _answered_here(self, client: _Client, request: CheckedRequest) -> bool:
        """Answer a request without the driver when its answer is known, so that a flood of them never reaches it;
        False when it must go to the driver.

        Known are: a stop of a goal that no longer runs; with nothing on its way to the driver and the driver
        running, the mode the arm is in and a stop while no motion runs (the driver's own answers to them); and a
        repeat of the newest request sent to the driver, still unanswered and nothing sent since, which shares
        its answer (a repeated mode change the driver would refuse as pending finishes with the first one).
        """
        if request.op == "stop" and "goal" in request.args:
            return request.args["goal"] not in client.goals and self._known(client, request, None)
        shared = self._commands.get(self._last_token)
        if shared is not None and self._repeatable == ((request.op, request.args.get("mode")), self._last_token):
            shared.sharing.append((client, request.id))
            self.counters.answered_here += 1
            return True
        if self._commands or request.op == "reset_fault":
            return False
        state = self.state.block.read()
        if state is None or self.state.driver_gone(state) is not None:
            return False
        if request.op == "set_mode" and state.mode is request.args["mode"]:
            return self._known(client, request, state.mode)
        if request.op == "stop" and state.mode is not Mode.TRAJECTORY:
            return self._known(client, request, None)
        return False

    def _known(self, client: _Client, request: CheckedRequest, result: Mode | None) -> bool:
        """Answer `request` as finished with `result`, as the driver would."""
        self.counters.answered_here += 1
        self._answer(client, reply(request.id, "finished", result=result))
        return True

    def _send(self, client: _Client, request: CheckedRequest) -> int:
        """Hand a mode change, fault reset or stop to the driver; its answers reach the client later."""
        counted = request.op != "stop"
        if counted and client.in_flight >= MAX_IN_FLIGHT:
            raise CommandRejected("too many requests of this connection wait for the robot",
                                  what=f"at most {MAX_IN_FLIGHT} mode changes and resets waiting at once",
                                  why=f"{client.in_flight} are waiting for the RT driver's answer",
                                  how="wait for the answers (set_mode() and reset_fault() wait for theirs) before "
                                      "sending more")
        token = next(self._tokens)
        record: dict[str, Any] = {"op": request.op, "token": token}
        if request.op == "set_mode":
            record["mode"] = request.args["mode"].name.lower()
        elif request.op == "stop" and "goal" in request.args:
            record["goal"] = client.goals[request.args["goal"]]
        elif request.op == "react":
            record.update(reaction=reaction_json(request.args["condition"], request.args["action"]),
                          once=request.args["once"])
        elif request.op in ("stream", "speed_override", "unreact", "payload", "simulate"):
            record.update(request.args)
        self._commands[token] = _Command(client, request.id, counted=counted)
        client.in_flight += counted
        try:
            self._write_intake(record)
        except DriverSilent:
            del self._commands[token]
            client.in_flight -= counted
            raise
        if "goal" not in request.args:
            self._repeatable = ((request.op, request.args.get("mode")), token)
        return token

    def _start_motion(self, client: _Client, request: CheckedRequest) -> None:
        """Plan from the driver's current state and hand the motion over; re-plan when the state moved on."""
        plan = self._planner(request)
        label = "move_joints" if request.op == "move_joints" else "trajectory"
        planning_s = 0.0
        for attempt in range(PLAN_ATTEMPTS):
            prepared, start = self._prepare(preemption_lead(attempt, planning_s))
            began = time.monotonic()
            motion, note = plan((start[0], start[1], start[2]))
            planning_s = time.monotonic() - began
            slot = self._take_slot()
            segments = self.slab.write(slot, motion)
            token = next(self._tokens)
            self._commands[token] = _Command(client, request.id, slot)
            self._write_intake({"op": "start", "token": token, "prepared": prepared, "slot": slot,
                                "segments": segments, "label": label, "note": note,
                                "tolerances": None if request.args["tolerances"] is None
                                else tolerances_json(request.args["tolerances"]),
                                **until_json(request.args["until"])})
            answer = self._await(token)
            if answer.get("stale"):
                self._release(answer)
                del self._commands[token]
                continue
            if answer["stage"] == "accepted":
                client.goals[request.id] = token
            self._deliver(token, answer)
            return
        raise CommandRejected(f"{label} could not be started", what="the arm's state to settle long enough to plan",
                              why=f"the state changed during {PLAN_ATTEMPTS} planning attempts",
                              how="retry, or stop the robot first")

    def _prepare(self, lead_s: float) -> tuple[int, np.ndarray]:
        """Where a motion planned now starts, as the driver prepared it (its token, and the state); asked again while
        the running motion's future is not known ahead, for at most UNKNOWN_WAIT_S."""
        deadline = time.monotonic() + UNKNOWN_WAIT_S
        while True:
            prepared = next(self._tokens)
            self._write_intake({"op": "prepare", "token": prepared, "lead_s": lead_s})
            answer = self._await(prepared)
            if answer.get("start") is not None:
                return prepared, np.array(answer["start"], dtype=float)
            if time.monotonic() > deadline:
                raise unknown_future(str(answer.get("unknown", "")))
            self._pause(UNKNOWN_POLL_S)

    def _planner(self, request: CheckedRequest) -> Callable[[StartState], tuple[PolynomialMotion, str]]:
        """What plans the request's motion from a start state: the motion, and how it differs from the request."""
        limits, args = self.limits, request.args
        if request.op == "move_joints":
            return lambda start: (plan_point_to_point(limits, start, args["target"], args["speed_scale"]).polynomial(),
                                  "")

        def fit(start: StartState) -> tuple[PolynomialMotion, str]:
            timed = fit_to_limits(args["trajectory"], limits.reaching(start[0]), start, self.cycle_time_s)
            return timed.motion, timed.note()

        return fit

    # -- the driver --------------------------------------------------------------------------------
    def _until(self, done: Callable[[], bool], silent: DriverSilent) -> None:
        """Pass the driver's answers on until `done()`; `silent` is raised if that takes DRIVER_TIMEOUT_S."""
        deadline = time.monotonic() + DRIVER_TIMEOUT_S
        while not done():
            if time.monotonic() > deadline:
                raise silent
            self._pump()
            time.sleep(POLL_S)

    def _pause(self, seconds: float) -> None:
        """Pass the driver's answers on for `seconds`."""
        until = time.monotonic() + seconds
        while time.monotonic() < until:
            self._pump()
            time.sleep(POLL_S)

    def _write_intake(self, record: dict[str, Any]) -> None:
        data = json.dumps(record, allow_nan=False, separators=(",", ":")).encode()
        self._until(lambda: self.intake.write(data), DriverSilent(
            "the RT driver takes no commands", what="room in its intake ring",
            why=f"it stayed full for {DRIVER_TIMEOUT_S:g} s", how=RESTART_HOW))
        self._last_token = record["token"]

    def _await(self, token: int) -> dict[str, Any]:
        """The driver's next answer for `token` (passing on everything else meanwhile)."""
        self._answers[token] = {}
        try:
            self._until(lambda: bool(self._answers[token]), DriverSilent(
                "the RT driver did not answer", what=f"an answer within {DRIVER_TIMEOUT_S:g} s",
                why="its loop or its service thread is stalled", how=RESTART_HOW))
            return self._answers[token]
        finally:
            del self._answers[token]

    def _take_slot(self) -> int:
        self._until(lambda: bool(self.free_slots), DriverSilent(
            "no motion slot was released", what="the driver to release a finished motion",
            why=f"all {self.slab.shared_slots} slots stayed in use for {DRIVER_TIMEOUT_S:g} s",
            how="stop the robot and retry"))
        return self.free_slots.pop(0)

    def _pump(self) -> None:
        """Pass the driver's answers on to the clients they belong to."""
        while (record := self.outcomes.read()) is not None:
            outcome = json.loads(record)
            token = outcome["token"]
            if token in self._answers and not self._answers[token]:
                self._answers[token] = outcome  # the request being planned takes it from here
            else:
                self._deliver(token, outcome)
        if self.outcomes.dropped:
            _log.error("%d driver answers were lost", self.outcomes.dropped)
            self.outcomes.dropped = 0

    def _deliver(self, token: int, outcome: dict[str, Any]) -> None:
        command = self._commands.get(token)
        if command is None:
            return
        stage = outcome["stage"]
        if stage in ("rejected", "finished", "failed"):
            self._release(outcome)
            del self._commands[token]
            if command.client is not None:
                command.client.goals.pop(command.request_id, None)
                command.client.in_flight -= command.counted
        for client, request_id in ([(command.client, command.request_id)] if command.client else []) + command.sharing:
            self._answer(client, reply_of_json(request_id, stage, outcome.get("result"), outcome.get("error")))

    def _release(self, outcome: dict[str, Any]) -> None:
        slot = outcome.get("slot")
        if slot is not None and slot not in self.free_slots:
            self.free_slots.append(slot)

    def _send_counters(self) -> None:
        now = time.monotonic()
        counters = asdict(self.counters)
        if now < self._next_counters or counters == self._sent_counters:
            return
        self._next_counters = now + COUNTERS_PERIOD_S
        if self.intake.write(json.dumps({"op": "counters", "token": 0, **counters}).encode()):
            self._sent_counters = counters


def main(argv: list[str] | None = None) -> int:
    """Serve the robot named on the command line; one JSON line on stdout says it is ready or why not."""
    argv = sys.argv[1:] if argv is None else argv
    os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))  # not the real-time policy of the driver's threads
    stop = begin("command_service")
    robot_id = argv[0]
    try:
        channels = RobotChannels.attach_service(robot_id)
        server = listen(robot_id)
    except PlemError as error:
        announce({"ready": False, "error": error.to_dict()})
        return 1
    try:
        service = CommandService(channels, server, channels.state.header.cycle_time_ns * 1e-9)
        announce({"ready": True})
        service.run(stop)
    finally:
        server.close()
        remove_own_socket(robot_id)
        channels.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
