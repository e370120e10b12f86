"""Other local users cannot crash, hang, impersonate or read a robot through /dev/shm or its recordings.

User nobody plants files (forged status files, FIFOs, symbolic links, segments of its own) where plem
looks; plem must ignore or refuse them, never block on them, never remove them, and never take them for
its own. Acting as nobody needs root: those tests are skipped otherwise. Every open that a regression
could block runs under `finishes`, which fails the test instead of hanging the suite.
"""

from __future__ import annotations

import contextlib
import grp
import json
import logging
import os
import stat
import threading
import traceback
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from plem.control.limits import ArmLimits
from plem.core.files import write_atomic
from plem.ipc.channels import RobotChannels, channel_names
from plem.ipc.records import raw_record_length
from plem.ipc.segment import SegmentError, SharedSegment, segment_path
from plem.ipc.state_segment import StateSegment, state_segment_name
from plem.middleware.monitor_feed import MONITOR_TOPICS, QueueCount
from plem.middleware.raw_cdr import RawEncoder
from plem.recording.access import FileAccess, restrict_umask
from plem.recording.archive import EVENT_LOG
from plem.recording.recorder import Recorder
from plem.recording.repair import repair
from plem.recording.segment import SegmentWriter
from plem.recording.settings import RecordingSettings
from plem.recording.status import MAX_STATUS_BYTES, read_status, remove_status, status_path, write_status
from tests.integration.test_recorder import STORE, Clock, fault, feed

NOBODY = 65534
DAEMON = 1
HANG_GUARD_S = 30.0
JOINTS = tuple(f"joint{i}" for i in range(6))
LIMITS = ArmLimits(JOINTS, -np.ones(6), np.ones(6), np.ones(6), np.ones(6), np.ones(6), np.ones(6))
S = 1_000_000_000


# -- helpers ---------------------------------------------------------------------------------------
def as_user(action: Callable[[], str], uid: int = NOBODY, gid: int = NOBODY, groups: tuple[int, ...] = ()) -> str:
    """Run `action` in a forked child that has become `uid`; its returned text, or its traceback as a failure."""
    read_end, write_end = os.pipe()
    pid = os.fork()
    if pid == 0:                                             # the child: never returns into pytest
        result, code = "", 1
        try:
            os.close(read_end)
            os.setgroups(list(groups))
            os.setgid(gid)
            os.setuid(uid)
            result, code = action(), 0
        except BaseException:  # noqa: BLE001 - the child reports whatever the action raised, then exits
            result = traceback.format_exc()
        finally:
            os.write(write_end, result.encode())
            os._exit(code)
    os.close(write_end)
    with os.fdopen(read_end, "rb") as pipe:
        output = pipe.read().decode()                        # until the child exits
    _, status = os.waitpid(pid, 0)
    assert os.waitstatus_to_exitcode(status) == 0, f"the child acting as uid {uid} failed:\n{output}"
    return output


def finishes(action: Callable[[], Any], unblock: Callable[[], None] | None = None) -> BaseException | None:
    """Run `action` in a thread; the exception it raised (None if none). Fails if it blocks instead of returning."""
    outcome: list[BaseException | None] = []

    def target() -> None:
        try:
            action()
        except BaseException as error:  # noqa: BLE001 - handed to the test, which re-raises it
            outcome.append(error)
        else:
            outcome.append(None)

    thread = threading.Thread(target=target, daemon=True)
    thread.start()
    thread.join(HANG_GUARD_S)
    if thread.is_alive():
        if unblock is not None:
            unblock()
        pytest.fail(f"blocked for {HANG_GUARD_S:g} s instead of refusing")
    return outcome[0]


def release_fifo(path: Path) -> Callable[[], None]:
    """Lets a reader blocked in open() on the FIFO go on (it then sees end of file)."""
    def release() -> None:
        os.close(os.open(path, os.O_WRONLY | os.O_NONBLOCK))
    return release


def other_group() -> int:
    """A group other than the test's own, for shm_group."""
    for name in ("daemon", "nogroup", "users"):
        try:
            gid = grp.getgrnam(name).gr_gid
        except KeyError:
            continue
        if gid != os.getegid():
            return gid
    pytest.skip("no group other than the test's own exists")


def mode_of(path: Path) -> int:
    return stat.S_IMODE(path.lstat().st_mode)


@pytest.fixture
def nobody() -> None:
    if os.geteuid() != 0:
        pytest.skip("acting as user nobody needs root (setuid in a forked child)")


