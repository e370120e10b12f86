"""The Python client against a real RT driver and its command service: wrong arguments give PlemErrors that say what
was expected, extreme numbers are refused in words, and floods of requests whose answer is known never reach the
driver."""

from __future__ import annotations

import json
import math
import socket
import struct
import time
import uuid
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import pytest

from plem.bridge import connect
from plem.bridge.client import RobotClient
from plem.control.modes import Mode
from plem.control.trajectory import JointTrajectory, TrajectoryPoint
from plem.core.arguments import ArgumentError
from plem.errors import CommandRejected, PlemError
from plem.ipc.command_socket import frame, socket_path
from plem.ipc.request_bounds import MIN_SPEED_SCALE
from plem.launch.command_service import COUNTERS_PERIOD_S, MAX_IN_FLIGHT
from plem.launch.plan import plan_robot
from plem.launch.rt_driver import Driver, driving
from tests.e2e.launched import wait_until


@pytest.fixture(scope="module")
def served() -> Iterator[tuple[Driver, RobotClient]]:
    """A simulated arm's RT driver with its command service, and a client of it; the arm holds."""
    robot_id = f"args_{uuid.uuid4().hex[:8]}"
    with driving(plan_robot({"bus": "mock", "robot_id": robot_id}, generate=False)) as driver, \
            connect(robot_id) as client:
        client.set_mode("hold")
        yield driver, client


@pytest.fixture
def client(served: tuple[Driver, RobotClient]) -> RobotClient:
    _, client = served
    if client.live_state().mode is not Mode.HOLD:
        client.reset_fault() if client.live_state().faulted else client.set_mode("hold")
    return client


def point(positions: Any, time_from_start: float = 1.0) -> dict[str, Any]:
    return {"positions": positions, "time_from_start": time_from_start}


CALLS: dict[str, Callable[[RobotClient], object]] = {
    "move_joints tolerances list": lambda c: c.move_joints([0.0] * 6, tolerances=[0.1] * 6),  # type: ignore[arg-type]
    "move_joints tolerances str": lambda c: c.move_joints([0.0] * 6, tolerances="abc"),  # type: ignore[arg-type]
    "move_joints huge ints": lambda c: c.move_joints([10**400] * 6),
    "move_joints str target": lambda c: c.move_joints("abc"),  # type: ignore[arg-type]
    "move_joints None target": lambda c: c.move_joints(None),  # type: ignore[arg-type]
    "move_joints str speed": lambda c: c.move_joints([0.0] * 6, speed_scale="fast"),  # type: ignore[arg-type]
    "execute_trajectory None": lambda c: c.execute_trajectory(None),  # type: ignore[arg-type]
    "execute_trajectory list": lambda c: c.execute_trajectory([point([0.0] * 6)]),  # type: ignore[arg-type]
    "execute_trajectory dict": lambda c: c.execute_trajectory({"points": []}),  # type: ignore[arg-type]
    "TrajectoryPoint positions None": lambda c: TrajectoryPoint(positions=None, time_from_start=1.0),  # type: ignore
    "TrajectoryPoint time str": lambda c: TrajectoryPoint((0.0,) * 6, "1"),  # type: ignore[arg-type]
    "from_lists ints": lambda c: JointTrajectory.from_lists(c.joint_names, [1, 2, 3]),  # type: ignore[list-item]
    "from_lists int names": lambda c: JointTrajectory.from_lists([1, 2], [point([0.0] * 2)]),  # type: ignore
    "from_lists int": lambda c: JointTrajectory.from_lists(c.joint_names, 5),  # type: ignore[arg-type]
    "set_mode timeout str": lambda c: c.set_mode("hold", timeout="x"),  # type: ignore[arg-type]
    "set_mode timeout nan": lambda c: c.set_mode("hold", timeout=math.nan),
    "set_mode mode None": lambda c: c.set_mode(None),  # type: ignore[arg-type]
    "stream duration str": lambda c: c.stream(duration="x"),  # type: ignore[arg-type]
    "stream duration nan": lambda c: c.stream(duration=math.nan),
    "stream timeout inf": lambda c: c.stream(timeout=math.inf),
    "events from_oldest str": lambda c: c.events(timeout=0, from_oldest="yes"),  # type: ignore[arg-type]
    "wait_for_state cycle float": lambda c: c.wait_for_state(0.1, after_cycle=1.5),  # type: ignore[arg-type]
    "wait_until_idle negative": lambda c: c.wait_until_idle(-1.0),
    "reset_fault timeout list": lambda c: c.reset_fault([]),  # type: ignore[arg-type]
    "connect robot_id int": lambda c: connect(5),  # type: ignore[arg-type]
}


@pytest.mark.parametrize("name", CALLS)
def test_wrong_arguments_raise_a_plem_error_saying_what_was_expected(client, name):
    with pytest.raises(PlemError) as caught:
        CALLS[name](client)
    error = caught.value
    assert isinstance(error, CommandRejected), error.render()
    assert error.what and error.why and error.how
    assert "object has no attribute" not in error.render() and "Traceback" not in error.render()
    assert client.live_state().mode is Mode.HOLD


def test_argument_errors_are_type_errors_too(client):
    with pytest.raises(TypeError):
        client.set_mode("hold", timeout="x")  # type: ignore[arg-type]
    with pytest.raises(ArgumentError, match="duration"):
        client.stream(duration=math.nan)


