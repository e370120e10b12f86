"""`plem launch` end to end: the real supervisor, RT driver and clients as separate processes on the mock bus."""

from __future__ import annotations

import grp
import hashlib
import json
import os
import re
import signal
import stat
import subprocess
import time
import uuid
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from plem.bridge import connect
from plem.bridge.client import DriverGone, RobotClient
from plem.control.events import EventKind
from plem.control.modes import Mode
from plem.ipc.channels import PRIVATE_RINGS, channel_names
from plem.ipc.command_socket import socket_path
from plem.ipc.robot_description import description_path, read_description
from tests.e2e.cli import run_plem
from tests.e2e.command_wire import RawConnection
from tests.e2e.launched import (
    Launch,
    as_nobody,
    clean_environment,
    launched,
    launched_robot,
    new_robot_id,
    process_gone,
    process_reaped,
    python_client,
    read_line,
    remove_generated,
    shm_files,
    start_launch,
    system_python,
    wait_until,
)

ARRIVED = 1e-3
LOOP_HZ = 1000.0

MOVE_CLIENT = """
    import json, sys
    from plem.bridge import connect
    client = connect(sys.argv[1])
    client.set_mode("hold")
    result = client.move_joints(json.loads(sys.argv[2]), 1.0).wait(30)
    state = client.state()
    print(json.dumps({"outcome": result.outcome.value, "mode": state.mode.name,
                      "position": state.position.tolist()}), flush=True)
"""

WAITING_CLIENT = """
    import json, sys
    from plem.bridge import connect
    client = connect(sys.argv[1])
    client.set_mode("hold")
    handle = client.move_joints(json.loads(sys.argv[2]), float(sys.argv[3]))
    print("waiting", handle.id, flush=True)
    handle.wait(60)
    print("finished", flush=True)
"""

STREAMING_CLIENT = """
    import json, sys
    from plem.bridge import connect
    client = connect(sys.argv[1])
    client.set_mode("hold")
    samples = client.stream(timeout=10)
    client.move_joints(json.loads(sys.argv[2]), float(sys.argv[3]))
    for count, sample in enumerate(samples, 1):
        if count == 200:
            print("streaming", sample.cycle, flush=True)
"""


# -- fixtures ----------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def robot(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Launch]:
    """One simulated Indy7 v2 shared by the tests that neither kill nor restart it."""
    with launched_robot(tmp_path_factory) as launch:
        yield launch


def shm_group_name() -> str | None:
    """An existing group other than ours, for shm_group:=."""
    for name in ("daemon", "nogroup", "users"):
        try:
            if grp.getgrnam(name).gr_gid != os.getegid():
                return name
        except KeyError:
            continue
    return None


@pytest.fixture(scope="module")
def group_robot(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Launch, grp.struct_group]]:
    name = shm_group_name()
    if name is None:
        pytest.skip("no group other than the test's own exists")
    directory = tmp_path_factory.mktemp("group_launch")
    robot_id = new_robot_id()
    with launched(["bus:=mock", f"robot_id:={robot_id}", f"shm_group:={name}"], [robot_id], directory,
                  clean_environment(directory / "plem_home")) as launch:
        yield launch, grp.getgrnam(name)


# -- shared checks -----------------------------------------------------------------------------------
def shared_memory_files(robot_id: str) -> list[str]:
    """The shared memory of a robot, as /dev/shm lists it."""
    return sorted(name[1:] for name in channel_names(robot_id).values())


def expected_files(robot_id: str) -> list[str]:
    """The shared memory of a robot and its command socket."""
    return sorted([*shared_memory_files(robot_id), socket_path(robot_id).name])


def target_away(client: RobotClient, distance: float) -> list[float]:
    """The current position with joint0 moved by `distance` rad, towards the side with room."""
    position = client.state().position.copy()
    upper = client.limits.max_position[0] - 0.2
    position[0] += distance if position[0] + distance < upper else -distance
    return position.tolist()


def expect_line(process: subprocess.Popen, prefix: str, timeout: float = 30) -> str:
    line = read_line(process, timeout)
    if not line.startswith(prefix):
        process.kill()
        _, errors = process.communicate()
        raise AssertionError(f"expected {prefix!r} from the client, got {line!r}; stderr:\n{errors}")
    return line


