"""The launched planner under hostile requests: one long request never blocks it for others (they are told at
once that it is busy, with whose request and how long it has left), a cancel or a client that goes away ends a
running request, every field is checked at the socket with a WHAT/WHY/HOW, and no request ends a planner thread."""

from __future__ import annotations

import json
import os
import select
import threading
from collections.abc import Callable, Iterator
from typing import Any

import pytest

from plem.bridge.planning import PlannerLink
from plem.errors import MoveItCode, PlanningError
from plem.ipc import command_socket
from plem.ipc.command_socket import FrameReader, frame
from plem.ipc.request_bounds import MIN_SPEED_SCALE
from plem.planning.goals import MAX_IK_TIMEOUT_S, MAX_PLANNING_TIME_S
from plem.planning.poses import MAX_COORDINATE_M
from tests.e2e.cli import run_plem
from tests.e2e.launched import Launch, launched_robot, wait_for

#: A pose no Indy7 reaches (its reach is under 1 m).
FAR = {"position": [3.0, 0.0, 0.5], "orientation": [0.0, 0.0, 0.0, 1.0]}
#: Waits for conditions (never for a time a test asserts on).
CONDITION_S = 60.0


@pytest.fixture(scope="module")
def launch(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Launch]:
    with launched_robot(tmp_path_factory, "record:=false", "planner:=true", "bridge:=false") as running:
        yield running


@pytest.fixture
def link(launch: Launch) -> Iterator[PlannerLink]:
    planner = PlannerLink(launch.robot_id)
    yield planner
    planner.close()


def error_of(call: Callable[[], Any]) -> PlanningError:
    """The PlanningError `call` raises (the test fails when it answers)."""
    with pytest.raises(PlanningError) as raised:
        call()
    return raised.value


def long_cartesian(link: PlannerLink) -> dict[str, Any]:
    """A Cartesian request long by its own parameters: from home, 0.2 m down in the most steps a path may have,
    with the longest planning time."""
    home = link.request("describe")["named_states"]["home"]
    tool = link.request("fk", positions=home)
    (pose,) = tool.values()
    lower = {"position": [pose["position"][0], pose["position"][1], pose["position"][2] - 0.2],
             "orientation": pose["orientation"]}
    return {"waypoints": [lower], "start": home, "max_step": 0.2 / 99_000,
            "options": {"timeout_s": MAX_PLANNING_TIME_S}}


class LongRequest:
    """The long Cartesian request, sent by `link` in a thread; `outcome` gets its answer or error."""

    def __init__(self, link: PlannerLink, args: dict[str, Any]) -> None:
        self.link, self.args = link, args
        self.outcome: list[Any] = []
        self.send()

    def send(self) -> None:
        self.outcome.clear()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        try:
            self.outcome.append(self.link.request("cartesian", MAX_PLANNING_TIME_S + CONDITION_S, **self.args))
        except PlanningError as error:
            self.outcome.append(error)

    def refused_as_busy(self) -> bool:
        return bool(self.outcome) and is_busy(self.outcome[0])


def is_busy(answer: object) -> bool:
    return isinstance(answer, PlanningError) and answer.summary == "the planner is busy"


def busy_while_running(probe: PlannerLink, refused_as_busy: Callable[[], bool], send_again: Callable[[], None]
                       ) -> PlanningError | None:
    """The probe's busy answer once the long request runs. The probe's own requests compute too: a long request
    that met one of them was refused as busy itself, and is sent again."""
    def produce() -> PlanningError | None:
        if refused_as_busy():
            send_again()
            return None
        return busy_answer(probe)

    return wait_for(produce, CONDITION_S)


def busy_answer(link: PlannerLink) -> PlanningError | None:
    """The planner's answer to a computing request (FK) when it is busy, else None."""
    try:
        link.request("fk")
    except PlanningError as error:
        if error.summary == "the planner is busy":
            return error
        raise
    return None


def test_a_busy_planner_says_whose_request_runs_and_a_cancel_ends_it(launch: Launch, link: PlannerLink) -> None:
    args = long_cartesian(link)
    other = PlannerLink(launch.robot_id)
    long_request = LongRequest(link, args)
    try:
        busy = busy_while_running(other, long_request.refused_as_busy, long_request.send)
        assert busy is not None, "the planner never answered busy while a long request ran"
        assert "a cartesian request from " in busy.why and f"pid {os.getpid()}" in busy.why
        assert f"s left of its {MAX_PLANNING_TIME_S:g} s" in busy.why and "cancel" in busy.how
        # requests that read answer as usual; bad requests from others are answered at once, never left hanging
        assert "arm" in other.request("describe")["groups"]
        assert "objects" in other.request("scene", action="get")
        for op, bad in (("ik", {"pose": FAR, "seed": [1e9] * 6}), ("plan", {"goal": {"named": "nowhere"}}),
                        ("ik", {"pose": FAR, "group": "no_group"}), ("plan", {"goal": None})):
            error = error_of(lambda op=op, bad=bad: other.request(op, **bad))  # type: ignore[misc]
            assert error.summary != "the planner did not answer" and error.how
        cancelled = PlannerLink(launch.robot_id).cancel()
        assert cancelled is not None and "a cartesian request from" in cancelled
        long_request.thread.join(CONDITION_S)
        outcome = long_request.outcome
        assert isinstance(outcome[0], PlanningError) and outcome[0].code == MoveItCode.PREEMPTED, outcome
        assert "cancelled" in outcome[0].summary
        assert wait_for(lambda: "ended early: a client cancelled it" in launch.errors, CONDITION_S)
        assert other.request("fk")
    finally:
        other.close()
        PlannerLink(launch.robot_id).cancel()
        long_request.thread.join(CONDITION_S)