@pytest.fixture
def robot_id() -> Iterator[str]:
    """A fresh robot_id; whatever anyone left under its names is removed afterwards (by root, or our own)."""
    name = f"users_{uuid.uuid4().hex[:8]}"
    yield name
    for path in [*(segment_path(n) for n in channel_names(name).values()), status_path(name)]:
        with contextlib.suppress(FileNotFoundError, PermissionError):
            path.unlink()


def plant_fifo(path: Path) -> str:
    os.mkfifo(path, 0o666)
    return "planted"


def plant_file(path: Path, content: bytes, mode: int = 0o644) -> str:
    fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, mode)
    os.write(fd, content)
    os.fchmod(fd, mode)
    os.close(fd)
    return "planted"


def status_document(pid: int | None = None) -> bytes:
    queue = {"name": "bag", "capacity": 0, "fill": 0, "written": 7, "dropped": 0}
    return json.dumps({"pid": pid or os.getpid(), "queues": [queue]}).encode()


# -- the recorder's status file, as the bridge reads it -------------------------------------------
def test_a_status_file_of_our_own_recorder_is_read(robot_id: str):
    write_status(robot_id, [QueueCount("bag", 0, 0, 7, 0)])
    assert mode_of(status_path(robot_id)) == 0o600
    assert read_status(robot_id) == [QueueCount("recorder:bag", 0, 0, 7, 0)]
    remove_status(robot_id)
    assert not status_path(robot_id).exists()


def test_a_status_file_is_group_readable_with_shm_group(robot_id: str, nobody: None):
    group = other_group()
    write_status(robot_id, [QueueCount("bag", 0, 0, 7, 0)], group)
    status = status_path(robot_id).stat()
    assert stat.S_IMODE(status.st_mode) == 0o640 and status.st_gid == group


def test_a_status_file_forged_by_another_user_is_ignored(robot_id: str, nobody: None, caplog):
    path = status_path(robot_id)
    document = status_document()                                     # names this process: it runs
    as_user(lambda: plant_file(path, document))
    with caplog.at_level(logging.WARNING, logger="plem.recorder"):
        assert read_status(robot_id) == []
        assert read_status(robot_id) == []
    warnings = [record.getMessage() for record in caplog.records if str(path) in record.getMessage()]
    assert len(warnings) == 1 and "nobody" in warnings[0]
    remove_status(robot_id)                                          # not ours: left alone
    assert path.exists()


@pytest.mark.parametrize("content", [
    b"{}", b"[]", b"null", b'"text"', b"\xff\xfe garbage", b"", b"[" * 100_000,
    b'{"pid": 1}', b'{"queues": []}', b'{"pid": "1", "queues": []}', b'{"pid": true, "queues": []}',
    b'{"pid": 100000000000000000000000000000, "queues": []}', b'{"pid": -5, "queues": []}',
    b'{"pid": PID, "queues": {}}', b'{"pid": PID, "queues": [1]}', b'{"pid": PID, "queues": [{"name": "x"}]}',
    b'{"pid": PID, "queues": [{"name": 1, "capacity": 0, "fill": 0, "written": 0, "dropped": 0}]}',
    b'{"pid": PID, "queues": [{"name": "x", "capacity": -1, "fill": 0, "written": 0, "dropped": 0}]}',
    b'{"pid": PID, "queues": [{"name": "x", "capacity": 0.5, "fill": 0, "written": 0, "dropped": 0}]}',
    b'{"pid": PID, "queues": [{"name": "x", "capacity": 0, "fill": 0, "written": 0, "dropped": 0, "y": 1}]}',
    b'{"pid": PID, "queues": [], "extra": 1}',
], ids=lambda content: content[:40].decode("latin-1"))
def test_a_status_file_of_the_wrong_shape_is_ignored(robot_id: str, content: bytes):
    plant_file(status_path(robot_id), content.replace(b"PID", str(os.getpid()).encode()), 0o600)
    assert read_status(robot_id) == []


def test_an_oversized_status_file_is_ignored(robot_id: str):
    document = status_document()
    plant_file(status_path(robot_id), document[:-1] + b" " * MAX_STATUS_BYTES + b"}", 0o600)
    assert read_status(robot_id) == []


def test_a_symbolic_link_as_status_file_is_not_followed(robot_id: str, tmp_path: Path):
    target = tmp_path / "status.json"
    target.write_bytes(status_document())
    status_path(robot_id).symlink_to(target)
    assert read_status(robot_id) == []