def move_in_new_process(launch: Launch, target: list[float]) -> dict:
    mover = python_client(MOVE_CLIENT, launch.robot_id, json.dumps(target), env=launch.env)
    output, errors = mover.communicate(timeout=60)
    assert mover.returncode == 0, errors
    return json.loads(output)


def assert_error_form(text: str) -> None:
    """A WHAT/WHY/HOW error and no traceback."""
    assert "Traceback" not in text
    for label in ("ERROR:", "WHAT:", "WHY:", "HOW:"):
        assert re.search(rf"^{label} \S", text, re.MULTILINE), f"no {label} line in:\n{text}"


def watch_until_hold(client: RobotClient, samples, timeout: float = 20) -> tuple[list[int], list[int], set[Mode]]:
    """Every cycle's sample until the loop is back in HOLD: their cycle numbers, times and the modes they show."""
    cycles: list[int] = []
    times: list[int] = []
    modes: set[Mode] = set()
    faulted = False
    deadline = time.monotonic() + timeout
    while True:
        for sample in samples:
            cycles.append(sample.cycle)
            times.append(sample.monotonic_ns)
            modes.add(sample.mode)
            faulted |= sample.faulted
        if Mode.HOLD in modes and client.state().mode is Mode.HOLD:
            break
        assert time.monotonic() < deadline, f"no HOLD within {timeout} s; modes seen {modes}"
        time.sleep(0.05)
    assert not faulted
    return cycles, times, modes


def assert_loop_undisturbed(client: RobotClient, killed: subprocess.Popen, target: list[float]) -> None:
    """Kill `killed` mid-motion, then: every cycle ran at ~1 kHz, the motion finished, no fault."""
    events = client.events(timeout=0)
    samples = client.stream(timeout=0)
    killed.send_signal(signal.SIGKILL)
    killed.wait(10)
    assert killed.returncode == -signal.SIGKILL
    assert client.state().mode is Mode.TRAJECTORY, "the client was not killed in the middle of the motion"

    cycles, times, modes = watch_until_hold(client, samples)
    elapsed = (times[-1] - times[0]) / 1e9                   # the loop's own clock: no stall hides in it
    assert samples.dropped == 0
    assert np.all(np.diff(cycles) == 1), "the loop skipped or repeated cycles"
    assert 0.85 * LOOP_HZ < (len(cycles) - 1) / elapsed < 1.15 * LOOP_HZ, (len(cycles), elapsed)
    assert Mode.FAULT not in modes and Mode.TRAJECTORY in modes

    state = client.state()
    assert not state.faulted and state.drives_enabled
    assert np.allclose(state.position, target, atol=ARRIVED), (state.position, target)
    seen = list(events)
    assert [e.cause for e in seen if e.kind is EventKind.MOTION_FINISHED] == ["succeeded"], seen
    assert not [e for e in seen if e.kind is EventKind.FAULT], seen
    assert wait_until(lambda: (client.stats() or {}).get("mode") == "hold", 2)
    assert client.stats()["fault_reason"] == ""


# -- 1. commanding from another process --------------------------------------------------------------
def test_client_process_moves_the_arm_and_cli_moves_it_home(robot: Launch, client: RobotClient):
    target = [0.3, -0.2, -1.2, 0.2, -1.1, 0.3]
    moved = move_in_new_process(robot, target)
    assert moved["outcome"] == "succeeded" and moved["mode"] == "HOLD"
    assert np.allclose(moved["position"], target, atol=ARRIVED)
    assert np.allclose(client.state().position, target, atol=ARRIVED)

    home = client.channels.state.poses["home"]
    names = client.joint_names
    assert home[names.index("joint2")] == pytest.approx(-1.570796) == home[names.index("joint4")]
    assert [home[i] for i, name in enumerate(names) if name not in ("joint2", "joint4")] == [0.0] * 4

    result = run_plem("move", "--to", "home", "--speed-scale", "1", "--robot-id", robot.robot_id, env=robot.env)
    assert result.returncode == 0, result.stderr
    assert "reached its goal" in result.stdout
    state = client.state()
    assert state.mode is Mode.HOLD and np.allclose(state.position, home, atol=ARRIVED), state.position