def test_a_client_that_goes_away_ends_its_request(launch: Launch, link: PlannerLink) -> None:
    args = long_cartesian(link)
    gone = command_socket.connect(launch.robot_id, service="planner")
    request = frame(json.dumps({"id": "gone", "op": "cartesian", **args}).encode())
    reader = FrameReader(1 << 20)

    def refused_as_busy() -> bool:
        """Whether the planner answered the request (it answers a long one only when it refuses it)."""
        if not select.select([gone], [], [], 0.0)[0]:
            return False
        answers = reader.feed(gone.recv(1 << 16))
        assert all(json.loads(answer)["error"]["summary"] == "the planner is busy" for answer in answers), answers
        return bool(answers)

    gone.sendall(request)
    assert busy_while_running(link, refused_as_busy, lambda: gone.sendall(request)) is not None
    gone.close()
    assert wait_for(lambda: "ended early: its client closed its connection" in launch.errors, CONDITION_S), \
        launch.errors[-2000:]
    assert wait_for(lambda: busy_answer(link) is None, CONDITION_S)


def test_requests_are_capped_and_every_field_is_checked(link: PlannerLink) -> None:
    pose = {"position": [0.4, 0.0, 0.5], "orientation": [0.0, 1.0, 0.0, 0.0]}
    attacks: list[tuple[str, dict[str, Any], str]] = [
        ("ik", {"pose": pose, "timeout_s": 1e9}, f"timeout_s in [0, {MAX_IK_TIMEOUT_S:g}]"),
        ("ik", {"pose": pose, "timeout_s": "long"}, "timeout_s is not a number"),
        ("ik", {"pose": pose, "avoid_collisions": "no"}, "avoid_collisions is not true or false"),
        ("ik", {"pose": pose, "seed": ["a"] * 6}, "positions must be a list of numbers"),
        ("ik", {"pose": {"position": [1e300, 0, 0]}}, f"±{MAX_COORDINATE_M:g} m"),
        ("fk", {"positions": [True] * 6}, "positions must be a list of numbers"),
        ("plan", {"goal": {"named": "home"}, "options": {"velocity_scale": 1e-9}}, f"{MIN_SPEED_SCALE:g}"),
        ("plan", {"goal": {"named": "home"}, "options": {"timeout_s": 1e6}}, f"{MAX_PLANNING_TIME_S:g}"),
        ("plan", {"goal": {"named": "home"}, "options": "fast"}, "the planning options are not an object"),
        ("plan", {"goal": {"pose": {"position": [1e300, 0, 0]}}}, "the position is out of range"),
        ("plan", {"goal": {"pose": pose, "position_only": 1}}, "position_only is not true or false"),
        ("cartesian", {"waypoints": [pose], "max_step": "abc"}, "max_step is not a number"),
        ("cartesian", {"waypoints": [pose], "jump_threshold": -1}, "jump_threshold is out of range"),
        ("scene", {"action": "attach", "name": "x", "touch_links": "tcp"}, "touch_links must be a list"),
        ("view", {"plans_seen": "abc"}, "plans_seen is not a number"),
    ]
    for op, args, expected in attacks:
        error = error_of(lambda op=op, args=args: link.request(op, **args))  # type: ignore[misc]
        text = f"{error.summary} {error.what} {error.why}"
        assert expected in text, (op, args, text)
        assert "failed on this" not in error.summary and error.how, (op, args, text)
    assert link.request("describe")["joint_names"]          # the same connection still serves


def test_nested_json_is_answered_and_the_connection_serves_on(launch: Launch) -> None:
    with command_socket.connect(launch.robot_id, service="planner") as connection:
        reader = FrameReader(1 << 20)
        connection.settimeout(CONDITION_S)

        def answer(payload: bytes) -> dict[str, Any]:
            connection.sendall(frame(payload))
            frames: list[bytes] = []
            while not frames:
                data = connection.recv(1 << 16)
                assert data, "the planner closed the connection"
                frames = reader.feed(data)
            found: dict[str, Any] = json.loads(frames[0])
            return found

        assert answer(b"[" * 100_000 + b"]" * 100_000)["error"]["summary"] == "the request is not JSON"
        assert answer(json.dumps({"id": 1, "op": "describe"}).encode())["result"]["joint_names"]


def test_the_cli_refuses_extreme_numbers_with_the_bounds(launch: Launch) -> None:
    robot = ("--robot-id", launch.robot_id)
    slow = run_plem("move", "--to", "home", "--speed-scale", "1e-9", *robot, env=launch.env)
    assert slow.returncode == 2 and f"at least {MIN_SPEED_SCALE:g}" in slow.stderr, slow.stderr
    far = run_plem("plan", "--to-pose", "1e300", "0", "0", "0", "0", "0", "1", "--dry-run", *robot, env=launch.env)
    assert far.returncode == 1 and f"±{MAX_COORDINATE_M:g} m" in far.stderr, far.stderr
    long = run_plem("plan", "--to", "home", "--planning-time", "1000", "--dry-run", *robot, env=launch.env)
    assert long.returncode == 2 and f"at most {MAX_PLANNING_TIME_S:g}" in long.stderr, long.stderr
    for result in (slow, far, long):
        assert "did not answer" not in result.stderr and "Traceback" not in result.stderr
    slowest = run_plem("plan", "--to", "home", "--speed-scale", f"{MIN_SPEED_SCALE:g}", "--dry-run", *robot,
                       env=launch.env)
    assert slowest.returncode == 0 and "every limit kept" in slowest.stdout, slowest.stderr