def test_a_fifo_as_status_file_is_ignored_without_blocking(robot_id: str, nobody: None):
    path = status_path(robot_id)
    as_user(lambda: plant_fifo(path))
    results: list[list[QueueCount]] = []
    assert finishes(lambda: results.append(read_status(robot_id)), release_fifo(path)) is None
    assert results == [[]]


# -- shared memory: squatting, FIFOs, links ------------------------------------------------------
def nobody_creates_a_state_segment(robot_id: str) -> str:
    """As nobody: a state segment under the robot's name, left behind as a process that exits leaves it."""
    StateSegment.create(robot_id, LIMITS, 1_000_000).close()
    return "created"


def test_a_fifo_at_the_state_segment_name_is_refused_without_blocking(robot_id: str, nobody: None):
    path = segment_path(state_segment_name(robot_id))
    as_user(lambda: plant_fifo(path))
    error = finishes(lambda: StateSegment.create(robot_id, LIMITS, 1_000_000), release_fifo(path))
    assert isinstance(error, SegmentError), error
    assert str(path) in error.why and "FIFO" in error.why and "nobody" in error.why
    assert "robot_id:=" in error.how and f"rm {path}" in error.how
    assert stat.S_ISFIFO(path.lstat().st_mode)                      # neither opened nor removed
    error = finishes(lambda: StateSegment.attach(robot_id), release_fifo(path))
    assert isinstance(error, SegmentError) and "FIFO" in error.why


def test_our_own_fifo_at_a_segment_name_is_refused_too(robot_id: str):
    path = segment_path(state_segment_name(robot_id))
    os.mkfifo(path, 0o600)
    error = finishes(lambda: StateSegment.create(robot_id, LIMITS, 1_000_000), release_fifo(path))
    assert isinstance(error, SegmentError) and "FIFO" in error.why
    assert stat.S_ISFIFO(path.lstat().st_mode)


def test_segments_squatted_by_another_user_are_refused_and_left_alone(robot_id: str, nobody: None):
    path = segment_path(state_segment_name(robot_id))
    as_user(lambda: nobody_creates_a_state_segment(robot_id))
    assert path.stat().st_uid == NOBODY
    error = finishes(lambda: StateSegment.create(robot_id, LIMITS, 1_000_000))
    assert isinstance(error, SegmentError), error
    assert "nobody" in error.summary and str(path) in error.why and "robot_id:=" in error.how
    assert path.stat().st_uid == NOBODY                               # not replaced


def test_a_client_refuses_a_segment_of_another_non_root_user(robot_id: str, nobody: None):
    as_user(lambda: nobody_creates_a_state_segment(robot_id))
    error = finishes(lambda: StateSegment.attach(robot_id))
    assert isinstance(error, SegmentError), error
    assert "nobody" in error.why and "nobody" in error.how
    error = finishes(lambda: SharedSegment.open(state_segment_name(robot_id), writable=True))
    assert isinstance(error, SegmentError) and "nobody" in error.why


def client_result(name: str) -> str:
    """As the calling user: what attaching to `name` gives."""
    try:
        SharedSegment.open(name).close()
    except SegmentError as error:
        return f"refused: {error.why}"
    return "attached"


def test_a_group_member_attaches_to_root_but_not_to_another_user(robot_id: str, nobody: None):
    group = other_group()
    root_name, daemon_name = f"/{robot_id}_rt_raw", f"/{robot_id}_stats"
    root_segment = SharedSegment.create(root_name, 4096, 0o640, group)   # a root driver with shm_group
    daemon_path = segment_path(daemon_name)
    plant_file(daemon_path, b"\0" * 4096, 0o644)
    os.chown(daemon_path, DAEMON, DAEMON)
    try:
        assert as_user(lambda: client_result(root_name), groups=(group,)) == "attached"
        refused = as_user(lambda: client_result(daemon_name), groups=(group,))
        assert refused.startswith("refused") and "daemon" in refused
    finally:
        root_segment.close()
        SharedSegment.unlink(root_name)


def test_a_symbolic_link_at_a_segment_name_is_never_followed(robot_id: str, nobody: None):
    target_name = f"/{robot_id}_events"
    target = SharedSegment.create(target_name, 4096)
    link = segment_path(state_segment_name(robot_id))
    as_user(lambda: (link.symlink_to(segment_path(target_name)), "linked")[1])
    try:
        error = finishes(lambda: StateSegment.attach(robot_id))
        assert isinstance(error, SegmentError) and "symbolic link" in error.why
        error = finishes(lambda: StateSegment.create(robot_id, LIMITS, 1_000_000))
        assert isinstance(error, SegmentError) and "symbolic link" in error.why
        assert link.is_symlink()
    finally:
        target.close()
        SharedSegment.unlink(target_name)