# -- 2. a killed client never disturbs the loop --------------------------------------------------------
@pytest.mark.parametrize("script, busy_line", [(WAITING_CLIENT, "waiting"), (STREAMING_CLIENT, "streaming")],
                         ids=["waiting-on-a-motion", "streaming"])
def test_sigkill_of_a_client_leaves_the_loop_running(robot: Launch, client: RobotClient, script: str,
                                                     busy_line: str):
    target = target_away(client, 0.5)
    victim = python_client(script, robot.robot_id, json.dumps(target), "0.5", env=robot.env)
    try:
        expect_line(victim, busy_line)
        assert_loop_undisturbed(client, victim, target)
    finally:
        victim.kill()
        victim.communicate()

    after = target_away(client, 0.2)
    moved = move_in_new_process(robot, after)  # a new client can command afterwards
    assert moved["outcome"] == "succeeded" and np.allclose(moved["position"], after, atol=ARRIVED)


# -- 3. / 4. a killed launch ---------------------------------------------------------------------------
def test_sigkill_of_launch_and_driver_leaves_stale_memory_that_a_new_launch_replaces(tmp_path: Path):
    robot_id = new_robot_id()
    env = clean_environment(tmp_path / "plem_home")
    arguments = ["bus:=mock", f"robot_id:={robot_id}"]
    first = start_launch(arguments, [robot_id], tmp_path, env)
    try:
        driver = first.driver_pids()[robot_id]
        os.kill(driver, signal.SIGKILL)
        first.process.kill()
        first.process.wait(10)
        assert wait_until(lambda: process_reaped(driver), 10)
        # the shared memory stays behind; the command service dies with its driver and removes its socket
        assert wait_until(lambda: [path.name for path in shm_files(robot_id)] == shared_memory_files(robot_id), 10), \
            shm_files(robot_id)

        second = start_launch(arguments, [robot_id], tmp_path, env)
        try:
            replacing = re.search(rf"WARNING: replacing stale shared memory /{robot_id}_joint_actual_values "
                                  rf"left by process (\d+)", second.errors)
            assert replacing and int(replacing.group(1)) == driver, second.describe()
            new_driver = second.driver_pids()[robot_id]
            assert new_driver != driver
            with connect(robot_id) as client:
                assert client.channels.state.header.owner_pid == new_driver
                client.set_mode("hold")
                target = target_away(client, 0.3)
                assert client.move_joints(target, 1.0).wait(30).outcome.value == "succeeded"
                assert np.allclose(client.state().position, target, atol=ARRIVED)
            assert read_description(robot_id).pid == second.process.pid, "the new launch shares its description"
            assert second.stop() == 0, second.describe()
            assert shm_files(robot_id) == [] and not description_path(robot_id).exists()
        finally:
            second.cleanup()
    finally:
        first.cleanup()


def test_sigkill_of_launch_alone_stops_the_driver_cleanly(tmp_path: Path):
    robot_id = new_robot_id()
    with launched(["bus:=mock", f"robot_id:={robot_id}"], [robot_id], tmp_path,
                  clean_environment(tmp_path / "plem_home")) as launch, connect(robot_id) as client:
        driver = launch.driver_pids()[robot_id]
        client.set_mode("hold")
        events = client.events(timeout=0)
        launch.process.kill()
        launch.process.wait(10)
        assert wait_until(lambda: process_gone(driver) and not shm_files(robot_id), 5), shm_files(robot_id)
        # The mappings outlive the unlinked names: the driver's last words are still readable.
        stopped = [e for e in events if e.kind is EventKind.MODE_CHANGED]
        assert [(e.previous_mode, e.mode) for e in stopped] == [(Mode.HOLD, Mode.IDLE)], stopped
        last = client.channels.state.block.read()
        assert last.mode is Mode.IDLE and not last.drives_enabled and not last.faulted
        with pytest.raises(DriverGone):                       # the client no longer passes it off as current
            client.state()


