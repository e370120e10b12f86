"""A bag_dir the recorder cannot write into: one WHAT/WHY/HOW with the real cause and the `bag_dir:=` argument,
never a traceback, never "disk below threshold" over and over.

Acting as user nobody (a folder root owns, mode 0555; a folder made unwritable while recording) needs root.
"""

from __future__ import annotations

import importlib.metadata
import json
import os
import shutil
import subprocess
import sys
import tempfile
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest
from rosbags.rosbag2 import Reader

from plem.launch.recorder import record
from plem.middleware.monitor_feed import MONITOR_TOPICS
from plem.recording.archive import read_event_log
from plem.recording.problems import RecordingError
from plem.recording.recorder import Recorder
from plem.recording.settings import RecordingSettings
from tests.integration.test_local_users import NOBODY, as_user
from tests.integration.test_recorder import STORE, Clock, feed

S = 1_000_000_000


@pytest.fixture
def shared_folder() -> Iterator[Path]:
    """A folder every user may enter (pytest's tmp_path is root's alone), removed afterwards."""
    if os.geteuid() != 0:
        pytest.skip("acting as user nobody needs root (setuid in a forked child)")
    folder = Path(tempfile.mkdtemp(prefix="plem_bag_dir_"))
    folder.chmod(0o755)
    yield folder
    shutil.rmtree(folder)


def test_a_bag_dir_nobody_may_write_into_is_permission_denied(shared_folder: Path):
    bags = shared_folder / "bags"
    bags.mkdir(mode=0o555)                                   # root's, read-only to the recorder's user

    def start() -> str:
        try:
            Recorder(RecordingSettings(bags / "arm"), "arm", MONITOR_TOPICS, STORE)
        except RecordingError as error:
            return error.render()
        return "no error"

    text = as_user(start)
    assert text.startswith(f"ERROR: cannot write into {bags / 'arm'}: permission denied\n"), text
    assert f"WHY: {bags / 'arm'}: Permission denied" in text
    assert "WHAT: a bag directory the recorder's user, nobody (uid 65534), may create files in" in text
    assert "HOW: give nobody (uid 65534) write access" in text and "pass bag_dir:=DIR to plem launch" in text
    assert not (bags / "arm").exists()


def test_a_bag_dir_made_unwritable_while_recording_stops_it_once_and_it_resumes(shared_folder: Path):
    """The robot's folder turns read-only to the recorder's user between two segments: one 'permission denied'
    whatever the guard passes in between (never 'disk below threshold'), then recording resumes."""
    robot = shared_folder / "arm"
    robot.mkdir(mode=0o700)
    os.chown(robot, NOBODY, NOBODY)                          # the recorder's user's own folder
    importlib.metadata.version("rosbags")                    # what rosbags loads to write a bag, before nobody
                                                             # (who cannot read root's Python library) needs it

    def record_through_it() -> str:
        clock = Clock()
        recorder = Recorder(RecordingSettings(robot, segment_s=1.0), "arm", MONITOR_TOPICS, STORE, clock=clock,
                            disk_usage=lambda _: (100, 10, 90))
        feed(recorder, clock, range(1500))
        robot.chmod(0o500)                                   # the segment from cycle 2000 on cannot be created
        feed(recorder, clock, range(1500, 2500))
        for _ in range(10):                                  # ten guard passes, each trying to resume
            clock.now += S
            recorder.maintain()
        stopped = recorder.stopped is not None and recorder.segment is None
        robot.chmod(0o700)
        clock.now += S
        recorder.maintain()
        feed(recorder, clock, range(13_500, 13_501))        # the next message opens the new segment
        resumed = recorder.segment is not None
        recorder.close()
        return json.dumps({"stopped": stopped, "resumed": resumed, "lost": recorder.unrecorded})

    outcome = json.loads(as_user(record_through_it))
    assert outcome["stopped"] and outcome["resumed"] and outcome["lost"] == 500
    entries = list(read_event_log(robot))
    stops = [entry for entry in entries if entry["kind"] == "recording_stopped"]
    assert len(stops) == 1, [entry["message"] for entry in stops]
    assert stops[0]["message"].startswith(f"ERROR: recording stopped: cannot write into {robot}: permission denied")
    assert "Permission denied" in stops[0]["reason"] and "bag_dir:=" in stops[0]["message"]
    assert not any("threshold" in entry["message"] for entry in entries if entry["kind"] != "segment_opened")
    [resumed] = [entry for entry in entries if entry["kind"] == "recording_resumed"]
    assert resumed["not_recorded"] == 500 and resumed["reason"] == "Permission denied"
    for segment in sorted(path for path in robot.iterdir() if path.is_dir())[:2]:
        with Reader(segment) as reader:
            assert reader.message_count == 1000, "the segments before the stop are whole"


UNUSABLE = {
    "/proc/nope": ("cannot write into /proc/nope/", "No such file or directory"),
    "/proc": ("cannot write into /proc/", "No such file or directory"),
    "/tmp/a\0b": ("bag_dir cannot be created: the path holds a NUL byte", "NUL byte"),
    "/tmp/" + "d" * 200 + "/" + "e" * 4800: ("bag_dir cannot be created: the path is 5006 bytes long", "4095"),
}


@pytest.mark.parametrize("bag_dir", UNUSABLE, ids=["proc_nope", "proc", "nul_byte", "5000_characters"])
def test_a_bag_dir_that_cannot_exist_is_one_what_why_how(bag_dir: str):
    summary, why = UNUSABLE[bag_dir]
    with pytest.raises(RecordingError) as raised:
        record({"bus": "mock", "robot_id": "arm", "bag_dir": bag_dir}, threading.Event())
    error = raised.value
    assert error.summary.startswith(summary) and why in error.why
    assert "bag_dir:=" in error.how and "cycle_time" not in error.how


def test_the_recorder_process_announces_the_bag_dir_problem_without_a_traceback():
    arguments = json.dumps({"bus": "mock", "robot_id": "arm", "bag_dir": "/proc/nope"})
    result = subprocess.run([sys.executable, "-m", "plem.launch.recorder", arguments], capture_output=True,
                            text=True, timeout=120)
    assert result.returncode == 1 and "Traceback" not in result.stderr, result.stderr
    [line] = result.stdout.splitlines()
    announcement = json.loads(line)
    assert announcement["ready"] is False
    error = announcement["error"]
    assert error["summary"] == "cannot write into /proc/nope/arm: no such file or directory"
    assert error["why"] == "/proc/nope: No such file or directory"
    assert error["how"].startswith("pass bag_dir:=DIR to plem launch")
