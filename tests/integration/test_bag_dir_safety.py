"""Another local user cannot steer root's recordings through a shared bag_dir, and a deleted robot directory or a
disk filled by other files never costs more than it must.

User nobody (a real other user: a forked child that setuid()s to it) plants links and directories where root's
recorder will look; root's recorder refuses them with a WHAT/WHY/HOW and never writes through them. These tests
need root; the deleted-directory test runs as any user, the full-disk test needs to mount a small tmpfs.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import shutil
import stat
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest
from rosbags.rosbag2 import Reader

from plem.launch.plan import prepare_bag_directory
from plem.middleware.monitor_feed import MONITOR_TOPICS
from plem.recording.archive import EVENT_LOG, read_event_log
from plem.recording.problems import RecordingError
from plem.recording.recorder import Recorder
from plem.recording.settings import RecordingSettings
from tests.integration.test_local_users import NOBODY, as_user
from tests.integration.test_recorder import STORE, Clock, Samples, fault, recorded, tmpfs

OWNER = f"nobody (uid {NOBODY})"


def mode_of(path: Path) -> int:
    return stat.S_IMODE(path.lstat().st_mode)


def refusal(directory: Path) -> RecordingError:
    """What root's recorder says when asked to record into `directory`."""
    with pytest.raises(RecordingError) as raised:
        Recorder(RecordingSettings(directory), "arm", MONITOR_TOPICS, STORE)
    return raised.value


@contextlib.contextmanager
def shared_folder() -> Iterator[Path]:
    """A directory as /tmp is (every user may create in it, sticky bit), holding nobody's own directory `loot`."""
    if os.geteuid() != 0:
        pytest.skip("acting as user nobody needs root (setuid in a forked child)")
    folder = Path(tempfile.mkdtemp(prefix="plem_shared_"))
    folder.chmod(0o1777)
    as_user(lambda: str((folder / "loot").mkdir(mode=0o777)))
    try:
        yield folder
    finally:
        shutil.rmtree(folder)


@pytest.fixture
def shared() -> Iterator[Path]:
    """`shared_folder` for one test."""
    with shared_folder() as folder:
        yield folder


def loot(shared: Path) -> list[str]:
    """What ended up in nobody's directory."""
    return sorted(path.name for path in (shared / "loot").iterdir())


def test_a_link_planted_as_the_robot_directory_is_refused_and_never_written_through(shared: Path):
    as_user(lambda: str(os.symlink(shared / "loot", shared / "arm")))
    error = refusal(shared / "arm")
    text = error.render()
    assert error.summary == f"{shared / 'arm'} is a symbolic link of {OWNER}", text
    assert f"pointing to {shared / 'loot'}" in error.why and f"`rm {shared / 'arm'}`" in error.how
    assert "bag_dir:=" in error.how
    problem = prepare_bag_directory({"bag_dir": str(shared)}, "arm", None)      # the launch's own check
    assert problem is not None and problem.summary == error.summary
    assert loot(shared) == [], "nothing was written into the link's target"


def test_the_recorder_process_refuses_the_link_without_a_traceback(shared: Path):
    as_user(lambda: str(os.symlink(shared / "loot", shared / "arm")))
    arguments = json.dumps({"bus": "mock", "robot_id": "arm", "bag_dir": str(shared)})
    result = subprocess.run([sys.executable, "-m", "plem.launch.recorder", arguments], capture_output=True,
                            text=True, timeout=120)
    assert result.returncode == 1 and "Traceback" not in result.stderr, result.stderr
    error = json.loads(result.stdout.splitlines()[-1])["error"]
    assert error["summary"] == f"{shared / 'arm'} is a symbolic link of {OWNER}"
    assert loot(shared) == []


def test_a_robot_directory_of_another_user_is_refused(shared: Path):
    as_user(lambda: str((shared / "arm").mkdir(mode=0o777)))
    (shared / "arm").chmod(0o777)                                   # whatever nobody's umask made of it
    error = refusal(shared / "arm")
    assert error.summary == f"{shared / 'arm'} belongs to {OWNER}, not to root (uid 0)"
    assert "owned by nobody (uid 65534) (mode 0777)" in error.why and "move, replace or read" in error.why
    assert f"mv {shared / 'arm'} {shared / 'arm'}.untrusted" in error.how and "chown -R root" in error.how
    assert list((shared / "arm").iterdir()) == [], "nothing was written into it"


def test_without_a_robot_id_the_launch_checks_bag_dir_only_as_a_directory_on_the_way(shared: Path):
    """A launch whose robot_id is itself the problem checks bag_dir alone: another user's bag_dir is no problem of
    its own (only a robot's directory must be the recorder's), a world-writable one without the sticky bit is."""
    assert prepare_bag_directory({"bag_dir": str(shared / "loot")}, None, None) is None
    assert prepare_bag_directory({"bag_dir": str(shared / "loot")}, "arm", None) is None      # created by root
    (shared / "open").mkdir()
    (shared / "open").chmod(0o777)
    problem = prepare_bag_directory({"bag_dir": str(shared / "open")}, None, None)
    assert problem is not None and problem.summary == f"{shared / 'open'} is writable by every user and has no " \
                                                      "sticky bit"