# -- 5. one driver per robot_id ------------------------------------------------------------------------
def test_second_launch_with_the_same_robot_id_is_refused(robot: Launch, client: RobotClient):
    before = client.state().cycle
    result = run_plem("launch", "bus:=mock", f"robot_id:={robot.robot_id}", env=robot.env)
    remove_generated(result.stdout)
    assert result.returncode == 1
    assert f"robot '{robot.robot_id}' already has a running RT driver" in result.stderr
    assert_error_form(result.stderr)
    assert robot.process.poll() is None
    assert client.channels.state.header.owner_pid == robot.driver_pids()[robot.robot_id]
    assert [path.name for path in shm_files(robot.robot_id)] == expected_files(robot.robot_id)
    assert client.wait_for_state(timeout=2, after_cycle=before + 500) is not None
    assert client.live_state().cycle > before + 500


# -- 6. several robots in one launch -------------------------------------------------------------------
def test_two_robots_in_one_launch_are_isolated(tmp_path: Path):
    left, right = new_robot_id(), new_robot_id()
    robots = tmp_path / "robots.yaml"
    robots.write_text(f"robots:\n  - {{robot_id: {left}, bus: mock}}\n  - {{robot_id: {right}, bus: mock}}\n")
    with launched([f"robots:={robots}"], [left, right], tmp_path,
                  clean_environment(tmp_path / "plem_home")) as launch, \
            connect(left) as moving, connect(right) as still:
        pids = launch.driver_pids()
        assert set(pids) == {left, right} and pids[left] != pids[right]
        assert moving.channels.state.header.owner_pid == pids[left]
        assert still.channels.state.header.owner_pid == pids[right]
        for robot_id in (left, right):
            assert [path.name for path in shm_files(robot_id)] == expected_files(robot_id)

        resting = still.state()
        moving.set_mode("hold")
        target = target_away(moving, 0.4)
        handle = moving.move_joints(target, 1.0)
        while not handle.done:
            during = still.state()
            assert during.mode is resting.mode and np.array_equal(during.position, resting.position)
            time.sleep(0.01)
        assert handle.wait(1).outcome.value == "succeeded"
        assert np.allclose(moving.state().position, target, atol=ARRIVED)
        after = still.state()
        assert np.array_equal(after.position, resting.position) and after.mode is resting.mode
        assert after.cycle - resting.cycle > 0.8 * LOOP_HZ * (after.monotonic_ns - resting.monotonic_ns) / 1e9

        moving_kinds = {e.kind for e in moving.events(timeout=0, from_oldest=True)}
        still_kinds = {e.kind for e in still.events(timeout=0, from_oldest=True) if e.cycle > resting.cycle}
        motion = {EventKind.MODE_CHANGED, EventKind.MOTION_STARTED, EventKind.MOTION_FINISHED}
        assert motion <= moving_kinds
        assert not motion & still_kinds, still_kinds
        assert still.stats()["commands"]["received"] == 0


# -- 7. permissions ------------------------------------------------------------------------------------
def test_shared_memory_is_owner_only(robot: Launch):
    files = shm_files(robot.robot_id)
    assert [path.name for path in files] == expected_files(robot.robot_id)
    for path in files:
        status = path.stat()
        assert stat.S_IMODE(status.st_mode) == 0o600, path
        assert (status.st_uid, status.st_gid) == (os.geteuid(), os.getegid()), path


def test_shm_group_makes_the_memory_group_readable(group_robot: tuple[Launch, grp.struct_group]):
    launch, group = group_robot
    files = shm_files(launch.robot_id)
    assert [path.name for path in files] == expected_files(launch.robot_id)
    private = {socket_path(launch.robot_id).name, *(name[1:] for ring, name in channel_names(launch.robot_id).items()
                                                    if ring in (*PRIVATE_RINGS, "motions", "stream"))}
    for path in files:
        status = path.stat()
        if path.name in private:   # the command socket and what only the driver and its command service map
            assert stat.S_IMODE(status.st_mode) == 0o600, path
            assert status.st_uid == os.geteuid(), path
        else:
            assert stat.S_IMODE(status.st_mode) == 0o640, path
            assert (status.st_uid, status.st_gid) == (os.geteuid(), group.gr_gid), path


