"""Nothing a client sends can stall or fault the loop, silence the command service or command the wrong goal.

Each test is an attack on a launched simulated arm: very large valid trajectories, floods of oversized
invalid requests, absurd request ids and numbers, stalled and foreign clients, a killed command service,
and a cancel that races a preemption.
"""

from __future__ import annotations

import math
import os
import signal
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from plem.bridge import connect
from plem.bridge.client import RobotClient
from plem.control.events import EventKind
from plem.control.modes import Mode
from plem.control.trajectory import JointTrajectory, TrajectoryOutcome
from plem.errors import CommandRejected, PlemError
from plem.ipc.request_bounds import MAX_TEXT_CHARS
from tests.e2e.cli import run_plem
from tests.e2e.command_wire import RawConnection
from tests.e2e.launched import (
    Launch,
    as_nobody,
    clean_environment,
    launched,
    launched_robot,
    new_robot_id,
    python_client,
    read_line,
    remove_shm,
    system_python,
    wait_until,
)

NOBODY = 65534


@pytest.fixture(scope="module")
def robot(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Launch]:
    with launched_robot(tmp_path_factory, "bridge:=false", "record:=false") as launch:
        yield launch


@pytest.fixture
def client(robot: Launch) -> Iterator[RobotClient]:
    assert robot.process.poll() is None, robot.describe()
    with connect(robot.robot_id) as connected:
        connected.set_mode("hold")
        connected.wait_until_idle(30)
        yield connected


def faults(events: list) -> list:
    return [event for event in events if event.kind is EventKind.FAULT]


def slow_wave(client: RobotClient, points: int, duration: float, amplitude: float = 0.05,
              lead: float = 0.0) -> JointTrajectory:
    """A valid trajectory of `points` quintic points: joint 0 moves by `amplitude` on a cycloid, at rest at both ends.

    With `lead`, the points start that many seconds later, so the arm may be moving when it begins.
    """
    start = client.state().command_position.copy()
    direction = -1.0 if start[0] > 0 else 1.0
    rows = []
    for i in range(1, points + 1):
        t = duration * i / points
        phase = 2 * math.pi * t / duration
        position, velocity, acceleration = start.copy(), np.zeros(client.dof), np.zeros(client.dof)
        position[0] += direction * amplitude * (t / duration - math.sin(phase) / (2 * math.pi))
        if i < points:
            velocity[0] = direction * amplitude / duration * (1 - math.cos(phase))
            acceleration[0] = direction * amplitude / duration * 2 * math.pi / duration * math.sin(phase)
        rows.append({"positions": position.tolist(), "time_from_start": lead + t, "velocities": velocity.tolist(),
                     "accelerations": acceleration.tolist()})
    return JointTrajectory.from_lists(client.joint_names, rows)


def test_a_3000_point_trajectory_runs_without_faulting_the_loop(client: RobotClient):
    events = client.events(timeout=0)
    before = client.stats()["cycles"]
    handle = client.execute_trajectory(slow_wave(client, 3000, 3.0))
    result = handle.wait(30)
    assert result.outcome is TrajectoryOutcome.SUCCEEDED, result
    assert not faults(list(events))
    assert client.state().mode is Mode.HOLD
    assert client.stats()["cycles"] > before + 3000


def test_a_flood_of_oversized_invalid_requests_is_refused_without_faulting_the_loop(client: RobotClient):
    events = client.events(timeout=0)
    position = client.state().position.copy()
    outside = (client.limits.max_position + 0.5).tolist()
    points = [{"positions": position.tolist(), "time_from_start": 0.001 * (i + 1),
               "velocities": [0.0] * client.dof, "accelerations": [0.0] * client.dof} for i in range(2400)]
    points[-1]["positions"] = outside  # invalid only at the very end, so all of it is read
    request = {"op": "execute_trajectory", "joint_names": list(client.joint_names), "points": points}
    connection = RawConnection(client.robot_id)
    try:
        for i in range(20):
            connection.send({"id": f"flood-{i}", **request})
        answers = connection.answers(20, timeout=60)
    finally:
        connection.close()
    assert len(answers) == 20 and {answer["stage"] for answer in answers} == {"rejected"}
    assert all("outside the position limits" in answer["error"]["summary"] for answer in answers)
    assert not faults(list(events))
    assert np.allclose(client.state().position, position, atol=1e-6)


