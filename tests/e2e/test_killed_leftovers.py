"""What `kill -9` of `plem launch` or of its recorder leaves in /dev/shm is gone after the next launch or stop."""

from __future__ import annotations

import os
import signal
from pathlib import Path

from plem.ipc.robot_description import description_path
from plem.recording.status import status_path
from tests.e2e.launched import clean_environment, launched, new_robot_id, start_launch, wait_until


def test_a_killed_recorders_status_file_is_gone_after_the_launch_stops(tmp_path: Path):
    robot_id = new_robot_id()
    arguments = ["bus:=mock", f"robot_id:={robot_id}", f"bag_dir:={tmp_path / 'bags'}", "bridge:=false"]
    with launched(arguments, [robot_id], tmp_path, clean_environment(tmp_path / "home")) as launch:
        assert wait_until(lambda: status_path(robot_id).exists(), 30), "the recorder publishes its counters"
        os.kill(launch.component_pid("recorder"), signal.SIGKILL)
        launch.wait_for(f"[{robot_id}/recorder] killed by SIGKILL", timeout=30)
        assert status_path(robot_id).exists(), "SIGKILL leaves it"
        assert launch.stop() == 0
    assert not status_path(robot_id).exists()


def test_a_killed_launchs_description_file_is_gone_after_the_next_launch(tmp_path: Path):
    killed, following = new_robot_id(), new_robot_id()
    environment = clean_environment(tmp_path / "home")
    launch = start_launch(["bus:=mock", f"robot_id:={killed}", "record:=false", "bridge:=false"], [killed],
                          tmp_path / "killed", environment)
    try:
        assert description_path(killed).exists()
        launch.process.kill()
        launch.process.wait()
        assert description_path(killed).exists(), "SIGKILL leaves it"
        with launched(["bus:=mock", f"robot_id:={following}", "record:=false", "bridge:=false"], [following],
                      tmp_path / "following", environment):
            assert not description_path(killed).exists()
    finally:
        launch.cleanup()
    assert not description_path(following).exists()