def _run_as_group_member(group: grp.struct_group, code: str) -> subprocess.CompletedProcess[str]:
    """`code` under the system interpreter as user nobody, a member of `group` (needs root)."""
    if os.geteuid() != 0 or system_python() is None:
        pytest.skip("needs root and a system Python of the test's version")
    process = as_nobody(code, groups=[group.gr_gid])
    stdout, stderr = process.communicate(timeout=60)
    return subprocess.CompletedProcess(process.args, process.returncode, stdout, stderr)


def test_shm_group_member_can_read_the_state(group_robot: tuple[Launch, grp.struct_group]):
    launch, group = group_robot
    probe = _run_as_group_member(group, "import numpy, plem.bridge")
    if probe.returncode != 0:
        # Only the machine may excuse this: files user nobody cannot read, or a library the system Python
        # lacks. An error inside plem itself fails the test.
        unreachable = "Permission denied" in probe.stderr or re.search(
            r"ModuleNotFoundError: No module named '(?!plem)", probe.stderr)
        assert unreachable, probe.stderr
        reason = probe.stderr.strip().splitlines()[-1]
        pytest.skip(f"the system Python cannot load plem's files as user nobody: {reason}")
    result = _run_as_group_member(group, f"from plem.bridge import connect\n"
                                         f"print(connect({launch.robot_id!r}).state().cycle)")
    assert result.returncode == 0, result.stderr
    assert int(result.stdout) > 0


# -- 8. malformed commands -----------------------------------------------------------------------------
def test_malformed_commands_are_rejected_without_reaching_the_loop(robot: Launch, client: RobotClient):
    assert wait_until(lambda: client.stats() is not None, 2)
    counted = client.stats()["commands"]
    before = client.state()
    events = client.events(timeout=0)
    tag = uuid.uuid4().hex[:6]
    requests = {
        f"unknown-op-{tag}": {"op": "teleport", "target": [0.0] * client.dof},
        f"out-of-limit-{tag}": {"op": "move_joints", "target": (client.limits.max_position + 0.5).tolist(),
                                "speed_scale": 0.5},
        f"wrong-length-{tag}": {"op": "move_joints", "target": [0.1] * (client.dof - 1)},
    }
    connection = RawConnection(robot.robot_id)
    try:
        connection.send(b"\xff\x00{garbage")
        for request_id, request in requests.items():
            connection.send({"id": request_id, **request})
        answers = connection.answers(4, timeout=5)
    finally:
        connection.close()
    assert [answer["stage"] for answer in answers] == ["rejected"] * 4, answers
    assert "unreadable request" in answers[0]["error"]["summary"]
    by_id = {answer["id"]: answer for answer in answers[1:]}
    assert set(by_id) == set(requests)
    assert "not a plem request" in by_id[f"unknown-op-{tag}"]["error"]["summary"]
    assert "outside the position limits" in by_id[f"out-of-limit-{tag}"]["error"]["summary"]
    assert "got 5 values" in by_id[f"wrong-length-{tag}"]["error"]["why"]
    assert wait_until(lambda: client.stats()["commands"]["received"] == counted["received"] + 4, 3)
    counts = client.stats()["commands"]
    assert counts == {**counted, "received": counted["received"] + 4, "rejected": counted["rejected"] + 4}
    seen = list(events)
    assert not [e for e in seen if e.kind in (EventKind.MOTION_STARTED, EventKind.MODE_CHANGED)], seen
    now = client.state()
    assert now.mode is before.mode and np.allclose(now.position, before.position, atol=1e-9)

    client.set_mode("hold")
    target = target_away(client, 0.2)
    assert client.move_joints(target, 1.0).wait(30).outcome.value == "succeeded"
    assert np.allclose(client.state().position, target, atol=ARRIVED)


@pytest.mark.parametrize("record", [
    pytest.param(json.dumps({"id": "list-op", "op": ["stop"]}).encode(), id="list-op"),
    pytest.param(b'{"a":' * 5000 + b"1" + b"}" * 5000, id="deeply-nested"),
    pytest.param(b'{"id": "inf", "op": "move_joints", "target": [Infinity, 0, 0, 0, 0, 0]}', id="infinity"),
])
def test_a_record_that_breaks_validation_does_not_deafen_the_driver(tmp_path: Path, record: bytes):
    robot_id = new_robot_id()
    with launched(["bus:=mock", f"robot_id:={robot_id}", "bridge:=false", "record:=false"], [robot_id], tmp_path,
                  clean_environment(tmp_path / "plem_home")) as launch, connect(robot_id) as client:
        connection = RawConnection(robot_id)
        try:
            connection.send(record)
            assert [answer["stage"] for answer in connection.answers(1)] == ["rejected"]
        finally:
            connection.close()
        assert client.set_mode("hold", timeout=3) is Mode.HOLD
        assert wait_until(lambda: client.stats()["commands"]["rejected"] == 1, 2)
        assert launch.process.poll() is None