def test_an_oversized_request_id_gets_a_bounded_answer_and_a_stop_still_arrives(client: RobotClient):
    events = client.events(timeout=0)
    state = client.state()
    target = state.position.copy()
    target[0] += -0.5 if target[0] > 0 else 0.5
    motion = client.move_joints(target, speed_scale=0.05)   # many seconds long
    connection = RawConnection(client.robot_id)
    try:
        connection.send({"id": "x" * 5000, "op": "set_mode", "mode": "hold"})
        connection.send({"id": "y", "op": "move_joints", "target": [0.0] * client.dof, "junk" + "z" * 50_000: 1})
        answers = connection.answers(2)
    finally:
        connection.close()
    assert [answer["stage"] for answer in answers] == ["rejected", "rejected"]
    assert "request id is malformed" in answers[0]["error"]["summary"]
    assert all(len(text) <= MAX_TEXT_CHARS for answer in answers for text in answer["error"].values()
               if isinstance(text, str))
    assert client.state().mode is Mode.TRAJECTORY
    client.stop().wait(5)
    assert motion.wait(5).outcome is TrajectoryOutcome.CANCELED
    client.wait_until_idle(10)
    assert not faults(list(events))


def test_a_stalled_or_silent_client_blocks_no_one(robot: Launch, client: RobotClient):
    stalled = python_client("""
        import os, signal, socket, struct, sys
        from plem.ipc.command_socket import socket_path
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        sock.connect(str(socket_path(sys.argv[1])))
        sock.sendall(struct.pack("<I", 1000) + b'{"id": "half')   # half a frame, then frozen
        print("sent", flush=True)
        os.kill(os.getpid(), signal.SIGSTOP)
    """, robot.robot_id)
    deaf = python_client("""
        import json, socket, struct, sys, time
        from plem.ipc.command_socket import frame, socket_path
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        sock.connect(str(socket_path(sys.argv[1])))
        request = json.dumps({"id": "deaf", "op": "stop", "pad": "p" * 60_000}).encode()
        for _ in range(200):                      # answers pile up: it never reads them
            sock.sendall(frame(request))
        print("sent", flush=True)
        time.sleep(120)
    """, robot.robot_id)
    try:
        assert read_line(stalled, 30) == "sent\n" and read_line(deaf, 60) == "sent\n"
        assert client.set_mode("hold", timeout=5) is Mode.HOLD
        target = client.state().position.copy()
        target[1] += -0.1 if target[1] > 0 else 0.1
        assert client.move_joints(target).wait(30).outcome is TrajectoryOutcome.SUCCEEDED
    finally:
        for process in (stalled, deaf):
            process.kill()
            process.wait(10)


def test_numbers_beyond_their_range_are_refused_before_the_driver(client: RobotClient):
    target = client.state().position.tolist()
    with pytest.raises(CommandRejected, match="goal_time is out of range"):
        client.move_joints(target, tolerances={"goal_time": 1e306})
    connection = RawConnection(client.robot_id)
    try:
        connection.send({"id": "big", "op": "move_joints", "target": target, "tolerances": {"goal_time": 1e306}})
        connection.send(b'{"id": "huge", "op": "move_joints", "target": [1' + b"0" * 400 + b', 0, 0, 0, 0, 0]}')
        connection.send({"id": "bool", "op": "move_joints", "target": [True] + target[1:]})
        answers = connection.answers(3)
    finally:
        connection.close()
    assert [answer["stage"] for answer in answers] == ["rejected"] * 3
    assert [answer["error"]["summary"] for answer in answers] == [
        "goal_time is out of range", "the target is out of range", "the target is not a number"]
    assert client.state().mode is Mode.HOLD


def test_a_cancel_names_its_goal_and_spares_the_goal_that_replaced_it(client: RobotClient):
    for _ in range(5):
        first = client.execute_trajectory(slow_wave(client, 50, 2.0))
        second = client.execute_trajectory(slow_wave(client, 50, 1.0, amplitude=0.03, lead=0.5))
        first.cancel()                                        # arrives a few ms after the preemption
        assert first.wait(5).outcome is TrajectoryOutcome.PREEMPTED
        assert second.wait(20).outcome is TrajectoryOutcome.SUCCEEDED
        client.wait_until_idle(10)


