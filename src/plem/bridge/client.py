"""The Python bridge: watch and command a running robot from any process on the same host.

`connect(robot_id)` maps the robot's shared memory. Reading state never talks to the driver; commands
are validated here, then sent over the robot's command socket to its command service, which checks them
again, plans them and answers on the same connection.
The client API mirrors `plem.robot.Robot`, so a script moves between in-process and launched robots.
"""

from __future__ import annotations

import json
import os
import select
import socket
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any, Generic, Protocol, TypeVar

import numpy as np

from plem.bridge.planning import PlannerLink, PlanningCalls
from plem.bridge.reactions import ReactionCalls, settle_then_average
from plem.bridge.streaming import StreamingCalls
from plem.control.commands import CommandTimeout
from plem.control.events import Event, newest_fault
from plem.control.limits import ArmLimits
from plem.control.modes import Mode
from plem.control.reactions import Action, Condition, reaction_json
from plem.control.state import JointState
from plem.control.streaming import StreamBlock, stream_block_name
from plem.control.trajectory import JointTrajectory, TrajectoryTolerances
from plem.core import arguments
from plem.errors import CommandRejected, PlemError
from plem.ipc import command_socket
from plem.ipc.channels import RobotChannels
from plem.ipc.command_socket import CommandSocketError, FrameReader, frame
from plem.ipc.records import RawSample, event_from_record
from plem.ipc.request_bounds import MAX_REQUEST_BYTES
from plem.ipc.requests import (
    check_request,
    encode,
    error_from_json,
    new_request_id,
    result_from_json,
    tolerances_json,
    until_json,
)
from plem.ipc.ring import RingReader
from plem.ipc.robot_description import read_description

DEFAULT_ROBOT_ID = "indy"
POLL_S = 0.0005
LIVENESS_PERIOD_NS = 50_000_000  # how often a waiting stream checks that the driver still runs
ACCEPT_TIMEOUT_S = 5.0
#: Extra wait for acceptance per trajectory point: re-timing costs up to about 1.2 ms per point (BENCHMARKS.md).
RETIMING_S_PER_POINT = 0.004
SEND_TIMEOUT_S = 5.0


class DriverGone(PlemError):
    """The robot's RT driver is gone: its process ended or its heartbeat in shared memory stopped."""


class Stamped(Protocol):
    """A record with the CLOCK_MONOTONIC time it was made at (samples and events)."""

    @property
    def monotonic_ns(self) -> int:
        """When the record was made (CLOCK_MONOTONIC, ns)."""
        ...


if TYPE_CHECKING:
    from plem.control.kinematics import ArmDynamics

T = TypeVar("T", bound=Stamped)


def default_robot_id() -> str:
    """PLEM_ROBOT_ID (set by `plem launch` for its components), else 'indy' as in the spec."""
    return os.environ.get("PLEM_ROBOT_ID") or DEFAULT_ROBOT_ID


def connect(robot_id: str | None = None, expected_dof: int | None = None) -> RobotClient:
    """A client of the running robot `robot_id`; `expected_dof` makes a DOF mismatch an error right away."""
    if robot_id is not None:
        arguments.text(robot_id, "robot_id")
    if expected_dof is not None:
        arguments.whole(expected_dof, "expected_dof", low=1)
    return RobotClient(RobotChannels.attach(robot_id or default_robot_id(), expected_dof))


