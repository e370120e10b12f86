"""Files a launch or a recorder killed with SIGKILL leaves in /dev/shm are removed by the next launch or stop.

The writers are real processes writing through plem's own functions, killed with SIGKILL; the next launch
(`share_description`) or the stop of any launch (`remove_description`) is what removes their files.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import uuid
from collections.abc import Iterator

import pytest

from plem.ipc.leftovers import remove_stale_files
from plem.ipc.robot_description import SharedDescription, description_path, remove_description, share_description
from plem.middleware.monitor_feed import QueueCount
from plem.recording.status import status_path, write_status
from tests.integration.test_local_users import NOBODY, as_user, status_document

WRITE_DESCRIPTION = """
import os, sys
from plem.ipc.robot_description import SharedDescription, share_description
share_description(sys.argv[1], SharedDescription("<robot name='arm'/>", {}, os.getpid()))
"""
WRITE_STATUS = """
import sys
from plem.middleware.monitor_feed import QueueCount
from plem.recording.status import write_status
write_status(sys.argv[1], [QueueCount("bag", 0, 0, 7, 0)])
"""


@pytest.fixture
def robot_ids() -> Iterator[tuple[str, str]]:
    """Two fresh robot_ids; their files are removed afterwards."""
    names = (f"left_{uuid.uuid4().hex[:8]}", f"next_{uuid.uuid4().hex[:8]}")
    yield names
    for name in names:
        for path in (description_path(name), status_path(name)):
            with contextlib.suppress(FileNotFoundError):
                path.unlink()


def killed_writer(script: str, robot_id: str) -> int:
    """Run `script` in a real process that then waits; SIGKILL it once its file is written; its pid."""
    process = subprocess.Popen([sys.executable, "-c", script + "\nprint('written', flush=True)\nsys.stdin.read()",
                                robot_id], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    assert process.stdout is not None and process.stdout.readline() == "written\n"
    process.send_signal(signal.SIGKILL)
    process.wait(timeout=30)
    return process.pid


def test_the_next_launch_removes_what_a_killed_launch_left(robot_ids: tuple[str, str]):
    killed, launched = robot_ids
    killed_writer(WRITE_DESCRIPTION, killed)
    assert description_path(killed).exists(), "SIGKILL leaves it"
    share_description(launched, SharedDescription("<robot name='arm'/>", {}, os.getpid()))
    assert not description_path(killed).exists() and description_path(launched).exists()


def test_the_stop_of_a_launch_removes_what_a_killed_recorder_left(robot_ids: tuple[str, str]):
    robot, other = robot_ids
    killed_writer(WRITE_STATUS, robot)
    assert status_path(robot).exists(), "SIGKILL leaves it"
    remove_description(robot)                                  # the launch's clean stop
    assert not status_path(robot).exists()
    killed_writer(WRITE_STATUS, robot)
    remove_description(other)                                  # any launch's stop
    assert not status_path(robot).exists()


def test_files_of_running_writers_and_of_other_users_stay(robot_ids: tuple[str, str]):
    running, foreign = robot_ids
    share_description(running, SharedDescription("<robot name='arm'/>", {}, os.getpid()))
    write_status(running, [QueueCount("bag", 0, 0, 7, 0)])
    assert not [path for path in remove_stale_files() if running in path.name]
    assert description_path(running).exists() and status_path(running).exists()
    if os.geteuid() != 0:
        return
    dead = killed_writer(WRITE_STATUS, foreign)
    status_path(foreign).unlink()

    def plant() -> str:
        fd = os.open(status_path(foreign), os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        os.write(fd, status_document(dead))
        os.close(fd)
        return "planted"

    as_user(plant)
    remove_stale_files()
    assert status_path(foreign).stat().st_uid == NOBODY, "another user's file is not ours to remove"