def test_another_users_leftover_ring_is_an_error_not_removed(robot_id: str, nobody: None):
    name = channel_names(robot_id)["events"]
    ring = segment_path(name)
    as_user(lambda: plant_file(ring, b"\0" * 4096))
    error = finishes(lambda: SharedSegment.unlink(name))
    assert isinstance(error, SegmentError) and "nobody" in error.why
    error = finishes(lambda: RobotChannels.create(robot_id, LIMITS, 1_000_000))
    assert isinstance(error, SegmentError) and "nobody" in error.why
    assert ring.stat().st_uid == NOBODY
    assert not segment_path(state_segment_name(robot_id)).exists()   # the driver's own set was taken back


def test_our_own_leftovers_are_still_replaced(robot_id: str):
    channels = RobotChannels.create(robot_id, LIMITS, 1_000_000)
    channels.close()                                                  # a driver killed before removing them
    warnings: list[str] = []
    channels = RobotChannels.create(robot_id, LIMITS, 1_000_000, warn=warnings.append)
    assert len(warnings) == 1 and "stale" in warnings[0]
    channels.remove()


# -- recordings ----------------------------------------------------------------------------------
@pytest.fixture
def permissive_umask() -> Iterator[None]:
    """The usual 022, so only plem's own choices can make files owner-only."""
    previous = os.umask(0o022)
    yield
    os.umask(previous)


def record_with_a_fault(directory: Path, group: int | None) -> None:
    """Two segments, a fault keeping both, then the end of recording."""
    clock = Clock()
    recorder = Recorder(RecordingSettings(directory, segment_s=1.0, group=group), "arm", MONITOR_TOPICS, STORE,
                        clock=clock)
    feed(recorder, clock, range(1500))
    fault(recorder, clock, 1500)
    recorder.close()


def assert_access(directory: Path, file_mode: int, directory_mode: int, group: int | None) -> None:
    entries = [directory, *directory.rglob("*")]
    assert {path.suffix for path in entries} >= {".mcap", ".yaml", ".keep", ".jsonl"}
    for path in entries:
        expected = directory_mode if path.is_dir() else file_mode
        assert mode_of(path) == expected, f"{path}: {oct(mode_of(path))}"
        if group is not None:
            assert path.stat().st_gid == group, path


def test_recordings_are_owner_only(tmp_path: Path, permissive_umask: None):
    directory = tmp_path / "bags" / "arm"
    record_with_a_fault(directory, None)
    assert (directory / EVENT_LOG).exists()
    assert_access(directory, 0o600, 0o700, None)
    assert mode_of(tmp_path / "bags") == 0o700                         # created by the recorder


def test_recordings_are_group_readable_with_shm_group(tmp_path: Path, permissive_umask: None, nobody: None):
    group = other_group()
    directory = tmp_path / "bags" / "arm"
    record_with_a_fault(directory, group)
    assert_access(directory, 0o640, 0o750, group)


def test_a_repaired_segment_keeps_the_access_of_the_killed_one(tmp_path: Path, permissive_umask: None,
                                                             nobody: None):
    group = other_group()
    segment = tmp_path / "arm_2027_01_15-07_00_00"
    writer = SegmentWriter(segment, [("/arm/rt_raw", MONITOR_TOPICS["rt_raw"])], STORE,
                           access=FileAccess(group))
    encoder = RawEncoder(6)
    for cycle in range(10):
        writer.append("/arm/rt_raw", S + cycle, encoder.encode(np.full(raw_record_length(6), float(cycle)), S + cycle))
    writer.flush()
    writer.abandon()                                                    # killed: no metadata.yaml
    assert repair(segment).repaired
    for path in [segment, *segment.iterdir()]:
        assert mode_of(path) == (0o750 if path.is_dir() else 0o640), path
        assert path.stat().st_gid == group


def test_atomic_writes_and_the_recorders_umask_only_ever_narrow(tmp_path: Path):
    previous = os.umask(0)
    try:
        write_atomic(tmp_path / "profile.json", "{}", mode=0o600)
        assert mode_of(tmp_path / "profile.json") == 0o600
        restrict_umask()
        assert os.umask(0o277) == 0o077
        restrict_umask()
        assert os.umask(0) == 0o277                                    # already narrower: kept
    finally:
        os.umask(previous)