class Stream(Generic[T]):
    """Records of one ring as they arrive, oldest first.

    Iteration ends after `timeout` s without a record (0: once nothing is left to read; None: never), and
    with `duration` at the first record made more than `duration` s after the stream was opened, or once
    that time has passed without one. While it waits for a record it raises DriverGone if the driver is gone.
    """

    def __init__(self, reader: RingReader, read: Callable[[], Any], convert: Callable[[Any], T],
                 timeout: float | None, duration: float | None, check_driver: Callable[[], object]) -> None:
        timeout = arguments.optional_seconds(timeout, "timeout")
        duration = arguments.optional_seconds(duration, "duration")
        self._reader = reader
        self._read = read
        self._convert = convert
        self._timeout_ns = None if timeout is None else timeout * 1e9
        self._end_ns = None if duration is None else time.monotonic_ns() + duration * 1e9
        self._check_driver = check_driver
        self._next_check = 0

    @property
    def dropped(self) -> int:
        """Records the loop wrote that this stream lost because it read too slowly."""
        return self._reader.dropped

    def __iter__(self) -> Stream[T]:
        return self

    def __next__(self) -> T:
        waiting_since = time.monotonic_ns()
        while (record := self._read()) is None:
            now = time.monotonic_ns()
            if self._ended(now) or (self._timeout_ns is not None and now - waiting_since >= self._timeout_ns):
                raise StopIteration
            if now >= self._next_check:
                self._check_driver()
                self._next_check = now + LIVENESS_PERIOD_NS
            time.sleep(POLL_S)
        item = self._convert(record)
        if self._ended(item.monotonic_ns):
            raise StopIteration
        return item

    def _ended(self, monotonic_ns: float) -> bool:
        return self._end_ns is not None and monotonic_ns > self._end_ns


class RemoteHandle:
    """One command sent to the driver: wait for acceptance (done on send) and for its result."""

    def __init__(self, client: RobotClient, request_id: str, description: str) -> None:
        self._client = client
        self.id = request_id
        self.description = description
        self.accepted = False
        #: What the driver said on accepting the command (a stream's session), or None.
        self.accepted_result: Any = None
        self.reply: dict[str, Any] | None = None

    @property
    def done(self) -> bool:
        """True once the driver's final answer (finished, failed or rejected) arrived."""
        self._client._collect()
        return self.reply is not None

    def wait_accepted(self, timeout: float | None = ACCEPT_TIMEOUT_S) -> None:
        """Block until the driver took the command; raises its rejection."""
        timeout = arguments.optional_seconds(timeout, "timeout")
        self._client._wait(self, lambda: self.accepted or self.reply is not None, timeout, "accepted")
        if self.reply is not None and self.reply["stage"] == "rejected":
            raise error_from_json(self.reply["error"])

    def cancel(self) -> RemoteHandle:
        """Stop this motion if it still runs; a motion that replaced it is left alone."""
        return self._client._send("stop", {"goal": self.id})

    def wait(self, timeout: float | None = None) -> Any:
        """Block until the command finished; returns its result, raises on rejection, abort or fault.

        The result has the types the in-process robot's handles return: a TrajectoryResult whose
        error_code is an ErrorCode, or the Mode reached.
        """
        timeout = arguments.optional_seconds(timeout, "timeout")
        self._client._wait(self, lambda: self.reply is not None, timeout, "finished")
        reply = self.reply
        assert reply is not None  # _wait returned, so the condition holds; a reply is never taken back
        if reply["error"] is not None:
            raise error_from_json(reply["error"])
        return result_from_json(reply["result"])


class RemoteSimulator:
    """A launched simulated arm's control interface, through its command service (bus:=mock only)."""

    def __init__(self, client: RobotClient) -> None:
        self._client = client

    def push(self, link: str, force: Sequence[float] = (0.0, 0.0, 0.0), torque: Sequence[float] = (0.0, 0.0, 0.0),
             point: Sequence[float] = (0.0, 0.0, 0.0)) -> None:
        """Push a link: a force (N) at `point` (m, link frame) and a torque (N·m), base-frame axes, until release()."""
        self._client._send("simulate", {"action": "push", "link": link, "force": list(force), "torque": list(torque),
                                        "point": list(point)}).wait(ACCEPT_TIMEOUT_S)

    def release(self) -> None:
        """End a push."""
        self._client._send("simulate", {"action": "release"}).wait(ACCEPT_TIMEOUT_S)

    def set_digital_inputs(self, joint: int, value: int) -> None:
        """What a joint's drive reports as its digital inputs (0x60FD), as MockBus.set_digital_inputs."""
        self._client._send("simulate", {"action": "digital_inputs", "joint": joint, "value": value}
                           ).wait(ACCEPT_TIMEOUT_S)

    def mount_payload(self, mass: float, center_of_mass: Sequence[float] = (0.0, 0.0, 0.0)) -> None:
        """Add a point-mass payload at the simulated arm's flange (mass 0 takes it off)."""
        self._client._send("simulate", {"action": "mount_payload", "mass": mass,
                                        "center_of_mass": list(center_of_mass)}).wait(ACCEPT_TIMEOUT_S)