@pytest.mark.parametrize("scale", [MIN_SPEED_SCALE / 2, 1e-6, 1e-100, 5e-324])
def test_speed_scales_below_the_minimum_are_refused_naming_it(client, scale):
    with pytest.raises(CommandRejected) as caught:
        client.move_joints([0.1] * 6, speed_scale=scale)
    text = caught.value.render()
    assert "speed_scale" in text and f"{MIN_SPEED_SCALE:g}" in text, text
    assert "Result" not in text and "Ruckig" not in text and "could not be handled" not in text, text


def test_the_slowest_speed_scale_is_planned(client):
    start = client.live_state().position
    handle = client.move_joints(start + 0.01, speed_scale=MIN_SPEED_SCALE)
    handle.cancel().wait(10)
    assert client.live_state().mode is not Mode.FAULT


@pytest.mark.parametrize("time_from_start", [1e-100, 5e-324, 1e-10])
def test_a_point_less_than_a_nanosecond_after_the_start_is_refused_in_words(client, time_from_start):
    target = list(client.live_state().position + 0.2)
    trajectory = JointTrajectory.from_lists(client.joint_names, [point(target, time_from_start)])
    with pytest.raises(CommandRejected) as caught:
        client.execute_trajectory(trajectory)
    assert "time_from_start" in caught.value.render() and "1e-09" in caught.value.what
    state = client.live_state()
    assert state.mode is Mode.HOLD and not state.faulted


# -- floods --------------------------------------------------------------------------------------------------------
def flood(robot_id: str, requests: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Send every request on one connection at once, then read one answer per request (final stages only)."""
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sock:
        sock.connect(str(socket_path(robot_id)))
        sock.settimeout(30)
        sock.sendall(b"".join(frame(json.dumps(request).encode()) for request in requests))
        answers: list[dict[str, Any]] = []
        buffer = b""
        while len(answers) < len(requests):
            buffer += sock.recv(1 << 16)
            while len(buffer) >= 4 and len(buffer) >= 4 + (length := struct.unpack_from("<I", buffer)[0]):
                answer = json.loads(buffer[4:4 + length])
                buffer = buffer[4 + length:]
                if answer["stage"] != "accepted":
                    answers.append(answer)
    return answers


def driver_counts(client: RobotClient, until: Callable[[dict[str, int]], bool] = lambda counts: True
                  ) -> dict[str, int]:
    """The driver's command counters from a statistics record written after this call, once `until` holds for
    them (the command service passes its own counts on to the driver every 0.1 s: they arrive a little later)."""
    first = client.stats()
    assert wait_until(lambda: client.stats() != first and until(client.stats()["commands"]), 10), \
        client.stats()["commands"]
    return client.stats()["commands"]


def settled_counts(client: RobotClient) -> dict[str, int]:
    """The driver's command counters once two records three counter periods apart agree: nothing of an earlier
    request is still on its way to them."""
    previous: dict[str, int] = {}
    while (counts := driver_counts(client)) != previous:
        previous = counts
        time.sleep(3 * COUNTERS_PERIOD_S)   # the period of the condition: counts still arriving change within it
    return counts


def test_repeated_mode_requests_and_stops_are_answered_without_the_driver(client):
    before = settled_counts(client)
    requests = [{"id": f"f{i}", "op": "set_mode" if i % 2 else "stop", **({"mode": "hold"} if i % 2 else {})}
                for i in range(2000)]
    answers = flood(client.robot_id, requests)
    assert all(answer["stage"] == "finished" for answer in answers), answers[:3]
    assert {answer["result"] for answer in answers if answer["id"][1:].isdigit() and int(answer["id"][1:]) % 2} == \
        {"hold"}
    after = driver_counts(client, lambda counts: counts["answered_here"] - before["answered_here"] >= 2000)
    assert after["answered_here"] - before["answered_here"] == 2000
    assert after["finished"] == before["finished"] and after["accepted"] == before["accepted"]


def test_a_repeated_mode_change_shares_the_answer_of_the_one_on_its_way(client):
    client.set_mode("idle")
    try:
        before = settled_counts(client)
        answers = flood(client.robot_id, [{"id": f"h{i}", "op": "set_mode", "mode": "hold"} for i in range(200)])
        assert [answer["stage"] for answer in answers] == ["finished"] * 200, answers[:3]
        assert {answer["result"] for answer in answers} == {"hold"}
        after = driver_counts(client, lambda counts: counts["answered_here"] - before["answered_here"] >= 199
                              and counts["finished"] > before["finished"])
        assert after["finished"] - before["finished"] == 1 and after["answered_here"] - before["answered_here"] == 199
    finally:
        client.set_mode("hold")


def test_one_connection_has_a_bounded_number_of_mode_changes_waiting(client):
    modes = ["idle", "hold"] * 200
    answers = flood(client.robot_id, [{"id": f"m{i}", "op": "set_mode", "mode": mode} for i, mode in enumerate(modes)])
    refused = [answer for answer in answers if answer["stage"] == "rejected"
               and answer["error"]["summary"] == "too many requests of this connection wait for the robot"]
    assert refused and str(MAX_IN_FLIGHT) in refused[0]["error"]["what"]
    assert all(answer["error"]["how"] for answer in refused)
    client.set_mode("hold")
    assert np.all(np.isfinite(client.live_state().position))