def test_a_world_writable_bag_dir_without_the_sticky_bit_is_refused(shared: Path):
    bags = shared / "bags"
    bags.mkdir()
    bags.chmod(0o777)
    error = refusal(bags / "arm")
    assert error.summary == f"{bags} is writable by every user and has no sticky bit"
    assert "mode 0777" in error.why and f"`chmod +t {bags}`" in error.how
    assert not (bags / "arm").exists()
    bags.chmod(0o1777)                                              # as /tmp: accepted
    Recorder(RecordingSettings(bags / "arm"), "arm", MONITOR_TOPICS, STORE).close()
    assert mode_of(bags / "arm") == 0o700


def test_links_on_the_way_are_followed_only_when_root_or_the_user_owns_them(shared: Path):
    as_user(lambda: str(os.symlink(shared / "loot", shared / "theirs")))
    error = refusal(shared / "theirs" / "arm")
    assert error.summary == f"{shared / 'theirs'} is a symbolic link of {OWNER}"
    assert loot(shared) == []
    (shared / "real").mkdir(mode=0o700)
    (shared / "ours").symlink_to(shared / "real")                   # root's own link: followed
    Recorder(RecordingSettings(shared / "ours" / "arm"), "arm", MONITOR_TOPICS, STORE).close()
    assert (shared / "real" / "arm").is_dir()


def test_a_directory_on_the_way_that_may_only_be_passed_through_is_enough(shared: Path):
    """A home of mode 0711: the recorder's user may pass through it without reading it, and records below it."""
    home = shared / "home"
    home.mkdir()
    home.chmod(0o711)
    (home / "bags").mkdir()
    os.chown(home / "bags", NOBODY, NOBODY)

    def record_there() -> str:
        Recorder(RecordingSettings(home / "bags" / "arm"), "arm", MONITOR_TOPICS, STORE).close()
        return "recorded"

    assert as_user(record_there) == "recorded"
    assert (home / "bags" / "arm").stat().st_uid == NOBODY and mode_of(home / "bags" / "arm") == 0o700


def test_a_robot_directory_swapped_while_recording_redirects_nothing(shared: Path):
    """nobody owns bag_dir, so it may rename root's robot directory and put a link in its place: the segments
    still go into root's directory (held open), and recreating it refuses the link and stops recording."""
    bags = shared / "their_bags"

    def make_bags() -> str:
        bags.mkdir()
        bags.chmod(0o1777)                                          # as /tmp, but nobody's
        return "made"

    as_user(make_bags)
    clock = Clock()
    recorder = Recorder(RecordingSettings(bags / "arm", segment_s=1.0), "arm", MONITOR_TOPICS, STORE, clock=clock,
                        disk_usage=lambda _: (100, 10, 90))
    samples = Samples(recorder, clock)
    samples.until(lambda: samples.cycle == 1500)
    target = shared / "loot" / "theirs"

    def swap() -> str:
        target.mkdir()
        os.rename(bags / "arm", bags / "moved")
        os.symlink(target, bags / "arm")
        return "swapped"

    as_user(swap)
    samples.until(lambda: recorder.stopped is not None)
    samples.until(lambda: samples.cycle == 4500)
    recorder.close()
    assert list(target.iterdir()) == [], "nothing went through the link"
    moved = bags / "moved"
    entries = list(read_event_log(moved))
    [stop] = [entry for entry in entries if entry["kind"] == "recording_stopped"]
    assert f"{bags / 'arm'} is a symbolic link of {OWNER}" in stop["message"]
    assert stop["message"].startswith("ERROR: recording stopped:")
    assert [cycle for _, _, cycle in recorded(moved)][:1500] == list(range(1500)), "recorded into root's directory"
    assert stat.S_IMODE(moved.stat().st_mode) == 0o700 and moved.stat().st_uid == 0


def test_what_another_user_planted_in_our_old_directory_is_never_followed(shared: Path):
    """A robot directory of ours that was left open to everyone (0777) is narrowed to 0700, and the links nobody put
    in it (an event log, a segment) are neither written through nor taken for segments."""
    robot = shared / "arm"
    robot.mkdir()
    robot.chmod(0o777)
    secret = shared / "loot" / "log"
    fake = shared / "loot" / "arm_2020_01_01-00_00_00"

    def plant() -> str:
        secret.write_text("nobody's\n")
        fake.mkdir()
        os.symlink(secret, robot / EVENT_LOG)
        os.symlink(fake, robot / fake.name)
        return "planted"

    as_user(plant)
    clock = Clock()
    recorder = Recorder(RecordingSettings(robot, segment_s=1.0), "arm", MONITOR_TOPICS, STORE, clock=clock,
                        disk_usage=lambda _: (100, 10, 90))
    assert mode_of(robot) == 0o700 and recorder.closed == []
    Samples(recorder, clock).until(lambda: recorder.closed != [])
    recorder.close()
    assert secret.read_text() == "nobody's\n" and list(fake.iterdir()) == []
    assert (robot / EVENT_LOG).is_symlink(), "left as it was, not followed"


