"""The bridge process on its own: a DDS configuration Cyclone refuses is its one WHAT/WHY/HOW line, not a traceback."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from tests.e2e.launched import clean_environment, new_robot_id


@pytest.mark.parametrize("uri", ["<bogus", "<CycloneDDS>é</CycloneDDS>"])
def test_the_bridge_reports_a_refused_cyclonedds_uri_as_why_it_could_not_start(tmp_path: Path, uri: str):
    arguments = json.dumps({"bus": "mock", "robot_id": new_robot_id(), "record": "false"})
    env = clean_environment(tmp_path / "home", CYCLONEDDS_URI=uri)
    result = subprocess.run([sys.executable, "-m", "plem.launch.ros_bridge", arguments], capture_output=True,
                            text=True, timeout=120, env=env)
    assert result.returncode == 1 and "Traceback" not in result.stderr, result.stderr
    (line,) = result.stdout.splitlines()
    announcement = json.loads(line)
    assert announcement["ready"] is False
    error = announcement["error"]
    assert "CYCLONEDDS_URI" in error["why"] and error["how"] == "fix or unset CYCLONEDDS_URI"
