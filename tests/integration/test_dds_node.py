"""Services and actions over real Cyclone DDS between two processes, on a private domain per test."""

from __future__ import annotations

import gc
import os
import subprocess
import sys
import textwrap
import threading
import time
import uuid
from collections.abc import Iterator
from typing import Any

import pytest

from plem.middleware.action import CANCEL_UNKNOWN_GOAL, SUCCEEDED, UNKNOWN, ActionClient
from plem.middleware.names import ActionNames
from plem.middleware.node import Node
from plem.middleware.qos import LATCHED
from tests.conftest import fresh_domain

SERVICE, ACTION, SET_MODE = "/t/add", "/t/set_mode", "plem_msgs/action/SetMode"
CANCEL_GOAL = "action_msgs/srv/CancelGoal"

#: Serves /t/add (CancelGoal: return_code 2, the request's goal_info echoed) and /t/set_mode (SetMode: two
#: feedbacks, then SUCCEEDED with the goal's mode) until its stdin closes.
SERVER = textwrap.dedent(f"""
    import sys, threading, time
    from plem.middleware.action import ActionServer, SUCCEEDED
    from plem.middleware.node import Node

    node = Node()
    adder = node.service({SERVICE!r}, {CANCEL_GOAL!r})

    class Run:
        # Two feedbacks, then success once a get_result request waits for it (or after 3 s).

        def __init__(self, goal):
            self.mode, self.reported, self.end = goal.mode, 0, time.monotonic() + 3.0

        def poll(self):
            if self.reported < 2:
                if server._feedback.subscribers == 0:   # feedback is volatile: wait for the client's reader
                    return None, None
                self.reported += 1
                return {{"mode": f"{{self.mode}}:{{self.reported}}"}}, None
            asked = any(goal.execution is self and goal.waiting for goal in server._goals.values())
            if not asked and time.monotonic() < self.end:
                return None, None
            return None, (SUCCEEDED, {{"success": True, "mode": self.mode, "message": "done"}})

        def cancel(self):
            return False

    server = ActionServer(node, {ACTION!r}, {SET_MODE!r}, Run, feedback_period=0.0)
    stop = threading.Event()
    threading.Thread(target=lambda: (sys.stdin.read(), stop.set()), daemon=True).start()
    waitset = node.waitset([adder, *server.services])

    print("ready", flush=True)
    deadline = time.monotonic() + 60
    while not stop.is_set() and time.monotonic() < deadline:
        waitset.wait(10_000_000)
        adder.flush()
        for request in adder.take():
            adder.reply(request, return_code=2, goals_canceling=[request.goal_info])
        server.spin_once()
    node.close()
""")


@pytest.fixture
def domain(monkeypatch: pytest.MonkeyPatch) -> int:
    """A private domain for this test and every process it starts, discovered on this host only."""
    domain_id = fresh_domain()
    monkeypatch.setenv("ROS_DOMAIN_ID", str(domain_id))
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    return domain_id


@pytest.fixture
def server(domain: int) -> Iterator[subprocess.Popen[str]]:
    process = subprocess.Popen([sys.executable, "-c", SERVER], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True, env=dict(os.environ))
    errors = ""
    try:
        assert process.stdout is not None and process.stdout.readline() == "ready\n", process.stderr.read()
        yield process
    finally:
        try:
            errors = process.communicate(timeout=5)[1]   # closes stdin: the server stops
        except subprocess.TimeoutExpired:
            process.kill()
            errors = process.communicate()[1]
    assert process.returncode == 0, errors


@pytest.fixture
def node(domain: int) -> Iterator[Node]:
    node = Node()
    assert node.domain_id == domain
    yield node
    node.close()


def wait_until(condition: Any, timeout: float = 5.0) -> bool:
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.01)
    return True


def goal_info(node: Node, goal_id: bytes, sec: int) -> Any:
    lib = node.library
    return lib.new("action_msgs/msg/GoalInfo", goal_id=lib.new("unique_identifier_msgs/msg/UUID", uuid=list(goal_id)),
                   stamp=lib.new("builtin_interfaces/msg/Time", sec=sec, nanosec=sec * 1000))


def test_service_call(server: subprocess.Popen[str], node: Node) -> None:
    """A request crosses processes and its reply comes back with the request's content."""
    client = node.client(SERVICE, CANCEL_GOAL)
    assert wait_until(lambda: client.ready)
    goal_id = uuid.uuid4().bytes
    reply = client.call(5.0, goal_info=goal_info(node, goal_id, 1234))
    assert reply.return_code == 2
    assert reply.rmw_guid == client.guid and reply.rmw_seq == 1
    assert [(bytes(info.goal_id.uuid), info.stamp.sec, info.stamp.nanosec) for info in reply.goals_canceling] == \
        [(goal_id, 1234, 1_234_000)]
    assert client.call(5.0, goal_info=goal_info(node, goal_id, 5)).rmw_seq == 2