# -- 9. arguments --------------------------------------------------------------------------------------
SPEC_DEFAULTS = {
    "bus": "ethercat", "robot_id": "indy", "robot_type": "indy7_v2", "description_package": "wim_description",
    "record": "true", "bag_dir": "~/bags/rt_monitoring", "retention_minutes": "60", "disk_threshold": "70",
}
DESCRIBED_DEFAULTS = ("urdf_file", "srdf_file", "robot_name")


def test_launch_help_lists_every_argument_with_its_default():
    result = run_plem("launch", "--help")
    assert result.returncode == 0, result.stderr
    listed = dict(re.findall(r"^  (\w+):=\s+(.*)$", result.stdout, re.MULTILINE))
    assert set(SPEC_DEFAULTS) | set(DESCRIBED_DEFAULTS) | {"eth_interface"} <= set(listed), listed
    for name, default in SPEC_DEFAULTS.items():
        assert listed[name].endswith(f"[default: {default}]"), (name, listed[name])
    for name in DESCRIBED_DEFAULTS:
        assert "default:" in listed[name], (name, listed[name])


def test_bad_launch_arguments_are_reported_together_and_start_nothing():
    robot_id = new_robot_id()
    result = run_plem("launch", "bus:=can", "disk_threshold:=150", f"robot_id:={robot_id}")
    assert result.returncode == 1
    assert_error_form(result.stderr)
    assert "invalid launch argument bus:=can" in result.stderr
    assert "invalid launch argument disk_threshold:=150" in result.stderr
    assert "Traceback" not in result.stdout and "rt_driver" not in result.stdout
    assert shm_files(robot_id) == []


def assert_refused_before_anything_started(result: subprocess.CompletedProcess[str], robot_ids: list[str],
                                           home: Path) -> None:
    """Exit 1 with WHAT/WHY/HOW, never a traceback or an internal error, and nothing started or recorded."""
    assert result.returncode == 1, result.stdout + result.stderr
    assert_error_form(result.stderr)
    assert "Internal error" not in result.stderr and "Traceback" not in result.stdout + result.stderr
    assert "rt_driver" not in result.stdout and "Generated files" not in result.stdout, result.stdout
    for robot_id in robot_ids:
        assert shm_files(robot_id) == [], robot_id
    assert not list(home.rglob("*.mcap")) and not list(home.rglob("*.db3"))


BAD_ARGUMENTS = [
    (["bag_dir:=/proc/nope"], ["/proc/nope: No such file or directory", "HOW: pass bag_dir:=DIR"]),
    (["bag_dir:=/proc"], ["No such file or directory", "HOW: pass bag_dir:=DIR"]),
    (["bag_dir:=/tmp/" + "b" * 5000], ["bag_dir cannot be created: the path is", "Linux allows 4095"]),
    (["shm_group:=99999999999"], ["invalid launch argument shm_group:=99999999999", "your groups:"]),
    (["shm_group:=no_such_group_xyz"], ["invalid launch argument shm_group:=no_such_group_xyz"]),
    (["cycle_time:=²"], ["invalid launch argument cycle_time:=²", "digits 0-9"]),
    (["retention_minutes:=²"], ["invalid launch argument retention_minutes:=²"]),
    (["rt_priority:=٣"], ["invalid launch argument rt_priority:=٣"]),
    (["joint_states_rate:=inf"], ["invalid launch argument joint_states_rate:=inf"]),
    (["max_consecutive_overruns:=0"], ["invalid launch argument max_consecutive_overruns:=0"]),
    (["robots:=~no_such_user_xyz/robots.yaml"], ["unknown home directory in robots:=~no_such_user_xyz"]),
    (["description_package:=~no_such_user_xyz/pkg"], ["unknown home directory in description_package:="]),
    (["bag_dir:=/proc/nope", "rt_priority:=99", "cycle_time:=5000"],
     ["/proc/nope: No such file or directory", "rt_priority out of range", "cycle_time out of range"]),
]