def test_the_command_service_runs_at_ordinary_priority(robot: Launch):
    """Its work grows with what clients send: it must never compete at the driver threads' real-time policy."""
    service = command_service_pid(robot.driver_pids()[robot.robot_id])
    assert service is not None and os.sched_getscheduler(service) == os.SCHED_OTHER


def test_a_killed_command_service_is_restarted_and_the_arm_holds_meanwhile(robot: Launch, client: RobotClient):
    driver = robot.driver_pids()[robot.robot_id]
    service = command_service_pid(driver)
    position = client.state().position.copy()
    events = client.events(timeout=0)
    os.kill(service, signal.SIGKILL)
    assert wait_until(lambda: command_service_pid(driver) not in (None, service), 20), robot.describe()
    assert np.allclose(client.state().position, position, atol=1e-6)
    assert client.state().mode is Mode.HOLD and not faults(list(events))
    assert wait_until(lambda: answers_mode(client), 10)


def command_service_pid(driver: int) -> int | None:
    """The command service child of a driver process, if one runs (read from /proc)."""
    for entry in Path("/proc").iterdir():
        try:
            parent = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
            command = (entry / "cmdline").read_bytes()
        except (OSError, ValueError, IndexError):
            continue
        if parent == driver and b"plem.launch.command_service" in command:
            return int(entry.name)
    return None


def answers_mode(client: RobotClient) -> bool:
    try:
        return client.set_mode("hold", timeout=2) is Mode.HOLD
    except PlemError:
        return False


needs_root = pytest.mark.skipif(os.geteuid() != 0 or system_python() is None,
                                reason="acting as another user needs root and a system Python of the tests' version")


@needs_root
def test_another_user_in_shm_group_may_watch_but_cannot_command_or_block(tmp_path: Path):
    robot_id = new_robot_id()
    with launched(["bus:=mock", f"robot_id:={robot_id}", "bridge:=false", "record:=false",
                   f"shm_group:={NOBODY}"], [robot_id], tmp_path, clean_environment(tmp_path / "home")), \
            connect(robot_id) as client:
        outsider = as_nobody("""
            import fcntl, glob, os, sys, time
            from plem.bridge import connect
            from plem.errors import PlemError
            robot = connect(sys.argv[1])
            print("watching", robot.state().cycle > 0, flush=True)
            held = []
            for path in glob.glob(f"/dev/shm/{sys.argv[1]}_*"):
                try:
                    fd = os.open(path, os.O_RDONLY)
                    fcntl.flock(fd, fcntl.LOCK_EX)
                    held.append(fd)
                except OSError:
                    pass
            try:
                robot.set_mode("hold")
                print("commanded", flush=True)
            except PlemError as error:
                print("refused", error.summary, flush=True)
            time.sleep(60)
        """, robot_id)
        try:
            assert read_line(outsider, 30) == "watching True\n", outsider.stderr.read() if outsider.poll() else ""
            answer = read_line(outsider, 30)
            if not answer:
                outsider.kill()
            assert answer.startswith("refused cannot reach the command service"), answer or outsider.stderr.read()
            assert client.set_mode("hold", timeout=5) is Mode.HOLD
            assert client.set_mode("idle", timeout=5) is Mode.IDLE
        finally:
            outsider.kill()
            outsider.wait(10)


@needs_root
def test_a_command_socket_taken_by_another_user_stops_the_launch(tmp_path: Path):
    robot_id = new_robot_id()
    squatter = as_nobody("""
        import socket, sys, time
        s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        s.bind(f"/dev/shm/{sys.argv[1]}_commands")
        s.listen(4)
        print("bound", flush=True)
        time.sleep(120)
    """, robot_id)
    try:
        assert read_line(squatter, 20) == "bound\n"
        env = clean_environment(tmp_path / "home")
        result = run_plem("launch", "bus:=mock", f"robot_id:={robot_id}", "bridge:=false", "record:=false", env=env)
        assert result.returncode == 1, result.stdout + result.stderr
        assert "is taken" in result.stderr and f"owned by nobody (uid {NOBODY})" in result.stderr, result.stderr
    finally:
        squatter.kill()
        squatter.wait(10)
        remove_shm(robot_id)