class RobotClient(PlanningCalls, StreamingCalls, ReactionCalls):
    """A connection to one robot's shared memory (see `connect`), and through it to its planner."""

    def __init__(self, channels: RobotChannels) -> None:
        self.channels = channels
        self.robot_id = channels.robot_id
        header = channels.state.header
        self.joint_names: tuple[str, ...] = header.joint_names
        self.dof = header.dof
        self.cycle_time_s = header.cycle_time_ns * 1e-9
        self.limits: ArmLimits = channels.state.limits
        self._socket: socket.socket | None = None
        self._frames = FrameReader()
        self._handles: dict[str, RemoteHandle] = {}
        self._lock = threading.RLock()
        self._stream_view: StreamBlock | None = None

    def _new_planner_link(self) -> PlannerLink:
        """The robot's planner process, on its socket."""
        return PlannerLink(self.robot_id)

    def _planning_joints(self) -> tuple[str, ...]:
        return self.joint_names

    def close(self) -> None:
        """Drop the command connection and unmap the robot's shared memory (the robot runs on)."""
        with self._lock:
            self._disconnect()
        self._close_planner()
        if self._stream_view is not None:
            self._stream_view.close()
        self.channels.close()

    def __enter__(self) -> RobotClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- state -------------------------------------------------------------------------------------
    def state(self) -> JointState | None:
        """The latest cycle's state (None before the first cycle); DriverGone once the driver is gone."""
        segment = self.channels.state
        state = segment.block.read()
        reason = segment.driver_gone(state)
        if reason is not None:
            raise self._gone(reason)
        return state

    def live_state(self) -> JointState:
        """The latest cycle's state; DriverGone also before the first cycle."""
        state = self.state()
        if state is None:
            raise self._gone("it has not published a cycle yet")
        return state

    def _gone(self, why: str) -> DriverGone:
        return DriverGone(f"the RT driver of robot '{self.robot_id}' is not running",
                          what="a running driver: its process alive and a heartbeat in shared memory every cycle",
                          why=why, how="start the robot with `plem launch` (bus:=mock for the simulated arm)")

    def wait_for_state(self, timeout: float = 1.0, after_cycle: int = 0) -> JointState | None:
        """Block until a state newer than `after_cycle` is published; None on timeout; DriverGone as state()."""
        deadline = time.monotonic() + arguments.seconds(timeout, "timeout")
        after_cycle = arguments.whole(after_cycle, "after_cycle")
        while True:
            state = self.state()
            if state is not None and state.cycle > after_cycle:
                return state
            if time.monotonic() > deadline:
                return None
            time.sleep(POLL_S)

    def stream(self, timeout: float | None = None, duration: float | None = None) -> Stream[RawSample]:
        """Every cycle's rt_raw sample from now on, in order.

        `duration`: the samples of the cycles of the next `duration` seconds, then the stream ends.
        `timeout`: the stream ends after that long without a sample (0: once it read what is there).
        A consumer slower than the loop loses the oldest samples; the stream's `dropped` counts them.
        """
        reader = self.channels.rings["rt_raw"].reader()
        return Stream(reader, reader.read_values, lambda record: RawSample.from_record(record, self.dof), timeout,
                      duration, self.state)

    def events(self, timeout: float | None = None, duration: float | None = None, *,
               from_oldest: bool = False) -> Stream[Event]:
        """Events (mode changes, faults, motions) as they happen; `timeout` and `duration` as for `stream`."""
        reader = self.channels.rings["events"].reader(from_oldest=arguments.flag(from_oldest, "from_oldest"))
        return Stream(reader, reader.read, event_from_record, timeout, duration, self.state)

    def faults(self) -> list[Event]:
        """The driver's fault history, oldest first: faults and their clearing, which no other event pushes out.

        It stays readable after the driver is gone.
        """
        return [event_from_record(record)
                for record in self.channels.rings["faults"].reader(from_oldest=True).read_all()]

    def last_fault(self) -> Event | None:
        """The newest fault, also when it was cleared since (None when the arm never faulted)."""
        return newest_fault(self.faults())

    def stats(self) -> dict[str, Any] | None:
        """The newest loop statistics record (timing, overruns, command counters), or None before the first.

        Raises DriverGone once the driver is gone, as `state()` does.
        """
        self.state()  # the liveness check
        record = self.channels.rings["stats"].newest()
        return None if record is None else json.loads(record)

    # -- streaming and the speed override ------------------------------------------------------------
    def _stream_arm(self) -> tuple[ArmLimits, tuple[str, ...]]:
        return self.limits, self.joint_names

    def _stream_block(self) -> StreamBlock:
        """The driver's stream block, mapped on first use (owner-only: this user's or root's driver)."""
        if self._stream_view is None:
            self._stream_view = StreamBlock.attach(stream_block_name(self.robot_id), self.dof)
        return self._stream_view

    def _stream_dynamics(self) -> ArmDynamics:
        """The arm's kinematics, from the URDF its launch shares (pinocchio is imported here, on first use)."""
        from plem.control.kinematics import ArmDynamics
        return ArmDynamics(read_description(self.robot_id).urdf, self.joint_names)

    def _stream_cycle_time(self) -> float:
        return self.cycle_time_s

    def _open_stream(self, timeout_s: float) -> tuple[int, RemoteHandle]:
        self._stream_block()
        handle = self._send("stream", {"timeout": timeout_s}, accept_within=ACCEPT_TIMEOUT_S)
        if handle.reply is not None:   # answered at once: refused, or ended already
            handle.wait(0)
        return int(handle.accepted_result["session"]), handle

    def _request_speed_override(self, factor: float) -> RemoteHandle:
        return self._send("speed_override", {"factor": factor})

    # -- reactions, the payload and the simulator ----------------------------------------------------------
    def _arm_reaction(self, condition: Condition, action: Action, once: bool) -> int:
        handle = self._send("react", {"reaction": reaction_json(condition, action), "once": once},
                            accept_within=ACCEPT_TIMEOUT_S)
        return int(handle.accepted_result["reaction"])

    def _remove_reaction(self, token: int) -> None:
        self._send("unreact", {"reaction": token}).wait(ACCEPT_TIMEOUT_S)

    def _send_payload(self, body: np.ndarray) -> None:
        self._send("payload", {"body": body.tolist()}).wait(ACCEPT_TIMEOUT_S)

    def _payload_dynamics(self) -> tuple[ArmDynamics, ArmLimits]:
        return self._stream_dynamics(), self.limits

    def _hold_at(self, pose: np.ndarray) -> None:
        self.move_joints(pose.tolist()).wait(60.0)

    def _mean_state(self, seconds: float) -> tuple[np.ndarray, np.ndarray]:
        return settle_then_average(self.live_state, time.sleep, seconds, self.cycle_time_s * 10)

    @property
    def simulator(self) -> RemoteSimulator:
        """The simulated arm's control interface (push a link, mount a payload), as `Robot.simulator` gives it
        in-process; the driver refuses it on a real bus."""
        return RemoteSimulator(self)

    # -- commands ----------------------------------------------------------------------------------
    def move_joints(self, target: Sequence[float], speed_scale: float = 1.0,
                    tolerances: TrajectoryTolerances | Mapping[str, Any] | None = None,
                    until: Condition | None = None) -> RemoteHandle:
        """Time-optimal jerk-limited motion to `target` (rad); returns once the driver accepted it.

        `speed_scale` in [MIN_SPEED_SCALE, 1] (plem.ipc.request_bounds) scales time: 0.5 takes twice as long.
        With `until` (plem.control.reactions), the motion stops as soon as the condition holds, and succeeds.
        """
        return self._send("move_joints", {"target": list(arguments.reals(target, "target")),
                                          "speed_scale": arguments.real(speed_scale, "speed_scale"),
                                          "tolerances": _tolerances(tolerances), **until_json(until)},
                          accept_within=ACCEPT_TIMEOUT_S)

    def execute_trajectory(self, trajectory: JointTrajectory,
                           tolerances: TrajectoryTolerances | Mapping[str, Any] | None = None,
                           until: Condition | None = None) -> RemoteHandle:
        """Follow a JointTrajectory (ros2_control spline semantics); returns once the driver accepted it.

        A trajectory that would break a limit is re-timed first (about a millisecond per point), so the wait
        for acceptance grows with the number of points. `until` as for `move_joints`.
        """
        arguments.instance(trajectory, JointTrajectory, "trajectory", "a JointTrajectory (plem.control.trajectory)")
        points = [{"positions": list(p.positions), "time_from_start": p.time_from_start,
                   **({"velocities": list(p.velocities)} if p.velocities is not None else {}),
                   **({"accelerations": list(p.accelerations)} if p.accelerations is not None else {})}
                  for p in trajectory.points]
        request = {"joint_names": list(trajectory.joint_names), "points": points, "tolerances": _tolerances(tolerances),
                   **until_json(until)}
        return self._send("execute_trajectory", request,
                          accept_within=ACCEPT_TIMEOUT_S + RETIMING_S_PER_POINT * len(points))

    def set_mode(self, mode: str | Mode, timeout: float = 5.0) -> Mode:
        """Change mode (idle, hold, free_drive) and wait until it took effect."""
        timeout = arguments.seconds(timeout, "timeout")
        return Mode(self.request_mode(mode).wait(timeout))

    def request_mode(self, mode: str | Mode) -> RemoteHandle:
        """Ask for a mode change without waiting; the handle's result is the mode reached."""
        arguments.instance(mode, (str, Mode), "mode", "a mode name (idle, hold, free_drive) or a Mode")
        return self._send("set_mode", {"mode": Mode.parse(mode).name.lower()})

    def reset_fault(self, timeout: float = 5.0) -> Mode:
        """Clear a fault: fault-reset the drives, re-enable them, hold where the arm is."""
        timeout = arguments.seconds(timeout, "timeout")
        return Mode(self.request_reset().wait(timeout))

    def request_reset(self) -> RemoteHandle:
        """Ask for a fault reset without waiting; the handle's result is the mode reached (HOLD)."""
        return self._send("reset_fault", {})

    def stop(self) -> RemoteHandle:
        """Cancel the running motion with a jerk-limited stop; the arm then holds."""
        return self._send("stop", {})

    def wait_until_idle(self, timeout: float = 30.0) -> None:
        """Block until no motion runs (mode is not TRAJECTORY)."""
        deadline = time.monotonic() + arguments.seconds(timeout, "timeout")
        while True:
            state = self.live_state()
            if state.mode is not Mode.TRAJECTORY:
                return
            if time.monotonic() > deadline:
                raise PlemError("the robot is still moving", what=f"motion to end within {timeout} s",
                                why=f"mode {state.mode.name}", how="wait longer or call stop()")
            time.sleep(0.002)

    def _send(self, op: str, args: dict[str, Any], accept_within: float | None = None) -> RemoteHandle:
        """Send one request; with `accept_within`, wait that many seconds for the driver to accept it."""
        payload = {"id": new_request_id(), "op": op, **{k: v for k, v in args.items() if v is not None}}
        check_request(payload, self.limits)  # the command service checks the same again
        record = encode(payload)
        if len(record) > MAX_REQUEST_BYTES:
            raise CommandRejected("the request is too large", what=f"at most {MAX_REQUEST_BYTES} bytes",
                                  why=f"it takes {len(record)} bytes", how="send fewer trajectory points")
        self.live_state()
        handle = RemoteHandle(self, payload["id"], op)
        with self._lock:  # answers are read under this lock too, so registering after sending loses none
            try:
                self._write(frame(record))
            except CommandSocketError:  # the command service was restarted: one new connection, one retry
                self._write(frame(record))
            self._handles[handle.id] = handle
        if accept_within is not None:
            handle.wait_accepted(accept_within)
        return handle

    def _connection(self) -> socket.socket:
        if self._socket is None:
            self._socket = command_socket.connect(self.robot_id)
            self._frames = FrameReader()
        return self._socket

    def _write(self, data: bytes) -> None:
        """Send all of `data`, waiting at most SEND_TIMEOUT_S for a command service that does not read."""
        connection = self._connection()
        view = memoryview(data)
        deadline = time.monotonic() + SEND_TIMEOUT_S
        while view:
            try:
                view = view[connection.send(view):]
                continue
            except BlockingIOError:
                pass
            except OSError as error:
                self._lost(f"sending failed: {error.strerror}")
                raise CommandSocketError("the command service closed the connection",
                                         what="a running command service", why=str(error.strerror),
                                         how="retry; check the robot with `plem state`") from None
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise CommandTimeout("the command service does not take the request",
                                     what=f"the request sent within {SEND_TIMEOUT_S:g} s",
                                     why="the command service is not reading", how="check the robot with `plem state`")
            select.select([], [connection], [], remaining)

    def _collect(self) -> None:
        """Route the answers that arrived to this client's handles."""
        with self._lock:
            if self._socket is None:
                return
            while True:
                try:
                    data = self._socket.recv(1 << 16)
                except BlockingIOError:
                    return
                except OSError as error:
                    data, reason = b"", error.strerror or str(error)
                else:
                    reason = "the command service closed the connection"
                if not data:
                    self._lost(reason)
                    return
                for record in self._frames.feed(data):
                    self._route(json.loads(record))

    def _route(self, reply: dict[str, Any]) -> None:
        request_id = reply.get("id")
        handle = self._handles.get(request_id) if isinstance(request_id, str) else None
        if handle is None:
            return
        if reply["stage"] == "accepted":
            handle.accepted = True
            handle.accepted_result = reply.get("result")
        else:
            handle.reply = reply
            del self._handles[handle.id]

    def _lost(self, reason: str) -> None:
        """The connection ended: every command still waiting fails with the reason (the arm is not affected)."""
        error = DriverGone("the connection to the command service was lost",
                           what="answers to the commands sent", why=reason,
                           how="check the robot with `plem state` and send the command again")
        for handle in self._handles.values():
            handle.reply = {"id": handle.id, "stage": "failed", "result": None, "error": error.to_dict()}
        self._handles.clear()
        self._disconnect()

    def _disconnect(self) -> None:
        if self._socket is not None:
            self._socket.close()
            self._socket = None

    def _wait(self, handle: RemoteHandle, condition: Callable[[], bool], timeout: float | None, stage: str) -> None:
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            self._collect()
            if condition():
                return
            self.live_state()
            if deadline is not None and time.monotonic() > deadline:
                raise CommandTimeout(f"{handle.description} was not {stage} in {timeout} s",
                                     what=f"the driver to answer within {timeout} s", why="no reply yet",
                                     how="wait longer, or check the robot with `plem state`")
            with self._lock:
                connection = self._socket
            try:
                select.select([connection] if connection is not None else [], [], [], POLL_S)
            except (OSError, ValueError):  # closed meanwhile by another thread: the next _collect() says why
                time.sleep(POLL_S)


def _tolerances(tolerances: TrajectoryTolerances | Mapping[str, Any] | None) -> dict[str, Any] | None:
    """Tolerances as a request carries them (their contents are checked with the request)."""
    if tolerances is None or isinstance(tolerances, Mapping):
        return None if tolerances is None else dict(tolerances)
    arguments.instance(tolerances, TrajectoryTolerances, "tolerances",
                       "a TrajectoryTolerances, a dict with keys path, goal, goal_time, stopped_velocity_tolerance, "
                       "or None")
    return tolerances_json(tolerances)