@pytest.mark.parametrize("arguments, messages", BAD_ARGUMENTS, ids=lambda value: str(value)[:40])
def test_bad_launch_arguments_are_explained_and_start_nothing(tmp_path: Path, arguments: list[str],
                                                              messages: list[str]):
    robot_id = new_robot_id()
    result = run_plem("launch", "bus:=mock", f"robot_id:={robot_id}", *arguments,
                      env=clean_environment(tmp_path / "home"))
    assert_refused_before_anything_started(result, [robot_id], tmp_path / "home")
    for message in messages:
        assert message in result.stderr, result.stderr


def test_a_launch_file_in_the_home_of_no_user_is_explained(tmp_path: Path):
    robot_id = new_robot_id()
    result = run_plem("launch", "~no_such_user_xyz/launch/bringup.launch.py", "bus:=mock", f"robot_id:={robot_id}",
                      env=clean_environment(tmp_path / "home"))
    assert_refused_before_anything_started(result, [robot_id], tmp_path / "home")
    assert "there is no user 'no_such_user_xyz'" in result.stderr


def test_a_nul_in_bag_dir_from_a_robots_file_is_explained(tmp_path: Path):
    robot_id = new_robot_id()
    robots = tmp_path / "robots.yaml"
    robots.write_text(f'robots:\n  - {{robot_id: {robot_id}, bus: mock, bag_dir: "/tmp/a\\0b"}}\n')
    result = run_plem("launch", f"robots:={robots}", env=clean_environment(tmp_path / "home"))
    assert_refused_before_anything_started(result, [robot_id], tmp_path / "home")
    assert "NUL byte" in result.stderr and "bag_dir:=" in result.stderr


def test_the_two_robot_example_starts_neither_arm_when_one_cannot_run(tmp_path: Path):
    """The example of docs/bringup.md on a machine without its interface: the simulated arm does not start either."""
    left, right = new_robot_id(), new_robot_id()
    robots = tmp_path / "robots.yaml"
    robots.write_text(f"robots:\n  - {{robot_id: {left}, bus: mock, robot_type: indy7_v2}}\n"
                      f"  - {{robot_id: {right}, bus: ethercat, eth_interface: nosuch0, master_index: 1, "
                      "robot_type: indy12_v2}\n")
    result = run_plem("launch", f"robots:={robots}", "cycle_time:=²", env=clean_environment(tmp_path / "home"))
    assert_refused_before_anything_started(result, [left, right], tmp_path / "home")
    for message in (f"robot {left}: invalid launch argument cycle_time:=²",
                    f"robot {right}: invalid launch argument cycle_time:=²",
                    f"robot {right}: Network interface does not exist: nosuch0"):
        assert message in result.stderr, result.stderr


def test_a_dds_configuration_cyclone_refuses_stops_the_launch_before_the_arm_starts(tmp_path: Path):
    robot_id = new_robot_id()
    result = run_plem("launch", "bus:=mock", f"robot_id:={robot_id}",
                      env=clean_environment(tmp_path / "home", CYCLONEDDS_URI="<bogus"))
    assert_refused_before_anything_started(result, [robot_id], tmp_path / "home")
    assert "Cyclone DDS refused the configuration" in result.stderr
    assert re.search(r"^HOW: fix or unset CYCLONEDDS_URI", result.stderr, re.MULTILINE), result.stderr


def test_summary_states_the_overrun_policy_and_a_kernel_that_is_not_real_time(tmp_path: Path):
    robot_id = new_robot_id()
    with launched(["bus:=mock", f"robot_id:={robot_id}", "cycle_time:=500", "record:=false", "bridge:=false"],
                  [robot_id], tmp_path, clean_environment(tmp_path / "home")) as launch:
        output = launch.output
    assert ("overruns      counted every 10 s; 1000 in a row fault the arm (the default on bus mock; "
            "max_consecutive_overruns:=N sets it)") in output
    realtime = Path("/sys/kernel/realtime").exists()
    assert ("kernel: not PREEMPT_RT" in output) is not realtime, output
    assert (f"[{robot_id}] warning: cycle_time 500 µs is below 1000 µs" in output) is not realtime, output


