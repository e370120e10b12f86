"""A Ctrl-C of `plem launch` is a clean stop: no component reports an error, and the launch exits 0 (docs/bringup.md).

The bridge watches the RT driver's heartbeat; the supervisor signals every component at once, so the driver may be
gone before the bridge has seen its own signal. Several stops in a row give that race its chances.
"""

from __future__ import annotations

import pytest

from tests.e2e.launched import clean_environment, launched, new_robot_id

STOPS = 3


@pytest.mark.parametrize("attempt", range(STOPS))
def test_ctrl_c_stops_the_launch_without_an_error(tmp_path_factory: pytest.TempPathFactory, attempt: int):
    directory = tmp_path_factory.mktemp(f"stop{attempt}")
    robot_id = new_robot_id()
    with launched(["bus:=mock", f"robot_id:={robot_id}", "record:=false"], [robot_id], directory,
                  clean_environment(directory / "plem_home")) as launch:
        assert launch.component_pid("bridge")
        code = launch.stop()
        output, errors = launch.output, launch.errors
    assert code == 0, launch.describe()
    assert "ERROR" not in output + errors, launch.describe()
    assert f"[{robot_id}/bridge] stopped (exited with code 0)" in output, launch.describe()
    assert f"[{robot_id}/rt_driver] stopped (exited with code 0)" in output, launch.describe()