def test_server_outlives_its_clients(server: subprocess.Popen[str], node: Node) -> None:
    """When every client writer is gone the server's reader gets a no-data sample; it must skip it."""
    client = node.client(SERVICE, CANCEL_GOAL)
    assert wait_until(lambda c=client: c.ready)
    assert client.call(5.0, goal_info=goal_info(node, bytes(16), 1)).return_code == 2
    del client
    gc.collect()
    time.sleep(0.2)   # the writer's unregistration reaches the server
    later = node.client(SERVICE, CANCEL_GOAL)
    assert wait_until(lambda: later.ready)
    assert later.call(5.0, goal_info=goal_info(node, bytes(16), 2)).return_code == 2
    assert server.poll() is None


def test_two_clients_get_only_their_own_replies(server: subprocess.Popen[str], node: Node) -> None:
    """Both clients see every reply on the topic; each returns only those carrying its writer's guid."""
    first, second = node.client(SERVICE, CANCEL_GOAL), node.client(SERVICE, CANCEL_GOAL)
    assert first.guid != second.guid
    assert wait_until(lambda: first.ready and second.ready)
    # Same sequence numbers on both: without routing by guid, the second would take the first's reply.
    for sec in (1, 2):
        assert first.call(5.0, goal_info=goal_info(node, bytes(16), sec)).goals_canceling[0].stamp.sec == sec
        assert second.call(5.0, goal_info=goal_info(node, bytes(16), 100 + sec)).goals_canceling[0].stamp.sec == \
            100 + sec
    mixed: list[tuple[int, int]] = []

    def calls(client: Any, base: int) -> None:
        for sec in range(base, base + 5):
            reply = client.call(5.0, goal_info=goal_info(node, bytes(16), sec))
            mixed.append((sec, reply.goals_canceling[0].stamp.sec))

    threads = [threading.Thread(target=calls, args=(client, base)) for client, base in ((first, 10), (second, 20))]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout=20)
    assert sorted(mixed) == [(sec, sec) for sec in (*range(10, 15), *range(20, 25))]


def test_action_round_trip(server: subprocess.Popen[str], node: Node) -> None:
    """Goal, feedback, result, stored result, unknown-goal cancel, and the latched status for a late reader."""
    assert not ActionClient(node, "/t/nobody_serves_this", SET_MODE).wait_for_server(0.1)
    client = ActionClient(node, ACTION, SET_MODE)
    assert client.wait_for_server(5.0)
    assert wait_until(lambda: client.feedback.publishers > 0 and client.status.publishers > 0)

    goal_id, accepted = client.send_goal(mode="hold")
    assert accepted
    status, result = client.result(goal_id, timeout=5.0)   # the goal ends only once this request waits for it
    assert status == SUCCEEDED
    assert (result.success, result.mode, result.message) == (True, "hold", "done")

    feedback: list[str] = []

    def two_feedbacks() -> bool:
        feedback.extend(message.feedback.mode for message in client.feedback.take()
                        if bytes(message.goal_id.uuid) == goal_id)
        return len(feedback) >= 2
    assert wait_until(two_feedbacks, timeout=3.0)
    assert feedback == ["hold:1", "hold:2"]

    for _ in range(2):   # an ended goal's result stays available
        again_status, again = client.result(goal_id, timeout=5.0)
        assert (again_status, again.mode, again.success) == (SUCCEEDED, "hold", True)
    assert client.result(uuid.uuid4().bytes, timeout=5.0)[0] == UNKNOWN
    assert client.cancel(uuid.uuid4().bytes) == CANCEL_UNKNOWN_GOAL == 2

    late = node.subscription(ActionNames(ACTION).status, "action_msgs/msg/GoalStatusArray", LATCHED)
    statuses: dict[bytes, int] = {}

    def goal_succeeded() -> bool:
        for message in late.take():
            statuses.update({bytes(item.goal_info.goal_id.uuid): item.status for item in message.status_list})
        return statuses.get(goal_id) == SUCCEEDED
    assert wait_until(goal_succeeded, timeout=3.0), statuses


def test_second_goal_with_a_used_id_is_refused(server: subprocess.Popen[str], node: Node) -> None:
    """A goal id the server already knows is not accepted again."""
    client = ActionClient(node, ACTION, SET_MODE)
    assert client.wait_for_server(5.0)
    assert wait_until(lambda: client.feedback.publishers > 0)
    goal_id, accepted = client.send_goal(mode="idle")
    assert accepted
    assert client.result(goal_id, timeout=5.0)[1].mode == "idle"
    request = node.library.new(f"{SET_MODE}_Goal", mode="free_drive")
    reply = client._send_goal.call(5.0, goal_id=node.library.new("unique_identifier_msgs/msg/UUID",
                                                                 uuid=list(goal_id)), goal=request)
    assert reply.accepted is False
    assert client.result(goal_id, timeout=5.0)[1].mode == "idle"