@pytest.mark.parametrize("bus", [[], ["bus:=ethercat"]], ids=["default", "explicit"])
def test_ethercat_without_the_interface_names_the_interfaces_and_the_simulations(bus: list[str]):
    robot_id = new_robot_id()
    result = run_plem("launch", *bus, "eth_interface:=nosuch0", f"robot_id:={robot_id}")
    remove_generated(result.stdout)
    assert result.returncode == 1
    assert_error_form(result.stderr)
    assert "Network interface does not exist: nosuch0" in result.stderr and "lo" in result.stderr
    assert "bus:=mock" in result.stderr and "bus:=ethercat_sim" in result.stderr
    assert "Traceback" not in result.stdout
    assert shm_files(robot_id) == []


# -- 10. plem state ------------------------------------------------------------------------------------
def test_state_without_a_running_robot_explains_how_to_start_one():
    robot_id = new_robot_id()
    result = run_plem("state", "--robot-id", robot_id)
    assert result.returncode == 1
    assert_error_form(result.stderr)
    assert f"shared memory /{robot_id}_joint_actual_values does not exist" in result.stderr
    assert re.search(r"^HOW: .*plem launch", result.stderr, re.MULTILINE)
    assert shm_files(robot_id) == []


def test_state_as_json_of_a_running_robot(robot: Launch, client: RobotClient):
    result = run_plem("state", "--robot-id", robot.robot_id, "--format", "json")
    assert result.returncode == 0, result.stderr
    data = json.loads(result.stdout)
    current = client.state()
    assert data["robot_id"] == robot.robot_id
    assert data["joint_names"] == list(client.joint_names) and len(data["position"]) == client.dof
    assert np.allclose(data["position"], current.position, atol=ARRIVED)
    assert data["mode"] == current.mode.name.lower() and 0 < data["cycle"] <= current.cycle


# -- 11. a scaffolded package's bring-up file ----------------------------------------------------------
def scaffold(directory: Path) -> Path:
    created = run_plem("create-description", "--name", "e2e_arm", "--dof", "6", "--output", str(directory))
    assert created.returncode == 0, created.stderr
    package = directory / "e2e_arm_description"
    assert (package / "launch" / "bringup.launch.py").is_file()
    return package


def package_digest(package: Path) -> dict[str, str]:
    return {str(path.relative_to(package)): "dir" if path.is_dir() else hashlib.sha256(path.read_bytes()).hexdigest()
            for path in sorted(package.rglob("*"))}


def launch_bringup(tmp_path: Path, env: dict[str, str]) -> tuple[dict[str, str], dict[str, str]]:
    """Launch the scaffold's bring-up file, check the robot runs, stop it; the package digest before and after."""
    package = scaffold(tmp_path / "packages")
    before = package_digest(package)
    robot_id = new_robot_id()
    with launched([str(package / "launch" / "bringup.launch.py"), "bus:=mock", f"robot_id:={robot_id}"],
                  [robot_id], tmp_path / "launch", env) as launch:
        assert f"robot {robot_id} (e2e_arm):" in launch.output and "6 joints, bus mock" in launch.output
        assert "planner       not started: no SRDF" in launch.output
        with connect(robot_id) as client:
            assert client.dof == 6 and client.wait_for_state(timeout=2, after_cycle=client.state().cycle + 100)
        assert launch.stop() == 0, launch.describe()
    assert shm_files(robot_id) == []
    return before, package_digest(package)


def test_scaffolded_bringup_file_launches_and_leaves_the_package_unchanged(tmp_path: Path):
    # The bytecode cache is switched off here; the next test covers it.
    before, after = launch_bringup(tmp_path, clean_environment(tmp_path / "plem_home", PYTHONDONTWRITEBYTECODE="1"))
    assert after == before


def test_bringup_launch_writes_no_bytecode_into_the_package(tmp_path: Path):
    env = clean_environment(tmp_path / "plem_home")
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    before, after = launch_bringup(tmp_path, env)
    assert after == before