# -- a robot directory deleted while recording ---------------------------------------------------------------
def test_a_deleted_robot_directory_is_created_again_and_recording_goes_on(tmp_path: Path, caplog):
    robot = tmp_path / "bags" / "arm"
    clock = Clock()
    recorder = Recorder(RecordingSettings(robot, segment_s=1.0, disk_threshold=100.0), "arm", MONITOR_TOPICS,
                        STORE, clock=clock)                 # the real disk's usage, whatever its fill
    samples = Samples(recorder, clock)
    samples.until(lambda: samples.cycle == 2500)
    shutil.rmtree(robot)                                            # rm -rf BAG_DIR/ROBOT_ID
    samples.until(lambda: samples.cycle == 6000)
    recorder.close()
    cycles = [cycle for _, _, cycle in recorded(robot)]
    assert cycles == list(range(3000, 6000)), "recorded from the next segment on, without a gap"
    assert mode_of(robot) == 0o700, "created again as at start, owner-only"
    [entry] = [entry for entry in read_event_log(robot) if entry["kind"] == "directory_recreated"]
    assert entry["lost_with_directory"] == 1000 + 10, "the open segment (cycles 2000 to 2999) went with it"
    assert f"{robot} was deleted, moved or replaced while recording" in entry["message"]
    assert recorder.unrecorded == 0 and "resumes by itself" not in caplog.text


# -- a disk other files fill -------------------------------------------------------------------------------
@pytest.fixture
def disk(tmp_path: Path) -> Iterator[Path]:
    """A 16 MiB tmpfs."""
    with tmpfs(tmp_path, "16m") as mount:
        yield mount


def test_a_disk_other_files_fill_keeps_every_segment_stops_and_resumes(disk: Path, caplog):
    """A foreign file takes the disk past disk_threshold: no segment is deleted for it (deleting them all would not
    make room), the open one is finished, recording stops with one WHAT/WHY/HOW and resumes once the file goes."""
    robot = disk / "arm"
    clock = Clock()
    recorder = Recorder(RecordingSettings(robot, segment_s=1.0, disk_threshold=70.0, flight_window_s=0.5), "arm",
                        MONITOR_TOPICS, STORE, clock=clock)
    samples = Samples(recorder, clock)
    samples.until(lambda: samples.cycle == 1500)
    fault(recorder, clock, 1500)                                    # keeps the segment from 1000 on
    samples.until(lambda: samples.cycle == 3500)
    total, used, _ = shutil.disk_usage(disk)
    foreign = disk / "foreign"
    foreign.write_bytes(bytes(int(0.9 * total) - used))             # not plem's: 90 % full
    before = sorted(path.name for path in robot.iterdir() if path.is_dir())
    samples.until(lambda: recorder.stopped is not None)
    stopped_at = samples.cycle
    kept = sorted(path.name for path in robot.iterdir() if path.is_dir())
    assert set(before) <= set(kept), "no segment was deleted"
    samples.until(lambda: samples.cycle == stopped_at + 3000)       # three guard passes while the disk is full
    assert recorder.stopped is not None and recorder.segment is None
    assert sorted(path.name for path in robot.iterdir() if path.is_dir()) == kept
    foreign.unlink()
    samples.until(lambda: recorder.stopped is None)
    lost = recorder.unrecorded
    samples.until(lambda: samples.cycle == stopped_at + 5500)
    recorder.close()

    entries = list(read_event_log(robot))
    kinds = [entry["kind"] for entry in entries]
    assert "deleted" not in kinds and kinds.count("recording_stopped") == 1 and kinds.count("recording_resumed") == 1
    [stop] = [entry for entry in entries if entry["kind"] == "recording_stopped"]
    message = stop["message"]
    assert message.startswith(f"ERROR: recording stopped: the disk holding {robot} is above disk_threshold 70 %")
    assert "deletes none to make room other files took" in message and "\nHOW: free space there" in message
    [resumed] = [entry for entry in entries if entry["kind"] == "recording_resumed"]
    assert resumed["not_recorded"] == lost and lost >= 3000
    for segment in kept:                                            # every segment reads back, the kept one too
        with Reader(robot / segment) as reader:
            assert reader.message_count > 0
    assert (robot / f"{before[1]}.keep").exists()
    cycles = [cycle for _, _, cycle in recorded(robot)]
    raw_lost = resumed["not_recorded_topics"]["rt_raw"]
    assert cycles[-1] == samples.cycle - 1 and len(cycles) + raw_lost == samples.cycle, "each cycle recorded or counted"
    assert not any(record.exc_info for record in caplog.records)
    assert errno.ENOSPC not in {entry.get("errno") for entry in entries}, "the disk never refused a write"
